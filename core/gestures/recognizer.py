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
#: other bound region (BoundRegions.find with a ``sigma``, read as the radial 1-σ the
#: estimator gives: σ/√2 along the line to the other region). Chosen leaving one desk out on
#: the 120-desk sweep's taps (scripts/tap_guard_loo.py --seed 1; every tap's place, σ and
#: distances dumped once, the guard recounted): for each desk the rule (this, INSIDE_SHARE and
#: the share of a tap's samples its place leaves out, touch.SETTLED_SHARE) that keeps the
#: most right taps the other 119 desks allow with at most 5·119/120 wrong, counted on the
#: held-out desk: 4.81 with the share 1/3 and taps placed after 0.7 of their samples in 113
#: of 120 folds (held out 31,664 right, 6 wrong; with the place's share fixed at 0.7, 31,661
#: and 5; placed by the whole touch, 31,507 and 5 at 5.53; on all 120 desks 31,667 and 4,
#: the sweep's). The odds read as a line's σ before (30, i.e. 900 radially) kept 31,213
#: right and 2 wrong.
LOG_ODDS = 4.81
ODDS = math.exp(LOG_ODDS)  # ≈ 120
#: the share of LOG_ODDS a point inside the region it is placed in needs (odds ≈ 5): a point
#: outside every region, brought in by ``snap``, is itself proof that the place is off by its
#: distance to the region. On that sweep all 40 taps a guard-less engine put in a wrong button
#: were such points; held out (taps placed by the whole touch), 1 (the guard as one odds) /
#: 2/3 / 1/2 / 1/3 kept 31,455 / 31,513 / 31,520 / 31,527 right with 5 wrong, and 1/3 is
#: chosen with the other two (a smaller share kept no more right taps). It is not 0: on
#: seed 3 two taps landed inside the wrong button, 34 mm from its neighbour's edge.
INSIDE_SHARE = 1 / 3


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

        ``sigma``: how well the point is placed (radial 1-σ, metres). A region is only found
        when the point is at least ``ODDS`` times likelier in it than in any other bound
        region that does not hold it (``ODDS ** INSIDE_SHARE`` for a point inside it), each
        likelihood that of the point's nearest place in the region under a normal error of
        ``sigma``: where the uncertainty reaches two regions alike, neither is taken (a miss,
        not the wrong button)."""
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
            # log of the odds of the region found against the nearest other one, along the
            # line between them (σ²/2 of the radial σ²)
            needed = LOG_ODDS if found[0] > 0.0 else INSIDE_SHARE * LOG_ODDS
            if others and (min(others) ** 2 - found[0] ** 2) / sigma**2 < needed:
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
