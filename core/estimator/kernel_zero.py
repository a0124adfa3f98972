"""The zero's windows, compiled: each sample into the window, the window measured at its end.

The kernel's side of :mod:`hapticdesk.estimator.zero`: :func:`window_add` fills the window
with the sample in flight (its low-passed force, its wrench, whether it is bad) and, at the
window's end, measures it (the spread of the low-passed force, the mean wrench) and raises
``EV_WINDOW`` for Python (the tare, the object rule); a tared desk's window that is not
still only ends the still run, and the idle desk's still windows are judged here
(:func:`_idle_window`: the still run, the idle log, the drift followed). Its sums are
numpy's (:func:`pairwise_sum`) and math.fsum's (:func:`exact_mean`) to the bit, so the
kernel's zero equals zero.py's. Readings that come zeroed (a force plate's) have no window:
:func:`zero_from_start` sets their zero to 0 at the first good sample.
"""

from __future__ import annotations

import math

import numpy as np

from hapticdesk.estimator.contacts import BAD_SAMPLE, FLAG_GAP
from hapticdesk.estimator.kernel_channels import steps_changed
from hapticdesk.estimator.kernel_compile import compiled, inlined
from hapticdesk.estimator.kernel_slots import (
    EV_WINDOW,
    I_IDLE_LOG,
    I_JO_WIN_BAD,
    I_N_DRIFT,
    I_SO_IDLE_LOG,
    I_SO_STILL_MEANS,
    I_SO_WIN_LP,
    I_SO_WIN_RAW,
    I_STILL_BLOCK,
    I_STILL_RING,
    I_WINDOW,
    J_DIRTY,
    J_IDLE_LOG_N,
    J_IDLE_LOG_POS,
    J_OBJECT_RUN,
    J_OBJECTS,
    J_RESTING_OFF,
    J_STILL_COUNT,
    J_STILL_POS,
    J_STILL_RUN,
    J_TARED,
    J_WIN_BADS,
    J_WIN_FILL,
    J_WINDOW_INDEX,
    J_WINDOWS_SEEN,
    J_ZERO_VERSION,
    P_DRIFT_MAX,
    P_STILL_N,
    S_LP,
    S_RAW,
    S_STILL_HI,
    S_STILL_LO,
    S_WIN_MEAN,
    S_WIN_SPREAD,
    S_WIN_T_END,
    S_ZERO,
    S_ZERO_T,
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
    it is bad); at the window's end its spread, mean and last time go to S_WIN_* and
    EV_WINDOW is returned, unless the desk is tared and the window is not still. Before the
    first good sample there is no wrench (the filters have not started: zeros); that sample
    stands in for those before it in its window, as if the input had started with it."""
    w = pi[I_WINDOW]
    win_lp = sf[pi[I_SO_WIN_LP] : pi[I_SO_WIN_LP] + 3 * w]
    win_raw = sf[pi[I_SO_WIN_RAW] : pi[I_SO_WIN_RAW] + 6 * w]
    win_bad = si[pi[I_JO_WIN_BAD] : pi[I_JO_WIN_BAD] + w]
    m = si[J_WIN_FILL]
    for j in range(m if first_good else 0):
        for lane in range(3):
            win_lp[lane * w + j] = sf[S_LP + lane]
        for lane in range(6):
            win_raw[lane * w + j] = sf[S_RAW + lane]
    for lane in range(3):
        win_lp[lane * w + m] = sf[S_LP + lane]
    for lane in range(6):
        win_raw[lane * w + m] = sf[S_RAW + lane]
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
    if si[J_TARED] and (bads / w > 0.1 or spread >= pf[P_STILL_N]):
        # once tared, a window that is not still (or mostly held over) only ends a still run
        # and the resting, from the next sample on (zero.py)
        si[J_STILL_RUN] = si[J_OBJECT_RUN] = 0
        si[J_RESTING_OFF] = 1
        return 0
    sf[S_WIN_SPREAD] = spread
    for lane in range(6):
        sf[S_WIN_MEAN + lane] = pairwise_sum(sf, pi[I_SO_WIN_RAW] + lane * w, w, 1) / w
    sf[S_WIN_T_END] = t
    if si[J_TARED] and _idle_window(spread, t, pf, pi, sf, si):
        return 0
    return EV_WINDOW


@inlined
def _window_spread(pi: np.ndarray, sf: np.ndarray, w: int) -> float:
    """The spread of the window's low-passed force (its largest axis), over means of
    I_STILL_BLOCK samples (zero.window_spreads); numpy's sums, so the same values to the
    bit."""
    lp_at = pi[I_SO_WIN_LP]
    block = pi[I_STILL_BLOCK]
    spread = 0.0
    for lane in range(3):
        lo, hi = math.inf, -math.inf
        for j in range(0, w, block):
            value = (
                sf[lp_at + lane * w + j]
                if block == 1
                else pairwise_sum(sf, lp_at + lane * w + j, block, 1) / block
            )
            lo, hi = min(lo, value), max(hi, value)
        spread = max(spread, hi - lo)
    return spread


@inlined
def _idle_window(
    spread: float, t_end: float, pf: np.ndarray, pi: np.ndarray, sf: np.ndarray, si: np.ndarray
) -> bool:
    """A still window of a tared desk with nothing absorbed, whose load is lighter than
    P_DRIFT_MAX: the idle desk, judged here as ZeroStage._still_window does (the still run
    goes on or starts again where the load moved, the window joins the idle desk's yardsticks
    — logged for zero.py —, and after I_N_DRIFT such windows the zero follows the drift: the
    mean of their means). Returns False, changing nothing, for any other window (Python's)."""
    if si[J_OBJECTS] or pi[I_N_DRIFT] == 0:
        return False
    f0 = sf[S_WIN_MEAN] - sf[S_ZERO]
    f1 = sf[S_WIN_MEAN + 1] - sf[S_ZERO + 1]
    f2 = sf[S_WIN_MEAN + 2] - sf[S_ZERO + 2]
    if not math.sqrt(f0 * f0 + f1 * f1 + f2 * f2) < pf[P_DRIFT_MAX]:
        return False
    si[J_WINDOWS_SEEN] += 1
    lo, hi = sf[S_STILL_LO : S_STILL_LO + 3], sf[S_STILL_HI : S_STILL_HI + 3]
    moved = False
    if si[J_STILL_RUN]:
        width = 0.0
        for lane, f in enumerate((f0, f1, f2)):
            width = max(width, max(hi[lane], f) - min(lo[lane], f))
        moved = width >= pf[P_STILL_N]
        if moved:
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
    log = pi[I_SO_IDLE_LOG] + 5 * si[J_IDLE_LOG_POS]
    sf[log] = spread
    sf[log + 1], sf[log + 2], sf[log + 3] = sf[S_WIN_MEAN], sf[S_WIN_MEAN + 1], sf[S_WIN_MEAN + 2]
    sf[log + 4] = si[J_WINDOW_INDEX]
    si[J_IDLE_LOG_POS] = si[J_IDLE_LOG_POS] + 1 if si[J_IDLE_LOG_POS] + 1 < pi[I_IDLE_LOG] else 0
    si[J_IDLE_LOG_N] = min(si[J_IDLE_LOG_N] + 1, pi[I_IDLE_LOG])
    si[J_OBJECT_RUN] = 0
    n = pi[I_N_DRIFT]
    if si[J_STILL_RUN] >= n:  # the drift followed: the mean of the last n windows' means
        for lane in range(6):
            first = si[J_STILL_POS] - n
            if first < 0:
                first += ring
            sf[S_ZERO + lane] = exact_mean(sf, pi[I_SO_STILL_MEANS] + lane, first, n, ring)
        sf[S_ZERO_T] = t_end
        si[J_ZERO_VERSION] += 1
        si[J_STILL_RUN] = 0
    si[J_RESTING_OFF] = 1  # (no object run: the load is not resting)
    return True


@inlined
def exact_mean(sf: np.ndarray, base: int, first: int, n: int, ring: int) -> float:
    """The mean of n values sf[base + 6·((first + j) mod ring)], summed with Neumaier's
    compensation: for the default two windows the correctly rounded sum, as zero.py's
    math.fsum; for more, the same to rounding."""
    total = 0.0
    small = 0.0
    for j in range(n):
        at = first + j
        if at >= ring:
            at -= ring
        x = sf[base + 6 * at]
        t = total + x
        if abs(total) >= abs(x):
            small += (total - t) + x
        else:
            small += (x - t) + total
        total = t
    return (total + small) / n


@compiled
def pairwise_sum(a: np.ndarray, start: int, n: int, stride: int) -> float:
    """Σ a[start + j·stride] for j < n, summed as numpy sums a contiguous axis (pairwise, 8
    lanes), so a window's mean is numpy's to the last bit."""
    if n < 8:
        res = 0.0
        for j in range(n):
            res += a[start + j * stride]
        return res
    if n <= 128:
        r0 = a[start]
        r1 = a[start + stride]
        r2 = a[start + 2 * stride]
        r3 = a[start + 3 * stride]
        r4 = a[start + 4 * stride]
        r5 = a[start + 5 * stride]
        r6 = a[start + 6 * stride]
        r7 = a[start + 7 * stride]
        j = 8
        while j < n - (n % 8):
            b = start + j * stride
            r0 += a[b]
            r1 += a[b + stride]
            r2 += a[b + 2 * stride]
            r3 += a[b + 3 * stride]
            r4 += a[b + 4 * stride]
            r5 += a[b + 5 * stride]
            r6 += a[b + 6 * stride]
            r7 += a[b + 7 * stride]
            j += 8
        res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
        while j < n:
            res += a[start + j * stride]
            j += 1
        return res
    n2 = n // 2
    n2 -= n2 % 8
    return pairwise_sum(a, start, n2, stride) + pairwise_sum(a, start + n2 * stride, n - n2, stride)


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
