"""The first ten minutes, end to end: `hapticdesk init` starts a layout, `hapticdesk ui
--actions` shows it in a real Chromium while a simulated person taps, the designer draws a new
region and binds a tap to it with the `log` action, saves, and the running desk fires that
tap: in the page's gestures, in its action counts, and as the line `log` prints.

With HAPTICDESK_SCREENSHOTS=docs the designer's pictures are saved under docs/images/.
"""

from __future__ import annotations

import json
import subprocess
import sys
from typing import Any

import pytest

from .conftest import DESKTOP, IMAGES, PHONE, SCENE, UiProcess, draw_rectangle


def test_a_layout_from_init_gets_a_drawn_region_whose_tap_fires(
    browser: Any, tmp_path: Any
) -> None:
    layout = tmp_path / "my-desk.yaml"
    made = subprocess.run(
        [sys.executable, "-m", "hapticdesk", "init", str(layout), "--desk", "kitamura2017"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert made.returncode == 0, made.stderr
    assert f"wrote {layout}" in made.stdout
    scene = tmp_path / "taps.yaml"  # taps at (0, 0), init's button, and at (20, -10) cm
    scene.write_text(SCENE, encoding="utf-8")
    ui = UiProcess(layout, scene, "--actions")
    context = browser.new_context(viewport=DESKTOP)
    try:
        page = context.new_page()
        errors: list[str] = []
        page.on("pageerror", lambda err: errors.append(str(err)))
        page.goto(ui.url)
        page.wait_for_selector("#region-button")  # the region init wrote
        # draw `pad` where the simulated finger also taps, and bind a tap there to `log`
        page.click("#tab-designer")
        page.wait_for_function("document.getElementById('yaml').value.includes('button')")
        draw_rectangle(page, "pad", (0.15, -0.05), (0.25, -0.15))
        page.select_option("#bind-region", "pad")
        page.select_option("#bind-gesture", "tap")
        page.select_option("#bind-action", "log")
        page.fill("#aopt-message", "{{ region }} {{ gesture }} fired")
        page.click("#bind-add")
        page.wait_for_function("document.getElementById('yaml').value.includes('region: pad')")
        page.eval_on_selector("#yaml", "t => { t.scrollTop = t.scrollHeight; }")
        IMAGES.mkdir(parents=True, exist_ok=True)
        page.screenshot(path=str(IMAGES / "designer-desktop.png"))
        page.click("#save")
        page.wait_for_function(
            "document.getElementById('save-status').textContent.startsWith('saved')"
        )
        assert page.text_content("#save-status") == "saved; the running desk uses it now"
        saved = layout.read_text(encoding="utf-8")
        assert saved.startswith("# A layout for hapticdesk, started by `hapticdesk init`")
        assert "pad:" in saved and "region: pad" in saved
        # the running desk fires the tap on `pad`: the page shows it and its action ran
        page.click("#tab-live")
        page.wait_for_function(
            "[...document.querySelectorAll('#events li')]"
            ".some(li => / tap pad /.test(li.textContent))",
            timeout=15000,
        )
        page.wait_for_function(
            "[...document.querySelectorAll('#actions li')]"
            ".some(li => /\\(tap in pad\\) → log: [1-9]\\d* done/.test(li.textContent))",
            timeout=15000,
        )
        assert page.text_content("#actions-hint") == ""  # actions run: no "off" hint
        assert any("[" in line and "pad tap fired" in line for line in ui.printed), ui.printed
        assert ui.proc.poll() is None
        assert not errors, errors
    finally:
        context.close()
        ui.stop()


def test_the_designer_fits_a_phone(browser: Any, tmp_path: Any) -> None:
    """`ui --layout NEW.yaml` starts the file itself; its designer on a 390×844 screen."""
    layout = tmp_path / "new.yaml"
    scene = tmp_path / "taps.yaml"
    scene.write_text(SCENE, encoding="utf-8")
    ui = UiProcess(layout, scene)
    context = browser.new_context(viewport=PHONE)
    try:
        assert layout.is_file()
        assert any(f"created {layout}" in line for line in ui.lines), ui.lines
        page = context.new_page()
        page.goto(ui.url)
        page.wait_for_selector("#region-button")
        page.click("#tab-designer")
        page.wait_for_function("document.getElementById('yaml').value.includes('button')")
        assert page.evaluate("document.scrollingElement.scrollWidth") <= PHONE["width"]
        IMAGES.mkdir(parents=True, exist_ok=True)
        page.screenshot(path=str(IMAGES / "designer-phone.png"), full_page=True)
        check = subprocess.run(
            [sys.executable, "-m", "hapticdesk", "check", str(layout)],
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert check.returncode == 0, check.stderr
    finally:
        context.close()
        ui.stop()


@pytest.mark.parametrize("blank", [False, True])
def test_what_init_writes_is_what_the_page_takes(tmp_path: Any, blank: bool) -> None:
    """The page's own check (POST /api/check, the loader `check` uses) takes init's layout,
    with --blank too (no regions, no bindings: a warning, not an error)."""
    pytest.importorskip("starlette")
    from starlette.testclient import TestClient

    from hapticdesk.commands.init import write_starter
    from hapticdesk.plugins.ui.server import UiServer

    layout = tmp_path / "start.yaml"
    write_starter(layout, "kitamura2017", blank=blank)
    client = TestClient(UiServer(layout, None).app(), base_url="http://127.0.0.1:8765")
    answer = client.post("/api/check", content=layout.read_text(encoding="utf-8"))
    assert answer.status_code == 200
    body = json.loads(answer.text)
    assert body["ok"], body
    assert [r["name"] for r in body["regions"]] == ([] if blank else ["button"])
