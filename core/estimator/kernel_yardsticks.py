"""The idle desk's yardsticks, compiled: its windows' spreads and wanders, and their medians.

The kernel's side of :mod:`hapticdesk.estimator.yardsticks` (which says what they are and
why): every still window of the idle desk joins them here at its window's end
(:func:`idle_window_joins`, from :func:`hapticdesk.estimator.kernel_zero.still_window`), and
the tare's windows at the tare (:func:`tare_yardsticks`, called from Python). Kept here, not in
Python, so a window's end never leaves the compiled loop: Python's lists and sorts cost
45–55 µs of a push each idle window (the code and data cold by then, five times a second).
Rings of fixed size in the state (``I_SO_IDLE_*``) hold what Python's lists held, in the same
order, so the medians are the same values.
"""

from __future__ import annotations

import math

import numpy as np

from hapticdesk.estimator.kernel_compile import compiled, inlined
from hapticdesk.estimator.kernel_slots import (
    I_IDLE_WINDOWS,
    I_SO_IDLE_SPREADS,
    I_SO_IDLE_TAIL,
    I_SO_IDLE_WANDERS,
    I_SO_SCRATCH,
    I_WANDER_WINDOWS,
    J_IDLE_SPREADS_N,
    J_IDLE_SPREADS_POS,
    J_IDLE_TAIL_N,
    J_IDLE_TAIL_POS,
    J_IDLE_WANDERS_N,
    J_IDLE_WANDERS_POS,
    P_IDLE_QUANTILE,
    P_STILL_N,
    P_STILL_NOISE_FACTOR,
    S_QUIET_SPREAD,
    S_QUIET_WANDER,
)


@inlined
def ring_push(si: np.ndarray, n_slot: int, pos_slot: int, cap: int, keep: int) -> int:
    """Where the next entry of a ring of ``cap`` entries goes (its count si[n_slot], at most
    ``keep`` ≤ cap, and its next place si[pos_slot] move on): its last ``keep`` entries are
    the last ones put, as a list trimmed at the front would keep."""
    pos = si[pos_slot]
    si[pos_slot] = pos + 1 if pos + 1 < cap else 0
    si[n_slot] = min(si[n_slot] + 1, keep)
    return pos


@inlined
def ring_wander(sf: np.ndarray, at: int, cap: int, pos: int, n: int) -> float:
    """How far the last ``n`` force means of a ring of 4-wide entries (something, force (3))
    strayed: the widest range of any component (yardsticks.wander, the same measure)."""
    strayed = 0.0
    for lane in range(1, 4):
        lo, hi = math.inf, -math.inf
        for j in range(n):
            k = pos - n + j
            if k < 0:
                k += cap
            value = sf[at + 4 * k + lane]
            lo, hi = min(lo, value), max(hi, value)
        strayed = max(strayed, hi - lo)
    return strayed


@inlined
def nth_smallest(
    sf: np.ndarray, at: int, stride: int, cap: int, pos: int, n: int, k: int, scratch: int
) -> float:
    """The ``k``-th smallest of the last ``n`` entries of a ring (sf[at + stride·j], ``pos``
    the next place), sorted in sf[scratch:] (at most 64 values, a window's end: an insertion
    sort is enough)."""
    for j in range(n):
        slot = pos - n + j
        if slot < 0:
            slot += cap
        value = sf[at + stride * slot]
        i = j
        while i > 0 and sf[scratch + i - 1] > value:
            sf[scratch + i] = sf[scratch + i - 1]
            i -= 1
        sf[scratch + i] = value
    return sf[scratch + k]


