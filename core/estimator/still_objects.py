"""The object rule: a load as still as the idle desk is an object put down, not a finger.

A load still within these multiples of the idle desk's own unsteadiness (its yardsticks,
:mod:`hapticdesk.estimator.yardsticks`) is an object, not a finger (fingers tremble and
wander), once held for ``object_settle_s``: the windows' spreads (of the low-passed force;
their median, none over OBJECT_SPIKE times the limit) within OBJECT_STILL_FACTOR of the idle
desk's, and the windows' means within OBJECT_WANDER_FACTOR of how far the idle desk's means
stray over as many windows in a row. The factors are about 1.2 times the idle desk's 90th
percentile over its median (1.3–1.6 for the spread, 1.4–2.0 for the wander on seven simulated
desks of 4–6 sensors, 8–40 kg, 4–9 Hz, 500–1200 Hz; scripts/objects_eval.py). Relative to
the yardsticks, over 0.6 s a still object's wander is 0.59 at the median, a finger held still
at 2.6–8 N's 6.7 (2.3 at the 10th percentile): the wander tells them apart best, as a
finger's 8–12 Hz tremor is mostly above the low-pass. Before, one yardstick for both, the
median spread of the tare's five windows, was noisy (a later idle window's median spread was
0.56–0.99 of it from desk to desk) and the wrong scale for the wander (a 500 Hz desk's idle
means stray about as far as its windows spread): 193 of 336 objects joined the zero within
1 s on those desks, now 306; fingers held still 3 s taken for one: 6 of 252, now 4.

An object absorbed into the zero is remembered (:class:`AbsorbedObject`) until it is lifted:
a still window back at the zero from before it (:func:`lifted`).
"""

from __future__ import annotations

import math
from typing import NamedTuple

from hapticdesk.estimator.yardsticks import Yardsticks, wander

OBJECT_STILL_FACTOR = 1.8
OBJECT_WANDER_FACTOR = 2.0
# ... or within this share of the load, whichever is more: a finger's force wanders by a few
# per cent of itself, so a heavy load that strays this little is no finger even on a desk
# whose own idle wander is larger (a tall desk swaying at 4.5 Hz: its 0.2 s means stray 0.05 N)
HEAVY_WANDER_SHARE = 0.004
# and a window's spread within this share of the load: a finger's 8–12 Hz tremor (1.5 % RMS)
# leaves about 1 % of its force in a window's spread after the 4.8 Hz low-pass
HEAVY_SPREAD_SHARE = 0.003
# one window of the run may spread up to this many times the limit (the desk's own noise now
# and then) while the run's median spread is within it
OBJECT_SPIKE = 1.3
# once a load rests (its means within the allowed wander), it rests on until they stray this
# many times the allowed wander (or a window is not still): on seven desks a 0.3 kg cup's
# means strayed up to 1.46 times it before the verdict (a long press fired on 5 of 42 cups),
# a finger's mostly far past it within a few windows
OBJECT_RESTING_KEEP = 1.6
# a load lighter than this (about half a kilogram) may be a finger resting lightly, which can
# be as still as a cup for 0.6 s: it waits one window more. On the seven desks (12 seeds):
# fingers held still at 2.6–4 N taken for an object 13 of 168 -> 4, objects of 0.15–0.3 kg
# within 1 s 158 of 168 -> 138 (touch_release_eval's light long presses on its unseen desk:
# 2 phantom releases -> 0)
LIGHT_LOAD_N = 5.0
# below this spread at the tare the readings are synthetic (no real sensor is that quiet):
# there is no yardstick for stillness, and objects wait for ``settle_s``
OBJECT_NOISE_FLOOR_N = 1e-4
# a lift restores the zero from before the object when the load is back within this share
# of the object's weight (or ``still_n``, whichever is larger) of that zero
LIFT_TOLERANCE = 0.2


class ObjectWindow(NamedTuple):
    """One window of a load held as still as the idle desk."""

    spread: float  # of its low-passed force
    force: tuple[float, float, float]  # its mean force less the zero


class AbsorbedObject(NamedTuple):
    """An object that became part of the zero, until it is lifted."""

    zero_before: list[float]  # (6) the zero it was added to
    weight_n: float  # its |F|


class ObjectVerdict(NamedTuple):
    """What one more window of a still load says."""

    run: int  # the object run's new length (0: the load is no object, for now)
    is_object: bool  # held long enough as still as an object: it is one


NO_OBJECT = ObjectVerdict(0, False)  # (the verdict on most windows: made once)


class ObjectRun:
    """The last windows of a load as still as the idle desk (the run's length is the
    kernel's ``J_OBJECT_RUN``), and whether the load rests (its means within the allowed
    wander so far)."""

    def __init__(self, n_object: int, drift_max_n: float) -> None:
        """``n_object``: the windows an object waits (0: no object rule); a load under
        ``drift_max_n`` is drift, never an object."""
        self.n_object = n_object
        self.drift_max_n = drift_max_n
        self.windows: list[ObjectWindow] = []
        self.resting = False

    def still(
        self,
        run: int,
        spread: float,
        force: tuple[float, float, float],
        load: float,
        idle: Yardsticks,
    ) -> ObjectVerdict:
        """One more window of a load (``run``: the object run so far; the window's
        ``spread``, its mean ``force`` less the zero and that force's size ``load``): is it
        held long enough as still as the idle desk to be an object? (A finger's tremor and
        slow wander move it more.) Judged on the last ``n_object`` windows (one more
        under LIGHT_LOAD_N): their means within the allowed wander of each other, their upper
        median spread within the limit, and none over OBJECT_SPIKE times it (one noisy window
        of the desk's own does not start the wait again). Also notes whether the load is
        resting: its windows so far as still as an object's."""
        n_object = self.n_object
        limit = max(OBJECT_STILL_FACTOR * idle.quiet_spread, HEAVY_SPREAD_SHARE * load)
        if (
            not n_object
            or load < self.drift_max_n  # (drift, also when drift is not followed)
            or idle.quiet_spread < OBJECT_NOISE_FLOOR_N
            or spread >= OBJECT_SPIKE * limit
        ):
            return NO_OBJECT
        if run == 0:
            self.windows = []
        run += 1
        wait = n_object + 1 if load < LIGHT_LOAD_N else n_object
        self.windows.append(ObjectWindow(spread, force))
        del self.windows[:-wait]
        strayed = wander([w.force for w in self.windows])
        allowed = max(OBJECT_WANDER_FACTOR * idle.quiet_wander, HEAVY_WANDER_SHARE * load)
        # the resting flag, once up in this run, drops only past OBJECT_RESTING_KEEP times the
        # allowed wander: a cup's means can stray just over it for a window or two while its
        # landing rings out, and a hold would fire on that one window
        keep = OBJECT_RESTING_KEEP if self.resting and run > 1 else 1.0
        self.resting = strayed < keep * allowed
        spreads = sorted(w.spread for w in self.windows)
        # (a load that strays is no object, for now)
        is_object = strayed < allowed and run >= wait and spreads[len(spreads) // 2] < limit
        return ObjectVerdict(run, is_object)


def lifted(absorbed: AbsorbedObject, mean: list[float], still_n: float) -> bool:
    """A still window whose mean force (``mean``, its first 3) is back at the zero from
    before ``absorbed``: the object was lifted."""
    before = absorbed.zero_before
    off = math.sqrt(sum((mean[i] - before[i]) ** 2 for i in range(3)))
    return off < max(still_n, LIFT_TOLERANCE * absorbed.weight_n)
