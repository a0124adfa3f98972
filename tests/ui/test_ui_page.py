"""The page in a real headless Chromium against a running `hapticdesk ui` (README, "Browser UI").

One service for the module, the tests in order: the live tap, a broken edit, the designer's
save that the running service then uses, a stroke template recorded in the page.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from typing import Any

import pytest

from .conftest import DESKTOP, DOCS, draw_rectangle


@pytest.fixture(scope="module")
def page(browser: Any, ui_service: Any) -> Any:
    context = browser.new_context(viewport=DESKTOP)
    p = context.new_page()
    errors: list[str] = []
    p.on("pageerror", lambda err: errors.append(str(err)))
    p.goto(ui_service.url)
    p.wait_for_selector("#region-b5")
    yield p
    context.close()
    assert not errors, f"the page raised: {errors}"


def test_live_view_shows_a_simulated_tap_in_its_region(page: Any, ui_service: Any) -> None:
    # the dot appears where the simulated finger taps: in b5, or (before the designer draws a
    # region there) at (20, -10) cm where no region is
    page.wait_for_function(
        "document.getElementById('last-region').textContent === 'b5'", timeout=15000
    )
    page.wait_for_function(
        "Number(document.getElementById('touch').getAttribute('r')) > 0"
        " && document.getElementById('touch-region').textContent === 'b5'",
        timeout=10000,
    )
    assert "hot" in (page.get_attribute("#region-b5", "class") or "")
    assert page.locator("#region-b4.hot").count() == 0
    DOCS.mkdir(exist_ok=True)
    page.screenshot(path=str(DOCS / "ui-live.png"))
    # the gesture arrives as an event, in the right region; the tare as a notice is not
    # asserted (it may come before the page connects)
    page.wait_for_function(
        "[...document.querySelectorAll('#events li')].some(li => / tap b5 /.test(li.textContent))",
        timeout=10000,
    )
    force = page.get_attribute("#force-line", "points") or ""
    assert len(force.split()) > 20  # the force over the last seconds is drawn


def test_a_broken_edit_shows_its_error_on_the_field(page: Any, ui_service: Any) -> None:
    before = ui_service.layout.read_text()
    page.click("#tab-designer")
    page.wait_for_function("document.getElementById('yaml').value.includes('b5')")
    text = page.input_value("#yaml")
    broken = text.replace("b5: {rect: [-2.5, -2.5, 2.5, 2.5]}", "b5: {rect: [-2.5, -2.5, 2.5]}")
    assert broken != text
    line = next(i + 1 for i, t in enumerate(broken.splitlines()) if t.startswith("  b5:"))
    page.fill("#yaml", broken)
    page.dispatch_event("#yaml", "input")
    page.wait_for_function("document.getElementById('yaml-error').textContent.length > 0")
    message = page.text_content("#yaml-error") or ""
    assert message.startswith(f"line {line}, column "), message
    assert "rect" in message
    assert "invalid" in (page.get_attribute("#yaml", "class") or "")
    page.click("#save")
    page.wait_for_function("document.getElementById('save-status').textContent === 'not saved'")
    assert ui_service.layout.read_text() == before  # nothing written
    page.fill("#yaml", text)  # put it back
    page.dispatch_event("#yaml", "input")
    page.wait_for_function("document.getElementById('yaml-error').textContent === ''")


def test_a_drawn_rectangle_with_a_tap_is_saved_checked_and_used(page: Any, ui_service: Any) -> None:
    draw_rectangle(page, "pad", (0.15, -0.05), (0.25, -0.15))
    drawn = re.search(r"\n  pad: \{rect: \[([^\]]+)\]\}\n", page.input_value("#yaml"))
    assert drawn, page.input_value("#yaml")
    corners = [float(v) for v in drawn.group(1).split(",")]
    assert corners == pytest.approx([15, -15, 25, -5], abs=0.3)  # cm, as the layout's units
    page.select_option("#bind-region", "pad")
    page.select_option("#bind-gesture", "tap")
    page.select_option("#bind-action", "log")
    page.click("#bind-add")
    page.wait_for_function("document.getElementById('yaml').value.includes('region: pad')")
    page.eval_on_selector("#yaml", "t => { t.scrollTop = t.scrollHeight; }")
    page.screenshot(path=str(DOCS / "ui-designer.png"))
    page.click("#save")
    page.wait_for_function("document.getElementById('save-status').textContent.startsWith('saved')")
    assert page.text_content("#save-status") == "saved; the running desk uses it now"
    saved = ui_service.layout.read_text()
    assert saved.startswith("# A 3 × 3 grid of 5 cm buttons")  # the user's comments kept
    assert saved.index("b9:") < saved.index("pad:")  # and their order
    check = subprocess.run(
        [sys.executable, "-m", "hapticdesk", "check", str(ui_service.layout)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert check.returncode == 0, check.stderr
    assert "pad" in check.stdout
    # the running service taps at (20, -10) cm: now inside `pad`, without a restart
    page.click("#tab-live")
    page.wait_for_function(
        "[...document.querySelectorAll('#events li')].some(li => / tap pad /.test(li.textContent))",
        timeout=10000,
    )
    assert ui_service.proc.poll() is None


def test_a_stroke_template_recorded_in_the_page_is_recognised(
    page: Any, ui_service: Any, to_screen: Any
) -> None:
    page.click("#tab-strokes")

    def draw(scale: float, dx: float) -> None:
        # a W, 16 cm wide, drawn with the mouse
        corners = [(-0.08, 0.08), (-0.04, -0.06), (0.0, 0.04), (0.04, -0.06), (0.08, 0.08)]
        pts = [(dx + x * scale, 0.02 + y * scale) for x, y in corners]
        sx, sy = to_screen(page, *pts[0])
        page.mouse.move(sx, sy)
        page.mouse.down()
        for (ax, ay), (bx, by) in zip(pts, pts[1:], strict=False):
            for k in range(1, 11):
                px, py = to_screen(page, ax + (bx - ax) * k / 10, ay + (by - ay) * k / 10)
                page.mouse.move(px, py)
        page.mouse.up()

    draw(1.0, 0.0)
    page.wait_for_function("document.querySelectorAll('#stroke-scores li').length > 0")
    page.fill("#stroke-name", "my_w")
    page.click("#stroke-keep")
    page.wait_for_function(
        "document.getElementById('record-status').textContent === 'kept as my_w'"
    )
    assert "my_w:" in ui_service.layout.read_text()
    # a second W, smaller and elsewhere, is recognised as the kept shape
    page.click("#stroke-discard")
    draw(0.8, 0.05)
    page.wait_for_function(
        "document.getElementById('stroke-result').textContent.startsWith('recognised: my_w')",
        timeout=10000,
    )


def test_the_set_up_panel_marks_points_and_reports_a_session(page: Any, ui_service: Any) -> None:
    page.click("#tab-setup")
    points = json.loads(page.input_value("#setup-points"))
    assert len(points) == 6
    assert page.locator("#marks .mark-label").count() == 6
    page.click("#setup-start")
    page.wait_for_function(
        "/^(keep the desk quiet|press point)/.test(document.getElementById('setup-status')"
        ".textContent)"
    )
    page.wait_for_timeout(2500)  # the simulated desk taps, it does not press the marks
    page.click("#setup-finish")
    page.wait_for_function("document.getElementById('setup-error').textContent.length > 0")
    assert re.search(r"expected 6 presses .* found \d", page.text_content("#setup-error") or "")


def test_a_polygon_is_drawn_corner_by_corner_and_ended_by_a_double_click(
    page: Any, to_screen: Any
) -> None:
    """The draft drawn under the pointer at each corner had taken the double click: no
    polygon was ever finished. Three corners, a double click on the last: one region of three."""
    page.click("#tab-designer")
    page.check("#tool-polygon")
    page.fill("#region-name", "tri")
    corners = [(0.0, -0.18), (0.05, -0.12), (-0.05, -0.12)]
    for x, y in corners[:-1]:
        page.mouse.click(*to_screen(page, x, y))
    page.mouse.click(*to_screen(page, *corners[-1]))
    page.mouse.dblclick(*to_screen(page, *corners[-1]))
    page.wait_for_selector("#region-tri")
    drawn = re.search(r"\n  tri: \{polygon: (\[\[.*\]\])\}\n", page.input_value("#yaml"))
    assert drawn, page.input_value("#yaml")
    points = [v for point in json.loads(drawn.group(1)) for v in point]  # cm, the layout's
    assert points == pytest.approx([100 * v for point in corners for v in point], abs=0.5)


def test_a_refused_drawing_says_why_beside_the_tools(page: Any, to_screen: Any) -> None:
    """A region drawn under a name no layout takes was refused without a word (the drawing
    gone, nothing said); a name the checker takes, with a dash, is now taken by the designer."""
    page.click("#tab-designer")
    page.check("#tool-rect")
    for name, refused in (("9lives", True), ("desk-lamp", False)):
        page.fill("#region-name", name)
        x0, y0 = to_screen(page, -0.30, 0.20)
        x1, y1 = to_screen(page, -0.25, 0.15)
        page.mouse.move(x0, y0)
        page.mouse.down()
        page.mouse.move(x1, y1)
        page.mouse.up()
        if refused:
            page.wait_for_function("document.getElementById('draw-error').textContent !== ''")
            assert "must start with a letter" in page.text_content("#draw-error")
        else:
            page.wait_for_selector(f"#region-{name}")
            assert page.text_content("#draw-error") == ""
