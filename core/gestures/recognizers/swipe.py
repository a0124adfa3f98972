"""Swipes: a quick, nearly straight stroke, decided at the release, in 4 or 8 directions.

Directions are as seen from above by the person at the desk: ``right`` is +x, ``up`` is
away from them (+y), ``down`` towards them. The ends are judged by the precision-weighted
line fit over the first and last few samples, where the estimator's differentiated-force
candidate places touching and releasing well (paper §3).

A swipe lifts off while the finger still moves, and the estimator's low-passed position lags
a moving finger by the low-pass's delay (``touch.delay_s``, 47 ms on the paper's desk: 3 cm
at 0.6 m/s). The end is therefore the line fitted over the last ``END_FIT_S``, carried on by
that delay (on simulated swipes: 97 of 100 recognised instead of 92, lengths 0.93 of the
true median instead of 0.77). A flick (12 cm at 0.7–1 m/s) is on the desk for about 0.2 s,
half of it the still touch-down, so that line took its slope from the still part and fell
short; the line over the last FLICK_FIT_S is used where it reaches farther the same way
(scripts/swipe_accuracy.py, paper desk: flicks 15 -> 74 of 84, 0.4–0.7 m/s 67 -> 83).

On a desk whose sway the estimator cannot follow (examples/desks/eight-legs.yaml, 4.2 Hz),
a quick swipe's points can run against the finger: a swipe the other way. Friction pulls
the board the way the finger slides (``Touch.drag``; on simulated swipes on four kinds of
desk, within 12 degrees of the finger's way), so a swipe whose points name another
direction than that drag is not fired: a miss, not a wrong command. And where the points
cannot follow the finger at all (flicks on that desk: 12 of 84 found by the points), a
quick touch that dragged the board hard (SLIDE_DRAG) and one way (SLIDE_STRAIGHTNESS) slid:
it is a swipe the way it dragged (its ``distance`` 0 where the points did not make the same
swipe). Taps drag 0.06-0.16 (up to 0.43 on a desk whose rocking the legs feel while a light
tap lasts), simulated swipes 0.495-0.9, a circle drawn quickly every way.
So where the drag is measured, a touch that dragged the board less than DIRECTION_DRAG was
pressed, not slid, and makes no swipe by its points: on a swaying desk a light tap's points
ran 37 mm in 40 ms, and its drag, a tenth of a swipe's, happened to point their way.

Carried on, a short touch's noise can look like motion: the line over a light, quick tap's
few samples slopes with the touch-down's scatter, and 47 ms (90 ms on a 3 Hz desk) of that
slope made a 5–9 cm "swipe" of 26 in 600 taps on the paper's desk. So the track itself, as
measured, must have moved at least MEASURED_SHARE of ``min_distance`` beyond its own
uncertainty (:meth:`Touch.moved`): on six simulated desks a tap's track moved at most 0.9 cm
(paper desk 0.2 cm), a swipe's at least 2.3 cm. Measured from the start alone, a still tap
whose first points strayed 2 cm and more (light taps on sensors quieter than their rounding
step) looked moved: the track must also have gone STILL_SHARE of ``min_distance`` from the
touch's best point, about the middle of a real swipe (120 random simulated desks,
scripts/desk_sweep.py: swipes fired on taps 31 -> 13, real swipes right 697 of 840 both).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from hapticdesk.estimator.contacts import ContactEvent
from hapticdesk.gestures.event import GestureEvent
from hapticdesk.gestures.layout import Binding, Layout
from hapticdesk.gestures.options import DIRECTIONS_4, DIRECTIONS_8
from hapticdesk.gestures.recognizer import BoundRegions, Recognizer
from hapticdesk.gestures.touch import Touch

#: the start of a swipe is averaged over this long
END_WINDOW_S = 0.04
#: the end's line is fitted over this long (longer: its slope is carried on, see above)
END_FIT_S = 0.2
#: ... or over this long, where that reaches farther the same way (a flick: see _end)
FLICK_FIT_S = 0.06
#: "the same way": the two ends' directions from the start within this cosine (45 degrees)
FLICK_AGREE_COS = math.cos(math.pi / 4)
#: a touch that dragged the board this hard (Touch.dragged) slid the way it dragged it: a
#: swipe whose points name another direction is the desk's sway, not the finger (see above);
#: one that dragged it less, where the drag is measured at all (Touch.dragged above 0), was
#: pressed, not slid: its points' swipe is none. Simulated swipes on 120 random desks
#: (scripts/desk_sweep.py's, 98 fired) dragged 0.61-0.9, with up to four legs reporting the
#: load alone; the swipes fired on taps 0.02-0.19 (desk 92 of that sweep 0.016: its light
#: tap's points, on an 8-legged 3.6 Hz desk, ran 37 mm "up" in 40 ms)
DIRECTION_DRAG = 0.2
#: a quick touch that dragged the board this hard (Touch.dragged) slid: a swipe the way it
#: dragged, where the points could not follow it. Midway between the hardest drag of a tap and
#: the lightest of a swipe seen: scripts/desk_sweep.py, 80 taps on 120 random desks, seeds 1-4:
#: taps up to 0.43, on desks swaying at 5-6 Hz whose rocking the legs feel as shear while a
#: light tap lasts 50-80 ms; swipes from 0.56; scripts/swipe_accuracy.py, those the drag alone
#: found: 0.495 on the three-legged desk, 0.59-0.60 on the eight-legged and the paper's. At
#: 0.35 two such taps were swipes nobody made (seed 1, desks 2 and 85)
SLIDE_DRAG = 0.46
#: ... and kept its drag this straight (Touch.drag_straightness: a circle drawn quickly
#: drags every way, a swipe one)
SLIDE_STRAIGHTNESS = 0.8
#: ... and lasted this long: the lift-off of a flick seen as a touch of its own for a few
#: samples (2 ms) drags the board back the other way (flicks on the tests' three-legged desk)
SLIDE_MIN_S = 0.05
#: a swipe by the points must have dragged the board its way, within this cosine (60 degrees):
#: friction pulls the board the way a finger slides, whatever the finger's pressure or the
#: surface (simulated swipes: within 12 degrees); the points of a tap whose noise made a 5 cm
#: "swipe" went against its drag in 10 of 13 such cases (scripts/desk_sweep.py)
POINTS_DRAG_COS = 0.5
#: no finger swipes faster, m/s (the points' length over the touch's time; quick human flicks
#: 1-2 m/s): a real stroke broken into a 9 ms fragment as the finger lifted "swiped" 20 cm
#: (8 of 240 real $1 strokes on the three-legged desk, scripts/dollar_swipes.py)
MAX_SPEED_M_S = 3.0
#: the measured track (without the carry-on) must have moved this share of ``min_distance``
MEASURED_SHARE = 0.4
#: ... and this share away from the touch's best point (about its middle on a swipe)
STILL_SHARE = 0.2


def _end(touch: Touch, start: tuple[float, float]) -> tuple[float, float] | None:
    """Where the swipe ended: the line fitted over the last END_FIT_S carried on by the
    delay, or over the last FLICK_FIT_S where that goes farther the same way (a flick)."""
    t = touch.times()
    end = touch.position_at(t[-1] + touch.delay_s, t[-1] - END_FIT_S, t[-1])
    quick = touch.position_at(t[-1] + touch.delay_s, t[-1] - FLICK_FIT_S, t[-1])
    if end is None or quick is None:
        return end
    a = np.subtract(end, start)
    b = np.subtract(quick, start)
    longer = float(np.hypot(*b)) > float(np.hypot(*a))
    if longer and float(a @ b) >= FLICK_AGREE_COS * float(np.hypot(*a) * np.hypot(*b)):
        return quick
    return end


def direction_name(dx: float, dy: float, directions: int) -> str:
    """The nearest of 4 or 8 compass directions of the vector (dx, dy)."""
    names = DIRECTIONS_8 if directions == 8 else DIRECTIONS_4
    sector = 2 * math.pi / len(names)
    return names[round(math.atan2(dy, dx) / sector) % len(names)]


class SwipeRecognizer(Recognizer):
    """``swipe``."""

    gestures = ("swipe",)

    def __init__(self, layout: Layout, bindings: Sequence[Binding]) -> None:
        super().__init__(layout, bindings)
        self.bound = BoundRegions(layout, "swipe")
        self.sliders = BoundRegions(layout, "slide")

    def on_contact(self, event: ContactEvent, touch: Touch) -> list[GestureEvent]:
        if event.kind != "up" or touch.samples < 2:
            return []
        t = touch.times()
        start = touch.position_at(t[0], t[0], t[0] + END_WINDOW_S)
        assert start is not None
        found, region = self.bound.find(start[0], start[1], touch.surface)
        if not found or (region is None and self.sliders.find(*start, touch.surface)[0]):
            return []  # a drag that starts on a slider is the slider's, not a swipe anywhere
        o = self.bound.options(region)
        if touch.duration() > o["max_duration_s"]:
            return []
        by_points = self._by_points(touch, start, o)
        gx, gy = touch.drag()
        dragged = touch.dragged()
        slid = (
            dragged >= SLIDE_DRAG
            and touch.drag_straightness() >= SLIDE_STRAIGHTNESS
            and touch.duration() >= SLIDE_MIN_S
        )
        if slid:  # the way it dragged, wherever the points went (see above)
            direction = direction_name(gx, gy, o["directions"])
            distance = 0.0
            if by_points is not None and by_points[0] == direction:
                distance = by_points[1]
        elif by_points is None:
            return []
        else:
            direction, distance, (dx, dy) = by_points
            if 0.0 < dragged < DIRECTION_DRAG:
                return []  # the board felt the finger press, not drag: a still touch's points
            if dragged >= DIRECTION_DRAG and direction_name(gx, gy, o["directions"]) != direction:
                return []  # the points went another way than the finger dragged: the sway
            if gx * dx + gy * dy < POINTS_DRAG_COS * math.hypot(gx, gy) * math.hypot(dx, dy):
                return []  # nothing dragged the board the points' way: a still touch's noise
        return [
            GestureEvent(
                event.t, "swipe", region, start[0], start[1],
                direction=direction,
                extra={"distance": round(distance, 6)},
            )
        ]  # fmt: skip

    def _by_points(
        self, touch: Touch, start: tuple[float, float], o: dict
    ) -> tuple[str, float, tuple[float, float]] | None:
        """The swipe the located points make (direction, length, (dx, dy)), or None."""
        end = _end(touch, start)
        assert end is not None
        dx, dy = end[0] - start[0], end[1] - start[1]
        distance = math.hypot(dx, dy)
        if distance < o["min_distance"]:
            return None
        if distance > MAX_SPEED_M_S * touch.duration():
            return None  # faster than a finger: a fragment of a touch, its points jumping
        if touch.moved(*start) < MEASURED_SHARE * o["min_distance"]:
            return None  # the carry-on alone made it: a still touch's noise (see above)
        best = touch.best()
        if touch.moved(best.x, best.y) < STILL_SHARE * o["min_distance"]:
            return None  # a still touch whose first points strayed (see above)
        # how far the path bows away from the straight line between the ends
        track = touch.track() - np.asarray(start)
        deviation = float(np.max(np.abs(track[:, 0] * dy - track[:, 1] * dx))) / distance
        if deviation > o["max_deviation"] * distance:
            return None
        return direction_name(dx, dy, o["directions"]), distance, (dx, dy)
