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


def wander(means: Sequence[Sequence[float]]) -> float:
    """How far window means strayed: the widest range of any component over ``means`` (one
    measure for the tare's windows, an object's and the idle desk's yardstick, so they
    compare; the kernel's is :func:`hapticdesk.estimator.kernel_yardsticks.ring_wander`)."""
    return max(max(c) - min(c) for c in zip(*means, strict=True))
