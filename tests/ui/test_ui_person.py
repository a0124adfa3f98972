"""The page as a person reads it (issue 32, "the page, for a person"), in a real Chromium at a
desktop's 1400×900 and a phone's 390×844, against `hapticdesk ui` (actions off) on the demo's
layout while a simulated person taps, slides the dimmer and draws circles.

With HAPTICDESK_SCREENSHOTS=docs the pictures the guides show are saved under docs/images/.
"""

from __future__ import annotations

import re
import shutil
from collections.abc import Iterator
from typing import Any

import pytest

from .conftest import DESKTOP, EXAMPLES, IMAGES, PHONE, UiProcess

# tap the lamp, slide the dimmer, tap where no region is, draw a circle; again and again
SCENE = "name: ui-person\ndesk: kitamura2017\nunits: cm\nquiet_s: 2.0\ntimeline:\n" + "".join(
    "  - tap: {point: [-20, -10], peak_n: 5, wait_s: 0.6}\n"
    "  - drag: {from: [-25, 15], to: [15, 15], speed: 15, force_n: 8, wait_s: 0.6}\n"
    "  - tap: {point: [-20, -10], peak_n: 5, wait_s: 0.4}\n"
    "  - stroke: {shape: circle, center: [15, -8], size: 12, speed: 20, wait_s: 0.6}\n"
    for _ in range(25)
)


@pytest.fixture(scope="module")
def service(tmp_path_factory: pytest.TempPathFactory) -> Iterator[UiProcess]:
    folder = tmp_path_factory.mktemp("ui-person")
    layout = folder / "demo.yaml"
    shutil.copy(EXAMPLES / "layouts" / "demo.yaml", layout)
    scene = folder / "person.yaml"
    scene.write_text(SCENE, encoding="utf-8")
    ui = UiProcess(layout, scene)  # no --actions: a preview
    yield ui
    ui.stop()


def open_page(
    browser: Any, service: UiProcess, viewport: dict[str, int]
) -> tuple[Any, Any, list[str]]:
    context = browser.new_context(viewport=viewport)
    page = context.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda err: errors.append(str(err)))
    page.goto(service.url)
    page.wait_for_selector("#region-dimmer")
    return context, page, errors


def events(page: Any) -> list[str]:
    return page.eval_on_selector_all("#events li", "items => items.map(li => li.textContent)")


def wait_for_a_slide_and_taps(page: Any) -> None:
    """Until a slide has ended (one line) and a tap came after it."""
    page.wait_for_function(
        """() => {
            const items = [...document.querySelectorAll('#events li')].map(li => li.textContent);
            const slide = items.findIndex(t => / slide dimmer .* end → dimmer_slide_end$/.test(t));
            return slide > 0 && items.slice(0, slide).some(t => / tap lamp /.test(t));
        }""",
        timeout=40000,
    )


def test_the_live_view_reads_as_one_story_on_a_desktop(browser: Any, service: UiProcess) -> None:
    context, page, errors = open_page(browser, service, DESKTOP)
    wait_for_a_slide_and_taps(page)
    # one live status, nothing "(not live)" beside it
    assert page.text_content("#status") == "live"
    assert "not live" not in (page.text_content("header") or "")
    # a slide is one line with its updates counted; the taps around it stay in view
    lines = events(page)
    slides = [t for t in lines if " slide dimmer " in t]
    assert slides and all(re.search(r"\(\d+ updates\)", t) for t in slides if " end " in t), lines
    ended = next(t for t in slides if t.endswith("dimmer_slide_end"))
    first, last = (float(v) for v in re.findall(r"(\d\.\d\d) → (\d\.\d\d)", ended)[0])
    assert last > first + 0.5  # the dimmer was slid from its left part to its right
    assert sum(" tap lamp " in t for t in lines) >= 1
    assert len(lines) < 40  # not one line per update: 20 of them a second would fill it
    # actions are off: said where the actions would be
    hint = page.text_content("#actions-hint") or ""
    assert "Actions are off" in hint and "--actions" in hint
    assert page.locator("#actions li").count() == 0
    # the force graph has a time axis (seconds before now) and a force axis
    labels = page.eval_on_selector_all("#force-axes text", "ts => ts.map(t => t.textContent)")
    assert "now" in labels and "−5 s" in labels and "0 N" in labels, labels
    # lengths in the layout's units (cm)
    page.wait_for_function("document.getElementById('rx').textContent.endsWith(' cm')")
    # the space used: the desk and the panel share the window's width
    desk_box = page.locator("#desk").bounding_box()
    aside_box = page.locator("aside").bounding_box()
    assert desk_box["width"] + aside_box["width"] > 0.9 * DESKTOP["width"]
    assert desk_box["height"] > 0.6 * DESKTOP["height"]
    IMAGES.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=str(IMAGES / "live-desktop.png"))
    context.close()
    assert not errors, errors


def test_on_a_phone_the_panel_goes_below_the_desk(browser: Any, service: UiProcess) -> None:
    context, page, errors = open_page(browser, service, PHONE)
    wait_for_a_slide_and_taps(page)
    width = page.evaluate("document.scrollingElement.scrollWidth")
    assert width <= PHONE["width"]  # nothing to scroll sideways
    desk_box = page.locator("#desk").bounding_box()
    aside_box = page.locator("aside").bounding_box()
    assert desk_box["width"] > 0.9 * PHONE["width"]
    assert aside_box["y"] >= desk_box["y"] + desk_box["height"]
    IMAGES.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=str(IMAGES / "live-phone.png"), full_page=True)
    context.close()
    assert not errors, errors


def test_an_open_stroke_is_drawn_open(browser: Any, service: UiProcess, to_screen: Any) -> None:
    """A stroke drawn in the Strokes tab was filled (a Z looked like an hourglass)."""
    context, page, errors = open_page(browser, service, DESKTOP)
    page.click("#tab-strokes")
    corners = [(-0.08, 0.06), (0.08, 0.06), (-0.08, -0.06), (0.08, -0.06)]  # a Z
    page.mouse.move(*to_screen(page, *corners[0]))
    page.mouse.down()
    for (ax, ay), (bx, by) in zip(corners, corners[1:], strict=False):
        for k in range(1, 9):
            page.mouse.move(*to_screen(page, ax + (bx - ax) * k / 8, ay + (by - ay) * k / 8))
    fill = page.eval_on_selector("#draft", "d => getComputedStyle(d).fill")
    assert fill == "none", fill
    page.mouse.up()
    context.close()
    assert not errors, errors


def test_the_set_up_points_are_in_the_layouts_units(browser: Any, service: UiProcess) -> None:
    context, page, errors = open_page(browser, service, DESKTOP)
    page.click("#tab-setup")
    assert "cm" in (page.text_content("label[for=setup-points]") or "")
    points = page.evaluate("JSON.parse(document.getElementById('setup-points').value)")
    # the paper's desk is 75 × 50 cm: its marks lie up to 25 cm from the middle, written in cm
    assert max(abs(v) for p in points for v in p) == pytest.approx(25, abs=0.1)
    # and drawn where those centimetres are (the marks' crosses, in the SVG's millimetres)
    xs = page.eval_on_selector_all(
        "#marks .mark-label", "ts => ts.map(t => Number(t.getAttribute('x')))"
    )
    assert max(xs) == pytest.approx(250 + 10, abs=1)
    context.close()
    assert not errors, errors
