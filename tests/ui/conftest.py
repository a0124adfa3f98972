"""The browser UI under test: `hapticdesk ui` started for real, driven by a real Chromium.

The browser is Debian's /usr/bin/chromium through Playwright (no `playwright install`, nothing
downloaded). Without it the page tests skip and say why, unless HAPTICDESK_REQUIRE_BROWSER is
set (CI sets it): then they fail.
"""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

CHROMIUM = Path("/usr/bin/chromium")
REQUIRE_ENV = "HAPTICDESK_REQUIRE_BROWSER"
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]
EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
# the page's screenshots: the documentation's pictures under docs/ only when asked for
# (HAPTICDESK_SCREENSHOTS=docs); a plain test run must not rewrite committed files
DOCS = (
    Path(__file__).resolve().parents[2] / "docs"
    if os.environ.get("HAPTICDESK_SCREENSHOTS") == "docs"
    else Path(tempfile.gettempdir()) / "hapticdesk-ui-screenshots"
)
#: the pictures of the page the guides show (docs/images/), each at both sizes
IMAGES = DOCS / "images"
#: the two windows the page is checked in: a desktop's and a phone's
DESKTOP = {"width": 1400, "height": 900}
PHONE = {"width": 390, "height": 844}

# Taps alternate between button b5 (0, 0) and (20, -10) cm, where no region is yet (the
# designer test draws one there), one a second, for longer than the page tests take.
SCENE = """
name: ui-taps
desk: kitamura2017
units: cm
quiet_s: 2.0
human: {tap_peak_n: [4, 6]}
timeline:
""" + "".join(
    "  - tap: {point: [0, 0], wait_s: 0.5}\n  - tap: {point: [20, -10], wait_s: 0.5}\n"
    for _ in range(60)
)


def _missing(reason: str) -> None:
    if os.environ.get(REQUIRE_ENV):
        pytest.fail(f"{reason}, and {REQUIRE_ENV} is set")
    pytest.skip(f"{reason} (apt-get install chromium; pip install playwright)")


@pytest.fixture(scope="session")
def browser() -> Iterator[Any]:
    """A headless Chromium (the system's binary) through Playwright."""
    if not CHROMIUM.exists():
        _missing(f"no browser at {CHROMIUM}")
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        _missing("the python package playwright is not installed")
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
        yield b
        b.close()


def watch_address(
    proc: subprocess.Popen[str], lines: list[str]
) -> tuple[threading.Event, list[str]]:
    """A thread that keeps ``proc``'s stderr lines in ``lines``; the event is set, and the
    list holds the page's address, once the page's line (``hapticdesk ui: http://…``) came."""
    found = threading.Event()
    url: list[str] = []

    def read() -> None:
        assert proc.stderr is not None
        for line in proc.stderr:
            lines.append(line)
            m = re.search(r"hapticdesk ui: (http://\S+)", line)
            if m and not url:
                url.append(m.group(1))
                found.set()

    threading.Thread(target=read, daemon=True).start()
    return found, url


def stop_process(proc: subprocess.Popen[str], how: int = signal.SIGINT) -> None:
    """``proc`` stopped as a user stops it (Ctrl-C, or ``how``), killed if it hangs."""
    if proc.poll() is None:
        proc.send_signal(how)
        try:
            proc.wait(20)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(5)


class UiProcess:
    """A `hapticdesk ui` child process and the URL it serves."""

    def __init__(self, layout: Path, scene: Path, *extra: str) -> None:
        self.layout = layout
        self.lines: list[str] = []
        #: what it printed (the `log` action's lines, with --actions)
        self.printed: list[str] = []
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "hapticdesk", "ui", "--layout", str(layout)]
            + ["--source", f"sim:{scene}", "--port", "0", *extra],
            stderr=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
        )
        self.url = ""

        def printed() -> None:
            assert self.proc.stdout is not None
            for line in self.proc.stdout:
                self.printed.append(line)

        threading.Thread(target=printed, daemon=True).start()
        found, url = watch_address(self.proc, self.lines)
        if not found.wait(30):
            self.stop()
            raise AssertionError("hapticdesk ui did not start:\n" + "".join(self.lines))
        self.url = url[0]

    def stop(self) -> None:
        stop_process(self.proc, signal.SIGTERM)


@pytest.fixture(scope="module")
def ui_service(tmp_path_factory: pytest.TempPathFactory) -> Iterator[UiProcess]:
    """`hapticdesk ui` on a copy of examples/layouts/buttons.yaml, a simulated desk tapping."""
    folder = tmp_path_factory.mktemp("ui")
    layout = folder / "buttons.yaml"
    shutil.copy(EXAMPLES / "layouts" / "buttons.yaml", layout)
    scene = folder / "taps.yaml"
    scene.write_text(SCENE, encoding="utf-8")
    service = UiProcess(layout, scene)
    service.started = time.monotonic()  # type: ignore[attr-defined]
    yield service
    service.stop()


def desk_to_screen(page: Any, x: float, y: float) -> tuple[float, float]:
    """Where desk point (x, y) metres is on the screen, from the SVG's own transform."""
    return page.evaluate(
        """([x, y]) => {
            const svg = document.getElementById('desk');
            const p = svg.createSVGPoint(); p.x = x * 1000; p.y = -y * 1000;
            const q = p.matrixTransform(svg.getScreenCTM());
            return [q.x, q.y];
        }""",
        [x, y],
    )


def draw_rectangle(page: Any, name: str, a: tuple[float, float], b: tuple[float, float]) -> None:
    """Draw the region ``name`` with the designer's rectangle tool from desk point ``a`` to
    ``b`` (metres), as a person drags, and wait until it is drawn."""
    page.click("#tab-designer")
    page.check("#tool-rect")
    page.fill("#region-name", name)
    x0, y0 = desk_to_screen(page, *a)
    x1, y1 = desk_to_screen(page, *b)
    page.mouse.move(x0, y0)
    page.mouse.down()
    page.mouse.move((x0 + x1) / 2, (y0 + y1) / 2)
    page.mouse.move(x1, y1)
    page.mouse.up()
    page.wait_for_selector(f"#region-{name}")


@pytest.fixture
def to_screen() -> Any:
    """desk_to_screen(page, x, y), for tests that draw on the desk."""
    return desk_to_screen
