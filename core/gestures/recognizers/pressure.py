"""Pressure gestures: ``press`` with named force levels, and ``force``, a continuous value.

``press`` fires when the force rises past a level (light, firm, hard, …) and re-arms that
level once the force has dropped ``hysteresis_n`` below it, so a trembling finger at the
threshold does not fire twice. A touch the stream resumed with after a gap (its start
unseen) fires only the levels its force rises past after the gap, not those it is above.
``force`` maps the force between ``min_n`` and ``max_n`` to 0..1 with begin/update/end,
updates rate-limited by ``interval_s`` and ``step``; a touch that broke off without a release
ends with ``cancel`` (value 0: the force is not known), and so does one that leaves its
region when the binding says ``leave: cancel`` (the value it had last on the region).
"""

from __future__ import annotations

from collections.abc import Sequence

from hapticdesk.estimator.contacts import ContactEvent
from hapticdesk.gestures.event import GestureEvent
from hapticdesk.gestures.layout import Binding, Layout
from hapticdesk.gestures.recognizer import BoundRegions, Recognizer
from hapticdesk.gestures.touch import Touch


class PressRecognizer(Recognizer):
    """``press``."""

    gestures = ("press",)

    def __init__(self, layout: Layout, bindings: Sequence[Binding]) -> None:
        super().__init__(layout, bindings)
        self.bound = BoundRegions(layout, "press")
        self.lowest = min(min(b.options["levels"].values()) for b in self.bindings)
        self._reset()

    def _reset(self) -> None:
        self._placed = False
        self._ignore = False
        self._region: str | None = None
        self._armed: dict[str, bool] = {}

    def on_contact(self, event: ContactEvent, touch: Touch) -> list[GestureEvent]:
        if event.kind == "up":
            self._reset()
            return []
        if event.kind == "down":
            self._reset()
        force = event.force_n
        if self._ignore or not touch.located:
            return []
        if not self._placed:
            if force < self.lowest:
                return []  # place the press where it is when it first matters
            self._placed = True
            x, y, _ = touch.best()
            found, self._region = self.bound.find(x, y, touch.surface)
            if not found:
                self._ignore = True
                return []
            levels = self.bound.options(self._region)["levels"]
            # a touch already down when the stream came back from a gap: the levels it was
            # above then fired before the gap (or rose unseen); only a rise past one fires
            self._armed = {n: not touch.began_unseen or force < v for n, v in levels.items()}
        options = self.bound.options(self._region)
        out: list[GestureEvent] = []
        for name, level in options["levels"].items():
            if self._armed[name] and force >= level:
                self._armed[name] = False
                x, y, _ = touch.best()
                out.append(
                    GestureEvent(event.t, "press", self._region, x, y, level=name, force_n=force)
                )
            elif not self._armed[name] and force < level - options["hysteresis_n"]:
                self._armed[name] = True
        return out

    def cancel(self, t: float, touch: Touch) -> list[GestureEvent]:
        self._reset()
        return []


class ForceRecognizer(Recognizer):
    """``force``: value 0..1 from the force while the finger stays on the region."""

    gestures = ("force",)

    def __init__(self, layout: Layout, bindings: Sequence[Binding]) -> None:
        super().__init__(layout, bindings)
        self.bound = BoundRegions(layout, "force")
        self._reset()

    def _reset(self) -> None:
        self._state = "idle"  # idle -> active | ignored
        self._region: str | None = None
        self._last_t = 0.0
        self._last_value = 0.0

    def _value(self, force: float) -> float:
        o = self.bound.options(self._region)
        return min(1.0, max(0.0, (force - o["min_n"]) / (o["max_n"] - o["min_n"])))

    def on_contact(self, event: ContactEvent, touch: Touch) -> list[GestureEvent]:
        if event.kind == "down":
            self._reset()
        if event.kind == "up":
            active = self._state == "active"
            region = self._region
            value = self._value(event.force_n) if active else 0.0
            self._reset()
            if not active:
                return []
            x, y, _ = touch.best()
            return [self._event(event.t, region, x, y, value, "end", event.force_n)]
        if self._state == "ignored" or not touch.located:
            return []
        x, y, _ = touch.best()
        if self._state == "idle":
            found, self._region = self.bound.find(x, y, touch.surface)
            if not found:
                self._state = "ignored"
                return []
            self._state = "active"
            value = self._value(event.force_n)
            self._last_t, self._last_value = event.t, value
            return [self._event(event.t, self._region, x, y, value, "begin", event.force_n)]
        if self.bound.left(self._region, *touch.current()):
            region, value = self._region, self._last_value
            self._state = "ignored"  # until the next touch: no update, no end
            return [self._event(event.t, region, x, y, value, "cancel", event.force_n)]
        value = self._value(event.force_n)
        o = self.bound.options(self._region)
        if event.t - self._last_t >= o["interval_s"] and abs(value - self._last_value) >= o["step"]:
            self._last_t, self._last_value = event.t, value
            return [self._event(event.t, self._region, x, y, value, "update", event.force_n)]
        return []

    def cancel(self, t: float, touch: Touch) -> list[GestureEvent]:
        active, region = self._state == "active", self._region
        self._reset()
        if not active:
            return []
        x, y, _ = touch.best()
        return [self._event(t, region, x, y, 0.0, "cancel", touch.force_n)]

    @staticmethod
    def _event(
        t: float, region: str | None, x: float, y: float, value: float, phase: str, force: float
    ) -> GestureEvent:
        return GestureEvent(t, "force", region, x, y, value=value, phase=phase, force_n=force)
