"""The set-up with a known weight in a real headless Chromium against a running `hapticdesk
ui` on a simulated 80 Hz load-cell desk: the page names a bad mass, shows the spots in cm,
records a 1 kg weight put on each in turn, and shows the fit, its check in mm and the profile
it wrote."""

from __future__ import annotations

import re
import shutil
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from hapticdesk.analysis.known_weight import suggested_spots
from hapticdesk.files.profile_reader import load_profile

from .conftest import DESKTOP, EXAMPLES, IMAGES, UiProcess

DESK = "kitamura2017-loadcells-80hz"
#: nobody touches the desk for this long first: the page is opened and Start pressed in it
QUIET_S = 12.0
PUT_S, REST_S, EMPTY_S, LIFT_S = 0.4, 2.0, 2.0, 0.3


def weight_scene(points: Any) -> str:
    """1 kg put on each point in turn, lifted off between them (a scene file's text)."""
    lines = [f"name: weight\ndesk: {DESK}\nquiet_s: {QUIET_S}\ntail_s: 2.0\ntimeline:"]
    for x, y in points:
        lines.append(
            f"  - put: {{object: sugar, mass_kg: 1.0, point: [{x:.5f}, {y:.5f}], "
            f"duration_s: {PUT_S}, wait_s: {EMPTY_S}}}"
        )
        lines.append(f"  - lift: {{object: sugar, duration_s: {LIFT_S}, wait_s: {REST_S}}}")
    return "\n".join(lines) + "\n"


@pytest.fixture(scope="module")
def weight_service(tmp_path_factory: pytest.TempPathFactory) -> Iterator[UiProcess]:
    folder = tmp_path_factory.mktemp("weight-page")
    layout = folder / "buttons.yaml"
    text = (EXAMPLES / "layouts" / "buttons.yaml").read_text(encoding="utf-8")
    layout.write_text(text.replace("desk: kitamura2017\n", f"desk: {DESK}\n"), encoding="utf-8")
    assert f"desk: {DESK}" in layout.read_text()
    scene = folder / "weight.yaml"
    scene.write_text(weight_scene(suggested_spots(load_profile(DESK), 4)), encoding="utf-8")
    service = UiProcess(layout, scene)
    service.started = time.monotonic()  # type: ignore[attr-defined]
    yield service
    service.stop()
    shutil.rmtree(folder, ignore_errors=True)


def test_the_page_calibrates_load_cells_with_a_known_weight(
    browser: Any, weight_service: UiProcess
) -> None:
    context = browser.new_context(viewport=DESKTOP)
    page = context.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda err: errors.append(str(err)))
    page.goto(weight_service.url)
    page.wait_for_selector("#sensors circle")
    page.click("#tab-setup")
    # a mass that is not a number, and one not above 0: said beside the field, nothing starts
    for typed, needle in (("a bag", "found 'a bag'"), ("0", "a mass above 0"), ("", "none was")):
        page.fill("#weight-mass", typed)
        page.click("#weight-start")
        page.wait_for_function(
            "(needle) => document.getElementById('weight-error').textContent.includes(needle)",
            arg=needle,
        )
        assert "invalid" in (page.get_attribute("#weight-mass", "class") or "")
        assert "Traceback" not in (page.text_content("#weight-error") or "")
    # the spots: drawn on the desk and listed in cm
    page.select_option("#weight-count", "4")
    page.click("#weight-show")
    page.wait_for_function("document.querySelectorAll('#weight-spots li').length === 4")
    spots = suggested_spots(load_profile(DESK), 4)
    listed = page.locator("#weight-spots li").all_text_contents()
    for (x, y), text in zip(spots, listed, strict=True):
        assert text == f"x {x * 100:.1f} cm, y {y * 100:.1f} cm"
    assert page.locator("#marks .mark-label").count() == 4
    page.fill("#weight-mass", "1")
    page.click("#weight-start")
    page.wait_for_function(
        "document.getElementById('weight-status').textContent.includes('spot 1 of 4')"
    )
    assert time.monotonic() - weight_service.started < QUIET_S, "started after the first put"  # type: ignore[attr-defined]
    # the simulated person puts the weight on each spot in turn; the page follows
    page.wait_for_function(
        "document.getElementById('weight-status').textContent.startsWith('spot 2')",
        timeout=30000,
    )
    scene_s = QUIET_S + 4 * (EMPTY_S + PUT_S + REST_S + LIFT_S) + 1.0
    left = scene_s - (time.monotonic() - weight_service.started)  # type: ignore[attr-defined]
    page.wait_for_timeout(max(0.0, left) * 1000)
    page.click("#weight-finish")
    page.wait_for_function(
        "document.getElementById('weight-check').textContent.length > 0", timeout=30000
    )
    check = page.text_content("#weight-check") or ""
    found = re.search(r"check spot 4, not in the fit: placed (\d+\.\d) mm from its mark", check)
    assert found, (check, page.text_content("#weight-error"))
    assert float(found.group(1)) < 5.0 and check.endswith("good")
    rows = page.locator("#weight-cells tr").all_text_contents()
    assert len(rows) == 5 and all(" cm" in row and " mm" in row for row in rows[1:])
    assert page.locator("#marks .measured").count() == 4  # each spot placed by a fit without it
    written = Path(weight_service.layout.parent / f"{DESK}-calibrated.yaml")
    assert written.exists() and load_profile(written).name == DESK
    assert str(written) in (page.text_content("#weight-profile") or "")
    IMAGES.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=str(IMAGES / "weight-setup-desktop.png"))
    # finished: nothing left to finish, and the page says so
    page.click("#weight-finish")
    page.wait_for_function(
        "document.getElementById('weight-error').textContent.includes('no set-up with a known')"
    )
    context.close()
    assert not errors, f"the page raised: {errors}"
