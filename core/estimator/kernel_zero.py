"""The zero's windows, compiled: each sample into the window, the window judged at its end.

The kernel's side of :mod:`hapticdesk.estimator.zero`: :func:`window_add` fills the window
with the sample in flight (its low-passed force, its wrench, whether it is bad) and, at the
window's end, measures it (the spread of the low-passed force, the mean wrench). Before the
tare it raises ``EV_WINDOW`` for Python (:mod:`.tare`); once tared, a window that is not
still only ends the still run and the resting, and a still one is judged here whole
(:func:`still_window`: the still run, the idle desk's yardsticks (:mod:`.kernel_yardsticks`),
the drift followed, the object rule and an object's lift (:mod:`.kernel_objects`)), so no
window's end leaves the compiled loop after the tare: in Python that judgment cost 60–120 µs
of CPU (its code and data cold five times a second), over issue 29's 100 µs a push. Only a
zero changed for an object (``EV_ABSORBED``, ``EV_LIFTED``) goes to Python, to be told. Its
sums are numpy's and math.fsum's (:mod:`.kernel_sums`), so the kernel's zero equals the one
Python took before. Readings that come zeroed (a force plate's)
have no window: :func:`zero_from_start` sets their zero to 0 at the first good sample.
"""

from __future__ import annotations

import math

import numpy as np

from hapticdesk.estimator.contacts import BAD_SAMPLE, FLAG_GAP
from hapticdesk.estimator.kernel_channels import steps_changed
from hapticdesk.estimator.kernel_compile import inlined
from hapticdesk.estimator.kernel_objects import lifted, object_still
from hapticdesk.estimator.kernel_slots import (
    EV_ABSORBED,
    EV_LIFTED,
    EV_WINDOW,
    I_JO_WIN_BAD,
    I_N_DRIFT,
    I_N_SETTLE,
    I_SO_STILL_MEANS,
    I_SO_WIN_LP,
    I_SO_WIN_RAW,
    I_STILL_BLOCK,
    I_STILL_RING,
    I_WINDOW,
    J_DIRTY,
    J_OBJ_HELD,
    J_OBJ_RESTING,
    J_OBJ_WINDOWS_N,
    J_OBJECT_RUN,
    J_OBJECTS,
    J_RESTING,
    J_RESTING_NEXT,
    J_RESTING_OFF,
    J_STILL_COUNT,
    J_STILL_POS,
    J_STILL_RUN,
    J_TARED,
    J_WIN_BADS,
    J_WIN_FILL,
    J_WINDOW_INDEX,
    J_WINDOWS_SEEN,
    J_ZERO_NEXT,
    J_ZERO_VERSION,
    P_DRIFT_MAX,
    P_STILL_N,
    S_LP,
    S_OBJ_F,
    S_OBJ_WEIGHT,
    S_OBJ_ZERO,
    S_RAW,
    S_STILL_HI,
    S_STILL_LO,
    S_WIN_MEAN,
    S_WIN_SPREAD,
    S_WIN_T_END,
    S_ZERO,
    S_ZERO_NEXT,
    S_ZERO_T,
    S_ZERO_T_NEXT,
)
from hapticdesk.estimator.kernel_sums import exact_mean, pairwise_sum
from hapticdesk.estimator.kernel_yardsticks import (
    idle_window_joins,
    still_limit,
    yardsticks_update,
)


