"""Long presses with hold tiers (libinput-gestures' habit): a binding with ``hold_s: 0.8``
fires when the finger has stayed still for 0.8 s, one with ``hold_s: 1.5`` at 1.5 s, and so
on. After a tier was reached, the release gives an event with phase ``end`` (Zigbee2MQTT's
``hold`` then ``release``); bindings with ``release: true`` react to that one.

A binding with ``repeat: true`` keeps firing while the finger stays (hold to dim, like a
keyboard's auto-repeat): events with phase ``repeat`` every ``interval_s`` after its tier.
A held press that ends without a release being seen (a gap, a stop, the end of a recording)
or that moves away after a tier ends with phase ``cancel`` instead of ``end``. A touch the
stream resumed with after a gap (its start unseen) holds no tier: how long it was held is not
known, and the tiers it reached before the gap fired then.

A load as still as an object put down (the estimator's ``resting``) holds no tier until the
estimator has decided: an object joins the zero and its touch ends without an event; a
finger soon trembles or wanders, and the tiers due by then fire. A load that rested while a
tier was due holds none while it is released: a cup lifted before it was judged.
"""

from __future__ import annotations

from collections.abc import Sequence

from hapticdesk.estimator.contacts import ContactEvent
from hapticdesk.gestures.event import GestureEvent
from hapticdesk.gestures.layout import Binding, Layout
from hapticdesk.gestures.recognizer import BoundRegions, Recognizer
from hapticdesk.gestures.touch import Touch

#: whether the finger left the spot is judged from when the force first reached this share of
#: the touch's peak so far (the rise left out). A firm press's rise is placed least well (the
#: error goes as 1/force), and on sensors quieter than their resolution step by more than its
#: σ says: 15-25 N presses on the paper's desk at half its noise had their first points 2 cm
#: off at 2-8 N and were cancelled 21 times in 60 when judged on every pressed sample
HOLD_FORCE_SHARE = 0.5


class LongPressRecognizer(Recognizer):
    """``long_press``."""

    gestures = ("long_press",)

    def __init__(self, layout: Layout, bindings: Sequence[Binding]) -> None:
        super().__init__(layout, bindings)
        self.bound = BoundRegions(layout, "long_press")
        tiers: dict[str | None, set[float]] = {}
        repeating: dict[str | None, set[float]] = {}
        for b in self.bindings:
            tiers.setdefault(b.region, set()).add(b.options["hold_s"])
            if b.options["repeat"]:
                repeating.setdefault(b.region, set()).add(b.options["hold_s"])
        self.tiers = {r: sorted(ts) for r, ts in tiers.items()}
        #: region -> the tiers a `repeat: true` binding listens to
        self.repeating = {r: sorted(ts) for r, ts in repeating.items()}
        self.first_tier = min(t for ts in self.tiers.values() for t in ts) if self.tiers else 0.0
        self._reset()

    def _reset(self) -> None:
        self._region: str | None = None
        self._placed = False
        self._cancelled = False
        self._rested = False  # the load was resting while a tier was due
        self._next = 0  # index of the next tier to reach
        self._reached: float | None = None  # the highest tier fired
        self._repeats: dict[float, float] = {}  # repeating tier -> sample time of its next repeat
        self._x = self._y = 0.0

    def on_contact(self, event: ContactEvent, touch: Touch) -> list[GestureEvent]:
        if event.kind == "down":
            self._reset()
            return []
        if event.kind == "up":
            reached, region, x, y = self._reached, self._region, self._x, self._y
            cancelled = self._cancelled
            self._reset()
            if reached is None or cancelled:
                return []
            return [
                GestureEvent(
                    event.t, "long_press", region, x, y, phase="end", hold_s=reached,
                    extra={"duration_s": round(touch.duration(), 6)},
                )
            ]  # fmt: skip
        if self._cancelled or not touch.located or touch.began_unseen:
            return []  # (a touch whose start a gap hid: how long it was held is not known)
        if event.t < touch.t_down + self.first_tier:
            return []
        if touch.resting and self._reached is None:
            # as still as an object put down: a cup on the button must not hold it. The
            # estimator decides within 0.6-0.8 s of stillness: an object ends the touch (it
            # joins the zero), a finger's tremor or wander ends the resting and the due tiers
            # fire then. (Once a tier fired, the touch was a finger: repeats go on.)
            self._rested = True
            return []
        if self._rested and self._reached is None and event.phase == "release":
            # a load that rested, leaving: a cup lifted before it was judged is no hold (a
            # finger that wanders fires at its next sample that is not a release)
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
        due = self._next < len(tiers) and event.t >= touch.t_down + tiers[self._next]
        if (due or self._repeat_due(event.t)) and self._moved_off(touch):
            return self._cancel(event.t)
        while self._next < len(tiers) and event.t >= touch.t_down + tiers[self._next]:
            tier = tiers[self._next]
            self._x, self._y, _ = touch.best()
            self._reached = tier
            out.append(self._event(event.t, tier, None, touch.force_n))
            if tier in self.repeating.get(self._region, ()):
                self._repeats[tier] = event.t + self.bound.options(self._region)["interval_s"]
            self._next += 1
        interval = self.bound.options(self._region)["interval_s"]
        for tier, t_next in self._repeats.items():
            if event.t >= t_next:
                out.append(self._event(event.t, tier, "repeat", touch.force_n))
                # on sample time: the next repeat is due one interval after this one was due
                self._repeats[tier] = max(t_next + interval, event.t)
        return out

    def cancel(self, t: float, touch: Touch) -> list[GestureEvent]:
        return self._cancel(t) if self._reached is not None and not self._cancelled else []

    def _repeat_due(self, t: float) -> bool:
        return any(t >= t_next for t_next in self._repeats.values())

    def _moved_off(self, touch: Touch) -> bool:
        """The finger left the spot (checked when something is about to fire, not at every
        sample: ``moved`` looks at the whole touch), judged without the rise, before the force
        first reached HOLD_FORCE_SHARE of its peak so far: it is placed least well."""
        x, y, _ = touch.best()
        moved = touch.moved(x, y, rise_share=HOLD_FORCE_SHARE)
        return moved > self.bound.options(self._region)["max_move"]

    def _cancel(self, t: float) -> list[GestureEvent]:
        """Stop the press here; after a tier, say so with phase ``cancel``."""
        reached = self._reached
        self._cancelled = True
        self._repeats.clear()
        if reached is None:
            return []
        return [self._event(t, reached, "cancel", None)]

    def _event(
        self, t: float, hold_s: float, phase: str | None, force_n: float | None
    ) -> GestureEvent:
        return GestureEvent(
            t, "long_press", self._region, self._x, self._y, phase=phase, hold_s=hold_s,
            force_n=force_n,
        )  # fmt: skip
