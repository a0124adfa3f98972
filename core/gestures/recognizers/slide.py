"""Sliders: a touch that starts on a region with an ``axis`` gives its position along the
axis as a value 0..1, with begin (at the first located sample, so touching a dimmer sets it),
update (rate-limited by ``interval_s`` and ``step``) and end (at the release), or cancel
when the touch broke off without a release (a gap, a stop, the end of a recording). The finger
may leave the region while sliding; the value then stays clipped to 0 or 1 (``leave: clip``,
the default), or the slide ends there with phase cancel and the value it had last on the
region (``leave: cancel``; nothing more for that touch, no end at the release).
"""

from __future__ import annotations

from collections.abc import Sequence

from hapticdesk.estimator.contacts import ContactEvent
from hapticdesk.gestures.event import GestureEvent
from hapticdesk.gestures.layout import Binding, Layout
from hapticdesk.gestures.recognizer import BoundRegions, Recognizer
from hapticdesk.gestures.touch import Touch


class SlideRecognizer(Recognizer):
    """``slide``."""

    gestures = ("slide",)

    def __init__(self, layout: Layout, bindings: Sequence[Binding]) -> None:
        super().__init__(layout, bindings)
        self.bound = BoundRegions(layout, "slide")
        self._reset()

    def _reset(self) -> None:
        self._state = "idle"  # idle -> active | ignored
        self._region: str | None = None
        self._last_t = 0.0
        self._last_value = 0.0
        self._value = 0.0
        self._xy = (0.0, 0.0)

    def on_contact(self, event: ContactEvent, touch: Touch) -> list[GestureEvent]:
        if event.kind == "down":
            self._reset()
        if event.kind == "up":
            active, region, value, (x, y) = (
                self._state == "active", self._region, self._value, self._xy
            )  # fmt: skip
            self._reset()
            return [self._event(event.t, region, x, y, value, "end")] if active else []
        if self._state == "ignored" or not touch.located:
            return []
        x, y = touch.current()
        begin = self._state == "idle"
        if begin:
            found, self._region = self.bound.find(x, y, touch.surface)
            if not found or self._region is None:
                self._state = "ignored"
                return []
            self._state = "active"
        assert self._region is not None
        if self.bound.left(self._region, x, y):
            region, value, (x0, y0) = self._region, self._value, self._xy
            self._state = "ignored"  # until the next touch: no update, no end
            return [self._event(event.t, region, x0, y0, value, "cancel")]
        value = float(self.layout.regions[self._region].value_along(x, y))
        self._value, self._xy = value, (x, y)
        o = self.bound.options(self._region)
        if begin or (
            event.t - self._last_t >= o["interval_s"] and abs(value - self._last_value) >= o["step"]
        ):
            self._last_t, self._last_value = event.t, value
            phase = "begin" if begin else "update"
            return [self._event(event.t, self._region, x, y, value, phase)]
        return []

    def cancel(self, t: float, touch: Touch) -> list[GestureEvent]:
        active, region, value, (x, y) = (
            self._state == "active", self._region, self._value, self._xy
        )  # fmt: skip
        self._reset()
        return [self._event(t, region, x, y, value, "cancel")] if active else []

    @staticmethod
    def _event(
        t: float, region: str | None, x: float, y: float, value: float, phase: str
    ) -> GestureEvent:
        return GestureEvent(t, "slide", region, x, y, value=value, phase=phase)
