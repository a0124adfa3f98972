"""The idle desk's own unsteadiness: the yardsticks an object put down is judged against.

How much a still, unloaded desk's windows spread, and how far their force means stray over
as many windows in a row as an object waits (``n_object``): each the median
(``IDLE_QUANTILE``) of the idle desk's own, over the tare's windows and then every idle still
window (the last ``IDLE_WINDOWS``). A median of a few windows is steady, a high quantile of
them is not. The kernel keeps them (:mod:`hapticdesk.estimator.kernel_yardsticks`: a window's
end never leaves the compiled loop), and its object rule
(:mod:`hapticdesk.estimator.kernel_objects`, :mod:`hapticdesk.estimator.still_objects`)
compares a load's windows with them.
"""

from __future__ import annotations

from collections.abc import Sequence

IDLE_QUANTILE = 0.5
IDLE_WINDOWS = 64
# a window is still when its spread is under ``still_n`` or, on a desk whose idle windows
# spread more, under this many times their median (the quiet spread, from the tare on). On
# load-cell desks read by HX711s at 50-80 Hz (scripts/objects_eval.py --desks loadcells) the
# idle windows spread 0.03-0.2 N at the median (0.2 N: eight 100 kg cells at 50 Hz) and up to
# 80 % of them past ``still_n`` (0.15 N): no window with a cup on it was still, it never
# rested, and 0.5-1.5 kg objects on a button fired its 0.8 s long press 61 times in 288 (14
# desks, 6 seeds); with 2.5 or more 9 (2: 10). Chosen by leave-one-out over those desks with
# still_objects.NOISY_EXTRA_WINDOWS (2.5 and 3 tie; over the object rule's own spike limit,
# 1.8 x 1.3). The paper's desk and the six unlike it spread 0.028-0.047 N at the median:
# 2.5 times that is under ``still_n``, nothing changes there
STILL_NOISE_FACTOR = 2.5


def wander(means: Sequence[Sequence[float]]) -> float:
    """How far window means strayed: the widest range of any component over ``means`` (one
    measure for the tare's windows, an object's and the idle desk's yardstick, so they
    compare; the kernel's is :func:`hapticdesk.estimator.kernel_yardsticks.ring_wander`)."""
    return max(max(c) - min(c) for c in zip(*means, strict=True))
