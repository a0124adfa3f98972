"""The built-in gesture recognizers, registered like any plugin's.

Each gesture maps to a lazy ``"module:Class"`` string, so a layout that binds only taps never
imports the stroke recognizer (python-can's ``BACKENDS`` habit, STYLE.md 4). One class may
serve several gestures (taps and double taps are told apart by one recognizer); the engine
then builds it once.
"""

from __future__ import annotations

from typing import Any

from hapticdesk.hookspecs import hookimpl

_PACKAGE = "hapticdesk.gestures.recognizers"

#: gesture -> ("module:Class", description)
RECOGNIZERS: dict[str, tuple[str, str]] = {
    "tap": (f"{_PACKAGE}.taps:TapRecognizer", "a short touch"),
    "double_tap": (f"{_PACKAGE}.taps:TapRecognizer", "two taps in quick succession"),
    "two_finger_tap": (
        f"{_PACKAGE}.taps:TapRecognizer",
        "a short touch with a second finger landing beside the first",
    ),
    "long_press": (f"{_PACKAGE}.long_press:LongPressRecognizer", "a touch held in place"),
    "press": (f"{_PACKAGE}.pressure:PressRecognizer", "a touch pressed harder than a tap"),
    "force": (f"{_PACKAGE}.pressure:ForceRecognizer", "force levels while touching"),
    "swipe": (f"{_PACKAGE}.swipe:SwipeRecognizer", "a quick straight stroke, by direction"),
    "slide": (f"{_PACKAGE}.slide:SlideRecognizer", "a position along a slider's axis"),
    "stroke": (f"{_PACKAGE}.stroke:StrokeRecognizer", "a drawn shape, by template"),
}


@hookimpl
def register_recognizers(register: Any) -> None:
    for gesture, (target, description) in RECOGNIZERS.items():
        register(gesture, target, description)
