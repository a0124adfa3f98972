"""Taps, double taps and two-finger taps: one state machine, because they decide together.

A touch is a tap when it is short (``max_duration_s``) and does not move (``max_move``, from
the whole touch's place); it is placed where it settled (``Touch.settled``: the last 30 % of
its pressed samples, whose place errs less than the whole touch's on light taps). Where a
double tap is bound at that point, the tap waits up to ``interval_s`` for a second touch;
everywhere else it fires at the release, so a button reacts without the double-tap delay.

A finger's position is known to a few millimetres (≈ 4.5 mm 1-σ for a light tap on the
paper's desk), so a tap aimed 2 mm inside a button's edge often lands just outside it: a
tap outside every bound region goes to the nearest one within its ``snap`` distance.

A two-finger tap is a short touch in which a second finger landed beside a still first one
(the estimator's second-finger stage, :mod:`hapticdesk.estimator.multitouch`, which a layout
binding it turns on): judged at the first finger's place, it fires at the release instead
of a tap or a double tap there. Two fingers landing at the same instant are one force to the
sensors and make a plain tap between them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from hapticdesk.estimator.contacts import ContactEvent
from hapticdesk.gestures.event import GestureEvent
from hapticdesk.gestures.layout import Binding, Layout
from hapticdesk.gestures.recognizer import BoundRegions, Recognizer
from hapticdesk.gestures.touch import Touch


@dataclass
class _PendingTap:
    """A tap waiting for a possible second one."""

    t_up: float
    x: float
    y: float
    surface: int
    force_n: float
    tap_region: str | None  # set when it also counts as a single tap there
    is_single: bool
    double_region: str | None
    double_options: dict[str, Any]


#: a touch that dragged along the surface harder than this (Touch.dragged) slid: no tap,
#: however little its located points moved (a flick on a desk whose points lag it)
MAX_TAP_DRAG = 0.35


def _is_tap(touch: Touch, options: dict[str, Any]) -> bool:
    """Short, still and not slid; still measured from the whole touch's mean (its middle),
    not from where it settled (a flick's end)."""
    centre = touch.best()
    return (
        touch.duration() <= options["max_duration_s"]
        and touch.moved(centre.x, centre.y) <= options["max_move"]
        and touch.dragged() <= MAX_TAP_DRAG
    )


class TapRecognizer(Recognizer):
    """``tap``, ``double_tap`` and ``two_finger_tap``."""

    gestures = ("tap", "double_tap", "two_finger_tap")
    needs_second_finger = frozenset({"two_finger_tap"})

    def __init__(self, layout: Layout, bindings: Sequence[Binding]) -> None:
        super().__init__(layout, bindings)
        self.taps = BoundRegions(layout, "tap")
        self.doubles = BoundRegions(layout, "double_tap")
        self.two_finger = BoundRegions(layout, "two_finger_tap")
        self._pending: _PendingTap | None = None
        self._second_down = False  # a touch began inside the double-tap window
        self._deadline: float | None = None
        self._earlier: list[GestureEvent] = []  # taps of earlier touches decided just now

    def next_deadline(self) -> float | None:
        return self._deadline

    def on_contact(self, event: ContactEvent, touch: Touch) -> list[GestureEvent]:
        if event.kind == "down":
            pending = self._pending
            if pending is not None:
                # the deadline fires before a later down, so this one is inside the window;
                # a second touch held too long means the first was a single tap after all
                self._second_down = True
                self._deadline = event.t + pending.double_options["max_duration_s"]
            return []
        if event.kind != "up":
            return []
        first, self._pending = self._pending, None
        if first is not None:
            self._second_down = False
            self._deadline = None
        if touch.claimed_by is not None:
            # a more specific gesture holds this touch (arbitration): it is no tap, so a tap
            # waiting for it was a single one
            self._earlier += self._single(first, event.t) if first is not None else []
            return []
        if touch.multi and self.two_finger:
            two = self._two_finger(touch, event.t)
            if two is not None:
                self._earlier += self._single(first, event.t) if first is not None else []
                return [two]
        if first is not None:
            double = self._double(first, touch, event.t)
            if double is not None:
                return [double]
            self._earlier += self._single(first, event.t)
        return self._judge(touch, event.t)

    def decided_earlier(self) -> list[GestureEvent]:
        out, self._earlier = self._earlier, []
        return out

    def on_deadline(self, t: float) -> list[GestureEvent]:
        self._deadline = None
        self._second_down = False
        first, self._pending = self._pending, None
        return self._single(first, t) if first is not None else []

    def _judge(self, touch: Touch, t: float) -> list[GestureEvent]:
        """A released touch on its own: a tap now, a tap waiting for its double, or nothing.
        A touch whose start a gap hid is nothing: its short rest is no tap."""
        if not touch.located or touch.began_unseen:
            return []
        x, y, _ = touch.settled()
        sigma = touch.place_sigma()  # (a tap whose uncertainty reaches two buttons: neither)
        tap_found, tap_region = self.taps.find(x, y, touch.surface, snap=True, sigma=sigma)
        is_single = tap_found and _is_tap(touch, self.taps.options(tap_region))
        double_found, double_region = self.doubles.find(x, y, touch.surface, True, sigma)
        if double_found:
            options = self.doubles.options(double_region)
            if _is_tap(touch, options):
                self._pending = _PendingTap(
                    t, x, y, touch.surface, touch.peak_force_n, tap_region, is_single,
                    double_region, options,
                )  # fmt: skip
                self._deadline = t + options["interval_s"]
                return []
        if is_single:
            return [GestureEvent(t, "tap", tap_region, x, y, force_n=touch.peak_force_n)]
        return []

    def _two_finger(self, touch: Touch, t: float) -> GestureEvent | None:
        """The two-finger tap ``touch`` makes, judged at its first finger, if it makes one."""
        if not touch.located:
            return None
        x, y, _ = touch.settled()
        sigma = touch.place_sigma()
        found, region = self.two_finger.find(x, y, touch.surface, snap=True, sigma=sigma)
        if not found or not _is_tap(touch, self.two_finger.options(region)):
            return None
        second = touch.second
        extra = {} if second is None else {"x2": round(second[0], 6), "y2": round(second[1], 6)}
        return GestureEvent(
            t, "two_finger_tap", region, x, y, force_n=touch.peak_force_n, extra=extra
        )

    def _double(self, first: _PendingTap, touch: Touch, t: float) -> GestureEvent | None:
        """The double tap made by ``first`` and the just released ``touch``, if they make one."""
        if not touch.located:
            return None
        x, y, _ = touch.settled()
        sigma = touch.place_sigma()
        found, region = self.doubles.find(x, y, touch.surface, snap=True, sigma=sigma)
        options = first.double_options
        if (
            not found
            or region != first.double_region
            or touch.surface != first.surface
            or math.hypot(x - first.x, y - first.y) > options["max_distance"]
            or not _is_tap(touch, options)
        ):
            return None
        force = max(first.force_n, touch.peak_force_n)
        return GestureEvent(t, "double_tap", region, first.x, first.y, force_n=force)

    @staticmethod
    def _single(first: _PendingTap, t: float) -> list[GestureEvent]:
        if not first.is_single:
            return []
        return [GestureEvent(t, "tap", first.tap_region, first.x, first.y, force_n=first.force_n)]
