"""The recognizer interface every gesture state machine implements, built-in or plugin.

A recognizer is created once per layout for the gestures it handles, with the bindings of
those gestures. The engine gives it every contact event with the current :class:`Touch`, in
sample-time order, and asks it for timers: ``next_deadline()`` is the sample time at which it
wants ``on_deadline(t)`` to be called, with ``t`` the first sample time at or after the
deadline. Each event it returns carries ``t`` = the sample time at which it was decided.
A desk senses one resultant force, so there is at most one touch at a time (a second finger
landing on it is flagged on that touch, :attr:`Touch.multi`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, ClassVar

from hapticdesk.estimator.contacts import ContactEvent
from hapticdesk.gestures.event import GestureEvent
from hapticdesk.gestures.layout import Binding, Layout
from hapticdesk.gestures.options import OptionSpec
from hapticdesk.gestures.touch import Touch

#: how far outside its region a finger must be before a `leave: cancel` gesture ends: about
#: twice a touch's position noise (≈ 4.5 mm 1-σ for a light touch on the paper's desk), so
#: a finger on the region's edge does not cancel it
LEAVE_MARGIN_M = 0.01
#: a point is placed in a region only when it is this many times likelier there than in any
#: other bound region (BoundRegions.find with a ``sigma``). On the 120-desk sweep
#: (scripts/desk_sweep.py --seed 1; 35,646 taps, 39 in a wrong button, 31,877 right), odds of
#: 10 / 30 / 100 / 300 left 35 / 27 / 20 / 12 in a wrong button and 31,852 / 31,759 / 31,576 /
#: 31,361 right: 30 is the most that keeps the right taps within 0.5 % (chosen on that sweep).
#: The wrong ones were placed 2.6-6.7 times their claimed σ off: past what any odds on that σ
#: can tell from a right tap snapped across a gap (the estimator's σ, README)
ODDS = 30.0
LOG_ODDS = math.log(ODDS)


class Recognizer:
    """Base class: override what the gesture needs."""

    #: gesture names this class recognises (one instance serves all of them)
    gestures: ClassVar[tuple[str, ...]] = ()
    #: plugin recognizers may describe their options so layouts are validated
    option_specs: ClassVar[dict[str, OptionSpec] | None] = None
    #: those of its gestures that read a second finger (``touch.multi``): a layout binding
    #: one turns on the estimator's second-finger stage (GestureEngine.needs_second_finger)
    needs_second_finger: ClassVar[frozenset[str]] = frozenset()

    def __init__(self, layout: Layout, bindings: Sequence[Binding]) -> None:
        self.layout = layout
        self.bindings = list(bindings)

    def on_contact(self, event: ContactEvent, touch: Touch) -> list[GestureEvent]:
        """One contact event (down, move, up) of ``touch``, already added to it. Its events
        belong to ``touch``; ``touch.claimed_by`` names the gesture that holds it when a more
        specific one claimed it (arbitration): a gesture of ``arbitration.ORDER`` that is
        not that one is dropped by the engine, and need not be decided."""
        return []

    def decided_earlier(self) -> list[GestureEvent]:
        """Events the last :meth:`on_contact` decided for an earlier touch (a tap that waited
        for a double tap and turned out single), taken once. The engine reads them apart
        from that call's events, which belong to the current touch: a gesture that claimed
        the current touch drops the others' events of it (arbitration), not these."""
        return []

    def next_deadline(self) -> float | None:
        """Sample time at which :meth:`on_deadline` is wanted, or None."""
        return None

    def on_deadline(self, t: float) -> list[GestureEvent]:
        """Called at the first sample time ``t`` >= the deadline; must clear or move it."""
        return []

    def cancel(self, t: float, touch: Touch) -> list[GestureEvent]:
        """``touch`` broke off at ``t`` without a release (a gap, a stop, the end of the
        recording): forget it. Continuous gestures return their ``cancel`` phase; nothing
        that fires on a release may fire here."""
        return []

    def flush(self, t: float) -> list[GestureEvent]:
        """The source ended at ``t``: decide whatever is pending now."""
        return self.on_deadline(t) if self.next_deadline() is not None else []


class BoundRegions:
    """The regions a gesture is bound in, to place a point, and their settings."""

    def __init__(self, layout: Layout, gesture: str) -> None:
        self.layout = layout
        self.gesture = gesture
        names = [b.region for b in layout.bindings if b.gesture == gesture]
        self.regions = [layout.regions[n] for n in dict.fromkeys(n for n in names if n is not None)]
        self.anywhere = any(n is None for n in names)

    def __bool__(self) -> bool:
        return bool(self.regions) or self.anywhere

    def find(
        self, x: float, y: float, surface: int, snap: bool = False, sigma: float = 0.0
    ) -> tuple[bool, str | None]:
        """(found, region name): the bound region holding the point, else (with ``snap``) the
        nearest one when the point is within that region's ``snap`` option of it, else
        (True, None) when the gesture is bound anywhere, else (False, None).

        ``sigma``: how well the point is placed (1-σ, metres). A region is only found when
        the point is at least ``ODDS`` times likelier in it than in any other bound region
        that does not hold it, each likelihood that of the point's nearest place in the
        region under a normal error of ``sigma``: where the uncertainty reaches two regions
        alike, neither is taken (a miss, not the wrong button)."""
        on_surface = [r for r in self.regions if r.surface_index == surface]
        distances = [(r.distance(x, y), r.name) for r in on_surface]
        found: tuple[float, str] | None = next(
            ((0.0, r.name) for r in on_surface if bool(r.contains(x, y))), None
        )
        if found is None and snap and distances:
            distance, nearest = min(distances)
            if distance <= self.options(nearest).get("snap", 0.0):
                found = (distance, nearest)
        if found is None:
            return self.anywhere, None
        if sigma > 0.0:
            others = [d for d, name in distances if name != found[1] and d > 0.0]
            # log of the odds of the region found against the nearest other one
            if others and (min(others) ** 2 - found[0] ** 2) / (2 * sigma**2) < LOG_ODDS:
                return self.anywhere, None
        return True, found[1]

    def left(self, region: str | None, x: float, y: float) -> bool:
        """Whether a finger at (x, y) has left ``region`` where the gesture's ``leave`` option
        says ``cancel``: farther outside it than :data:`LEAVE_MARGIN_M`."""
        if region is None or self.options(region).get("leave") != "cancel":
            return False
        return self.layout.regions[region].distance(x, y) > LEAVE_MARGIN_M

    def options(self, region: str | None) -> dict[str, Any]:
        """Resolved recognizer settings of the gesture in ``region``."""
        return self.layout.options_for(self.gesture, region)
