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
a still window back at the zero from before it. The kernel applies the rule and sees the lift
(:mod:`hapticdesk.estimator.kernel_objects`, these constants passed in its parameters), so a
window's end never leaves the compiled loop; Python keeps the objects absorbed and words the
notices (:mod:`hapticdesk.estimator.zero`).
"""

from __future__ import annotations

from typing import NamedTuple

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
# and then) while the run's median spread is within it. A window spread further ends the run
# and the resting, but for one window a run of a load under LIGHT_LOAD_N that rests, whose mean
# keeps it resting (within OBJECT_RESTING_KEEP of the run's): a light desk still ringing from
# a cup's landing, its mean where the cup rests (the flag dropped for that window and a due
# long press fired: on the random desks of scripts/desk_sweep.py 3 of the 5 long presses nobody
# made in 48,000 taps, 2 in 336 objects of scripts/objects_eval.py; a finger's window that
# spreads so moves its mean with it, 2.7 times the allowed wander at the median). Not for
# heavier loads: firm presses held that way fired 0.2 s later, cups of 0.7 kg and more never
# fired
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
# on a desk whose idle windows spread NOISY_STILL_SHARE of ``still_n`` or more at the median
# (its noise sets the still limit there, kernel_yardsticks.still_limit) and where the
# wander allowed is NOISY_WANDER_SHARE of the load or more, a finger's wander (a few per cent
# of its force) hides in it: on the load-cell desks of scripts/objects_eval.py --desks
# loadcells, 8 and 15 N fingers held on a button were taken for an object after 0.6 s, 3 of
# 336 (the allowance 1.3-2.5 % of their force). There the verdict waits this many windows
# more: a finger's means stray on with time, noise's do not (on the noisiest six of those
# desks, over 3 windows the fingers' strayed 1.1 times the idle desk's wander at the 5th
# percentile, over 5 windows 4.6), while the resting is judged on the last I_N_OBJECT windows
# as before (without the load's share, judged on all 16 objects fired a long press in 288,
# on the last ones 11).
# Leave-one-out over the 14 desks on that long-press test: 2 windows and 1 %, no finger lost
# and 9 objects; 1 window, 2 lost; 3 windows, 11 objects; 0.5 %, 10 objects; 2 %, 2 lost.
# The spread's share, on the objects test of --desks loadcells too (4 seeds: 224 objects, 168
# fingers held still 3 s): 0.4 (wherever the noise sets the limit) 3 fingers taken for an
# object, 123 objects within 1 s, but the two shipped desks' 0.15-0.3 kg ones waited past 1 s
# (28 -> 20 of 32 within 1 s, the presses after them within 2 mm 26 -> 18); 0.5 and 0.67: 4
# fingers, 135 and 141 objects, the shipped desks as before; 1.0: 17 fingers (main: 6, 114).
# A leave-one-out on fingers taken and long presses alone picks 0.4 (one finger fewer, on a
# desk that took it on main too): 0.67 was chosen for the shipped desks' objects
NOISY_EXTRA_WINDOWS = 2
NOISY_WANDER_SHARE = 0.01
NOISY_STILL_SHARE = 0.67
# below this spread at the tare the idle readings sat still: a sensor quieter than its
# resolution step (or synthetic readings). Its yardsticks are then these shares of the force
# one step of its coarsest channel makes, once a load's readings have taught the steps (the
# paper's desk, whose readings flicker by a step at noise 0.4 N, steps 0.075-0.15 N, has a
# quiet spread of 0.19 and a wander of 0.09 of that force; taken a little quieter). Without
# them, on the paper's desk at noise 0.1-0.25 N, a 0.3-1.5 kg cup on a long-press button
# fired it 12 of 16 times (no yardstick: objects waited for ``settle_s``); with them 1 of 16,
# fingers held still 3 s taken for an object 5 of 72 (3 of 72 at noise 0.4 N; 7 of 72 with
# shares 0.2 and 0.1). Without steps learned, or where a channel changed by no whole number of
# its step (unquantised synthetic readings: a perfectly static press was taken for an object,
# tests/sim/test_sim_simulate.py), there is no yardstick, as before
OBJECT_NOISE_FLOOR_N = 1e-4
STEP_SPREAD_SHARE = 0.15
STEP_WANDER_SHARE = 0.075
# a lift restores the zero from before the object when the load is back within this share
# of the object's weight (or ``still_n``, whichever is larger) of that zero
LIFT_TOLERANCE = 0.2


class AbsorbedObject(NamedTuple):
    """An object that became part of the zero, until it is lifted."""

    zero_before: list[float]  # (6) the zero it was added to
    weight_n: float  # its |F|
