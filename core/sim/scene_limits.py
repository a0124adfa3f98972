"""The bounds a scene's numbers must keep: times, repeats, forces, speeds, masses and units.

What a run may hold in memory is bounded by samples, in the timeline (one touch's track) and
in `simulate` (the whole recording); these bounds refuse a typing mistake where it is written.
"""

from __future__ import annotations

MIN_QUIET_S = 1.5  # the estimator tares over the first second; leave it a margin
#: the longest time a scene may give (quiet_s, tail_s, duration_s, start_s, wait_s, hold_s,
#: an action's duration_s …): a day.
MAX_SCENE_S = 86_400.0
#: the most times an action may repeat, and the most actions a timeline may expand to
MAX_REPEAT = 10_000
MAX_ACTIONS = 100_000
#: the hardest a scene's finger presses (N: a person leaning their whole weight on it) and
#: the fastest its force may change (N/s): beyond, a typing mistake (a tap of 1e300 N
#: saturated every simulated sensor and no contact was seen)
MAX_FORCE_N = 1_000.0
MAX_FORCE_RATE_N_S = 100_000.0
#: a finger's speed, m/s: slower is a hold, faster no hand moves (a speed of 1e-300 was
#: refused as a swipe of 10^300 samples, written out digit by digit)
MIN_SPEED_M_S, MAX_SPEED_M_S = 0.001, 10.0
#: the heaviest object a scene puts on the desk, kg (its weight at most MAX_FORCE_N: a mass
#: of 1e300 kg saturated every sensor)
MAX_OBJECT_KG = 100.0
#: a scene's `units:` and their length in metres
UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001}
