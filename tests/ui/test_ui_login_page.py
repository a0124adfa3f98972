"""The token asked by the page in a real headless Chromium: `hapticdesk ui` with a token prints
a bare address; the page opened there asks for the token, a wrong one is said, the right one
opens the live desk (plugins/ui/login.py)."""

from __future__ import annotations

import shutil
from typing import Any

import pytest

from .conftest import DESKTOP, EXAMPLES, SCENE, UiProcess

TOKEN = "a-token-for-the-test-0123"


def test_the_page_asks_for_the_token_and_opens_with_it(
    browser: Any, tmp_path: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    layout = tmp_path / "buttons.yaml"
    shutil.copy(EXAMPLES / "layouts" / "buttons.yaml", layout)
    scene = tmp_path / "taps.yaml"
    scene.write_text(SCENE, encoding="utf-8")
    monkeypatch.setenv("HAPTICDESK_UI_TOKEN", TOKEN)
    ui = UiProcess(layout, scene)
    context = browser.new_context(viewport=DESKTOP)
    try:
        assert TOKEN not in "".join(ui.lines) and "asks for its token" in "".join(ui.lines)
        page = context.new_page()
        page.goto(ui.url)
        page.fill("#token", "not it")
        page.click("input[type=submit]")
        page.wait_for_selector("p.err")
        assert page.locator("#region-b5").count() == 0
        page.fill("#token", TOKEN)
        page.click("input[type=submit]")
        page.wait_for_selector("#region-b5", timeout=15000)  # the live desk, its scripts loaded
        assert TOKEN not in page.url
    finally:
        context.close()
        ui.stop()
    assert TOKEN not in "".join(ui.lines)