@inlined
def window_add(
    t: float,
    flags: int,
    first_good: bool,
    pf: np.ndarray,
    pi: np.ndarray,
    sf: np.ndarray,
    si: np.ndarray,
) -> int:
    """The sample in flight into the zero's window (its low-passed force, its wrench, whether
    it is bad); at the window's end its spread, mean and last time go to S_WIN_*: before the
    tare EV_WINDOW is returned, after it a still window is judged (:func:`still_window`:
    its events returned). Before the first good sample there is no wrench (the filters have
    not started: zeros); that sample stands in for those before it in its window, as if the
    input had started with it."""
    _decided_before(sf, si)
    w = pi[I_WINDOW]
    win_lp = sf[pi[I_SO_WIN_LP] : pi[I_SO_WIN_LP] + 3 * w]
    win_raw = sf[pi[I_SO_WIN_RAW] : pi[I_SO_WIN_RAW] + 6 * w]
    win_bad = si[pi[I_JO_WIN_BAD] : pi[I_JO_WIN_BAD] + w]
    m = si[J_WIN_FILL]
    # (a sample's lanes side by side, [3j + lane] and [6j + lane]: each sample writes two
    # short runs, where lanes one after the other ([lane·w + j]) wrote nine cache lines)
    for j in range(m if first_good else 0):
        for lane in range(3):
            win_lp[3 * j + lane] = sf[S_LP + lane]
        for lane in range(6):
            win_raw[6 * j + lane] = sf[S_RAW + lane]
    for lane in range(3):
        win_lp[3 * m + lane] = sf[S_LP + lane]
    for lane in range(6):
        win_raw[6 * m + lane] = sf[S_RAW + lane]
    win_bad[m] = 1 if flags & (BAD_SAMPLE | FLAG_GAP) else 0
    m += 1
    if m < w:
        si[J_WIN_FILL] = m
        return 0
    si[J_WIN_FILL] = 0
    bads = 0
    for j in range(w):
        bads += win_bad[j]
    si[J_WIN_BADS] = bads
    spread = _window_spread(pi, sf, w)
    si[J_WINDOW_INDEX] += 1
    if si[J_TARED] and (bads / w > 0.1 or spread >= still_limit(pf, sf)):
        # once tared, a window that is not still (or mostly held over) only ends a still run
        # and the resting, from the next sample on
        si[J_STILL_RUN] = si[J_OBJECT_RUN] = 0
        si[J_RESTING_OFF] = 1
        return 0
    sf[S_WIN_SPREAD] = spread
    for lane in range(6):
        sf[S_WIN_MEAN + lane] = pairwise_sum(sf, pi[I_SO_WIN_RAW] + lane, w, 6) / w
    sf[S_WIN_T_END] = t
    if si[J_TARED]:
        return still_window(spread, t, pf, pi, sf, si)
    return EV_WINDOW  # (before the tare: Python's, tare.py)


@inlined
def _decided_before(sf: np.ndarray, si: np.ndarray) -> None:
    """What the last window's end decided for the samples after it, from this one on: the
    load resting (J_RESTING_NEXT), a new zero (J_ZERO_NEXT)."""
    if si[J_RESTING_NEXT]:
        si[J_RESTING] = 1
        si[J_RESTING_NEXT] = 0
    if si[J_ZERO_NEXT]:
        for lane in range(6):
            sf[S_ZERO + lane] = sf[S_ZERO_NEXT + lane]
        sf[S_ZERO_T] = sf[S_ZERO_T_NEXT]
        si[J_ZERO_NEXT] = 0


@inlined
def _window_spread(pi: np.ndarray, sf: np.ndarray, w: int) -> float:
    """The spread of the window's low-passed force (its largest axis), over means of
    I_STILL_BLOCK samples (zero.window_spreads); numpy's sums, so the same values to the
    bit."""
    lp_at = pi[I_SO_WIN_LP]
    block = pi[I_STILL_BLOCK]
    spread = 0.0
    if block == 1:
        # the three lanes' chains of min and max side by side (each lane's in the same order:
        # the same values), where one lane after the other waited on each comparison
        lp = sf[lp_at : lp_at + 3 * w]
        lo0 = lo1 = lo2 = math.inf
        hi0 = hi1 = hi2 = -math.inf
        for j in range(w):
            v0, v1, v2 = lp[3 * j], lp[3 * j + 1], lp[3 * j + 2]
            lo0, hi0 = min(lo0, v0), max(hi0, v0)
            lo1, hi1 = min(lo1, v1), max(hi1, v1)
            lo2, hi2 = min(lo2, v2), max(hi2, v2)
        return max(max(max(spread, hi0 - lo0), hi1 - lo1), hi2 - lo2)
    for lane in range(3):
        lo, hi = math.inf, -math.inf
        for j in range(0, w, block):
            value = pairwise_sum(sf, lp_at + 3 * j + lane, block, 3) / block
            lo, hi = min(lo, value), max(hi, value)
        spread = max(spread, hi - lo)
    return spread