@inlined
def idle_window_joins(
    spread: float,
    f0: float,
    f1: float,
    f2: float,
    index: int,
    pi: np.ndarray,
    sf: np.ndarray,
    si: np.ndarray,
) -> None:
    """One more window of the idle desk (``index``: its number; its spread and force mean):
    its spread joins the last I_IDLE_WINDOWS, and once I_WANDER_WINDOWS windows in a row are
    in the tail (none left out), how far their means strayed joins the wanders.
    :func:`yardsticks_update` then makes the yardsticks."""
    cap = pi[I_IDLE_WINDOWS]
    k = ring_push(si, J_IDLE_SPREADS_N, J_IDLE_SPREADS_POS, cap, cap)
    sf[pi[I_SO_IDLE_SPREADS] + k] = spread
    w, tail = pi[I_WANDER_WINDOWS], pi[I_SO_IDLE_TAIL]
    n, pos = si[J_IDLE_TAIL_N], si[J_IDLE_TAIL_POS]
    while n > 0:  # (the oldest first: the windows' numbers rise along the ring)
        oldest = pos - n
        if oldest < 0:
            oldest += w
        if index - sf[tail + 4 * oldest] < w:
            break
        n -= 1
    si[J_IDLE_TAIL_N] = n
    k = ring_push(si, J_IDLE_TAIL_N, J_IDLE_TAIL_POS, w, w)
    sf[tail + 4 * k] = index
    sf[tail + 4 * k + 1], sf[tail + 4 * k + 2], sf[tail + 4 * k + 3] = f0, f1, f2
    if si[J_IDLE_TAIL_N] == w:
        strayed = ring_wander(sf, tail, w, si[J_IDLE_TAIL_POS], w)
        k = ring_push(si, J_IDLE_WANDERS_N, J_IDLE_WANDERS_POS, cap, cap)
        sf[pi[I_SO_IDLE_WANDERS] + k] = strayed


@inlined
def yardsticks_update(pf: np.ndarray, pi: np.ndarray, sf: np.ndarray, si: np.ndarray) -> None:
    """The quiet spread and wander: the P_IDLE_QUANTILE quantile (nearest rank) of the idle
    desk's last windows' (kept as they are while there are none)."""
    cap, q, scratch = pi[I_IDLE_WINDOWS], pf[P_IDLE_QUANTILE], pi[I_SO_SCRATCH]
    n = si[J_IDLE_SPREADS_N]
    if n:
        k = min(n - 1, int(q * n))
        at, pos = pi[I_SO_IDLE_SPREADS], si[J_IDLE_SPREADS_POS]
        sf[S_QUIET_SPREAD] = nth_smallest(sf, at, 1, cap, pos, n, k, scratch)
    n = si[J_IDLE_WANDERS_N]
    if n:
        k = min(n - 1, int(q * n))
        at, pos = pi[I_SO_IDLE_WANDERS], si[J_IDLE_WANDERS_POS]
        sf[S_QUIET_WANDER] = nth_smallest(sf, at, 1, cap, pos, n, k, scratch)


@compiled
def tare_yardsticks(
    windows: np.ndarray, pf: np.ndarray, pi: np.ndarray, sf: np.ndarray, si: np.ndarray
) -> None:
    """At the tare (called from Python, :mod:`hapticdesk.estimator.zero`): the yardsticks
    start again from the tare's quiet windows, ``windows`` (n, 5) rows of spread, force mean
    (3) and window number, in a row."""
    for slot in (
        J_IDLE_SPREADS_N,
        J_IDLE_SPREADS_POS,
        J_IDLE_WANDERS_N,
        J_IDLE_WANDERS_POS,
        J_IDLE_TAIL_N,
        J_IDLE_TAIL_POS,
    ):
        si[slot] = 0
    sf[S_QUIET_SPREAD] = sf[S_QUIET_WANDER] = 0.0
    for j in range(windows.shape[0]):
        row = windows[j]
        idle_window_joins(row[0], row[1], row[2], row[3], int(row[4]), pi, sf, si)
    yardsticks_update(pf, pi, sf, si)


@inlined
def still_limit(pf: np.ndarray, sf: np.ndarray) -> float:
    """How far a still window's low-passed force may spread: ``still_n``, or on a desk whose
    own idle windows spread more, P_STILL_NOISE_FACTOR times their median (S_QUIET_SPREAD,
    yardsticks.STILL_NOISE_FACTOR says why)."""
    return max(pf[P_STILL_N], pf[P_STILL_NOISE_FACTOR] * sf[S_QUIET_SPREAD])
