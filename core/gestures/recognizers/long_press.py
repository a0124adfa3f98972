"""Long presses with hold tiers (libinput-gestures' habit): a binding with ``hold_s: 0.8``
fires when the finger has stayed still for 0.8 s, one with ``hold_s: 1.5`` at 1.5 s, and so
on. After a tier was reached, the release gives an event with phase ``end`` (Zigbee2MQTT's
``hold`` then ``release``); bindings with ``release: true`` react to that one.
"""

from __future__ import annotations

from collections.abc import Sequence

from hapticdesk.estimator.contacts import ContactEvent
from hapticdesk.gestures.event import GestureEvent
from hapticdesk.gestures.layout import Binding, Layout
from hapticdesk.gestures.recognizer import BoundRegions, Recognizer
from hapticdesk.gestures.touch import Touch


class LongPressRecognizer(Recognizer):
    """``long_press``."""

    gestures = ("long_press",)

    def __init__(self, layout: Layout, bindings: Sequence[Binding]) -> None:
        super().__init__(layout, bindings)
        self.bound = BoundRegions(layout, "long_press")
        self.tiers: dict[str | None, list[float]] = {}
        for b in self.bindings:
            self.tiers.setdefault(b.region, []).append(b.options["hold_s"])
        self.tiers = {r: sorted(set(ts)) for r, ts in self.tiers.items()}
        self.first_tier = min(t for ts in self.tiers.values() for t in ts) if self.tiers else 0.0
        self._reset()

    def _reset(self) -> None:
        self._region: str | None = None
        self._placed = False
        self._cancelled = False
        self._next = 0  # index of the next tier to reach
        self._reached: float | None = None  # the highest tier fired
        self._x = self._y = 0.0

    def on_contact(self, event: ContactEvent, touch: Touch) -> list[GestureEvent]:
        if event.kind == "down":
            self._reset()
            return []
        if event.kind == "up":
            reached, region, x, y = self._reached, self._region, self._x, self._y
            self._reset()
            if reached is None:
                return []
            return [
                GestureEvent(
                    event.t, "long_press", region, x, y, phase="end", hold_s=reached,
                    extra={"duration_s": round(touch.duration(), 6)},
                )
            ]  # fmt: skip
        if self._cancelled or not touch.located:
            return []
        if event.t < touch.t_down + self.first_tier:
            return []
        if not self._placed:
            self._placed = True
            x, y, _ = touch.best()
            found, self._region = self.bound.find(x, y, touch.surface)
            if not found:
                self._cancelled = True
                return []
        tiers = self.tiers[self._region]
        out: list[GestureEvent] = []
        while self._next < len(tiers) and event.t >= touch.t_down + tiers[self._next]:
            x, y, _ = touch.best()
            if touch.moved(x, y) > self.bound.options(self._region)["max_move"]:
                self._cancelled = True
                break
            self._x, self._y = x, y
            self._reached = tiers[self._next]
            out.append(
                GestureEvent(
                    event.t, "long_press", self._region, x, y, hold_s=tiers[self._next],
                    force_n=touch.force_n,
                )
            )  # fmt: skip
            self._next += 1
        return out