@inlined
def still_window(
    spread: float, t_end: float, pf: np.ndarray, pi: np.ndarray, sf: np.ndarray, si: np.ndarray
) -> int:
    """A still window of the tared desk (S_WIN_*), judged: back at the zero from before the
    last absorbed object (lifted: that zero restored, EV_LIFTED); else the still run goes on
    or starts again where the load moved; the idle desk's window (a load under P_DRIFT_MAX)
    joins the yardsticks and, after I_N_DRIFT such windows, the zero follows the drift (the
    mean of their means); any other load meets the object rule, and joins the zero when it
    is an object or held for I_N_SETTLE windows (EV_ABSORBED). Returns the events for Python
    (0: none, the common case). The load rests, as an object put down would, until the
    verdict (J_RESTING from the next sample on).

    A zero decided here applies from the next sample on (S_ZERO_NEXT), as it did when
    Python judged these windows after the sample; only the idle desk's drift followed with
    no object absorbed applies to this window's last sample already, as the kernel always
    did (the outputs stay the golden file's to the bit)."""
    si[J_WINDOWS_SEEN] += 1
    if si[J_OBJECTS] and lifted(pf, sf):
        for lane in range(6):
            sf[S_ZERO_NEXT + lane] = sf[S_OBJ_ZERO + lane]
        _zero_set(t_end, S_ZERO_NEXT, sf, si)
        si[J_OBJECTS] -= 1
        si[J_STILL_RUN] = si[J_OBJECT_RUN] = 0
        si[J_RESTING_OFF] = 1
        return EV_LIFTED
    f0 = sf[S_WIN_MEAN] - sf[S_ZERO]
    f1 = sf[S_WIN_MEAN + 1] - sf[S_ZERO + 1]
    f2 = sf[S_WIN_MEAN + 2] - sf[S_ZERO + 2]
    _still_run_on(f0, f1, f2, pf, pi, sf, si)
    load = math.sqrt(f0 * f0 + f1 * f1 + f2 * f2)
    if load < pf[P_DRIFT_MAX]:  # the idle desk: a window of its own unsteadiness
        mean = S_WIN_MEAN
        idle_window_joins(
            spread, sf[mean], sf[mean + 1], sf[mean + 2], si[J_WINDOW_INDEX], pi, sf, si
        )
        yardsticks_update(pf, pi, sf, si)
        if pi[I_N_DRIFT]:
            si[J_OBJECT_RUN] = 0
            _follow_drift(t_end, pi, sf, si)
            si[J_RESTING_OFF] = 1  # (no object run: the load is not resting)
            return 0
    run, is_object = object_still(si[J_OBJECT_RUN], spread, f0, f1, f2, load, pf, pi, sf, si)
    si[J_OBJECT_RUN] = run
    if not is_object and si[J_STILL_RUN] % pi[I_N_SETTLE]:
        if run > 0 and si[J_OBJ_RESTING]:
            si[J_RESTING_NEXT] = 1
        else:
            si[J_RESTING_OFF] = 1
        return 0
    _absorb(is_object, f0, f1, f2, load, t_end, pi, sf, si)
    return EV_ABSORBED


@inlined
def _still_run_on(
    f0: float, f1: float, f2: float, pf: np.ndarray, pi: np.ndarray, sf: np.ndarray, si: np.ndarray
) -> None:
    """The still run goes on with this window (its force less the zero f0, f1, f2; its mean
    wrench into the ring of I_SO_STILL_MEANS), or starts again here if the load moved by
    P_STILL_N."""
    lo, hi = sf[S_STILL_LO : S_STILL_LO + 3], sf[S_STILL_HI : S_STILL_HI + 3]
    if si[J_STILL_RUN]:
        width = 0.0
        for lane, f in enumerate((f0, f1, f2)):
            width = max(width, max(hi[lane], f) - min(lo[lane], f))
        if width >= pf[P_STILL_N]:
            si[J_STILL_RUN] = 0  # the load moved: a new still run starts here
    if si[J_STILL_RUN] == 0:
        lo[0] = hi[0] = f0
        lo[1] = hi[1] = f1
        lo[2] = hi[2] = f2
        si[J_STILL_COUNT] = 0
    else:
        for lane, f in enumerate((f0, f1, f2)):
            lo[lane], hi[lane] = min(lo[lane], f), max(hi[lane], f)
    ring = pi[I_STILL_RING]
    at = pi[I_SO_STILL_MEANS] + 6 * si[J_STILL_POS]
    for lane in range(6):
        sf[at + lane] = sf[S_WIN_MEAN + lane]
    si[J_STILL_POS] = si[J_STILL_POS] + 1 if si[J_STILL_POS] + 1 < ring else 0
    si[J_STILL_COUNT] = min(si[J_STILL_COUNT] + 1, ring)
    si[J_STILL_RUN] += 1


@inlined
def _follow_drift(t_end: float, pi: np.ndarray, sf: np.ndarray, si: np.ndarray) -> None:
    """An idle, still desk: what is left is sensor drift; after I_N_DRIFT windows the zero
    follows it (the mean of their means: often, so a drifting zero never builds up between
    touches)."""
    n = pi[I_N_DRIFT]
    if si[J_STILL_RUN] >= n:
        target = S_ZERO_NEXT if si[J_OBJECTS] else S_ZERO  # (still_window says why)
        _zero_of_still_means(n, target, pi, sf, si)
        _zero_set(t_end, target, sf, si)
        si[J_STILL_RUN] = 0


@inlined
def _absorb(
    is_object: bool,
    f0: float,
    f1: float,
    f2: float,
    load: float,
    t_end: float,
    pi: np.ndarray,
    sf: np.ndarray,
    si: np.ndarray,
) -> None:
    """A still load joins the zero: an object (the zero the mean over the windows that
    showed it one, not the last one alone: a desk swaying at 4–5 Hz moves a 0.2 s window's
    mean moment enough to put a press 2–3 mm off; their means are within the allowed
    wander), or a load held for I_N_SETTLE windows (the zero its window's mean). What it
    was added to, its weight and force go to S_OBJ_* (the last object's, for its lift and
    for Python's notice; J_OBJ_HELD the windows averaged, 0 for a held load)."""
    for lane in range(6):
        sf[S_OBJ_ZERO + lane] = sf[S_ZERO + lane]
    sf[S_OBJ_WEIGHT] = load
    sf[S_OBJ_F], sf[S_OBJ_F + 1], sf[S_OBJ_F + 2] = f0, f1, f2
    if is_object:
        held = min(si[J_OBJ_WINDOWS_N], si[J_STILL_COUNT])
        _zero_of_still_means(held, S_ZERO_NEXT, pi, sf, si)
        si[J_OBJ_HELD] = held
    else:
        for lane in range(6):
            sf[S_ZERO_NEXT + lane] = sf[S_WIN_MEAN + lane]
        si[J_OBJ_HELD] = 0
    _zero_set(t_end, S_ZERO_NEXT, sf, si)
    si[J_OBJECTS] += 1
    si[J_STILL_RUN] = si[J_OBJECT_RUN] = 0
    si[J_RESTING_OFF] = 1


@inlined
def _zero_of_still_means(
    n: int, target: int, pi: np.ndarray, sf: np.ndarray, si: np.ndarray
) -> None:
    """A zero (into sf[target:], S_ZERO or S_ZERO_NEXT): the mean of the still run's last
    ``n`` window means (its ring)."""
    ring = pi[I_STILL_RING]
    first = si[J_STILL_POS] - n
    if first < 0:
        first += ring
    for lane in range(6):
        sf[target + lane] = exact_mean(sf, pi[I_SO_STILL_MEANS] + lane, first, n, ring)


@inlined
def _zero_set(t: float, target: int, sf: np.ndarray, si: np.ndarray) -> None:
    """The zero just put in sf[target:] was set at time ``t``: at once (S_ZERO), or from the
    next sample on (S_ZERO_NEXT)."""
    if target == S_ZERO:
        sf[S_ZERO_T] = t
    else:
        sf[S_ZERO_T_NEXT] = t
        si[J_ZERO_NEXT] = 1
    si[J_ZERO_VERSION] += 1


@inlined
def zero_from_start(
    t: float, pf: np.ndarray, pi: np.ndarray, sf: np.ndarray, si: np.ndarray
) -> None:
    """Readings that come zeroed (``estimation.zeroed``), at the first good sample: the zero
    is 0 from here on (never tared, no drift, no object); the covariances are made from the
    profile's noise (zero.py, EV_COVS) before this sample is located."""
    for r in range(6):
        sf[S_ZERO + r] = 0.0
    sf[S_ZERO_T] = t
    si[J_TARED] = 1
    si[J_ZERO_VERSION] += 1
    si[J_DIRTY] = 1
    steps_changed(pf, pi, sf, si)  # (the steps the covariances use)
