"""The filter bank, compiled: the wrench low-passed, pseudo-differentiated and fast, the sway.

Stages 2 and 2b of the kernel (:mod:`hapticdesk.estimator.kernel`), the per-sample side of
:mod:`hapticdesk.estimator.filters` and :mod:`hapticdesk.estimator.sway`: :func:`_sections`
runs second-order sections as scipy's ``sosfilt`` does, to the bit; :func:`_steady` and
:func:`_restart_filters` start them as if the input had been constant forever (the first
good sample, after a gap); :func:`_filters` makes the low-passed wrench, the n-sample
pseudo-difference low-passed (paper eq. 8) and the fast 30 Hz force with its slopes;
:func:`_sway` adds the desk's sway, its inertial wrench from the low-passed force's curvature.
"""

from __future__ import annotations

import numpy as np

from hapticdesk.estimator.kernel_compile import inlined
from hapticdesk.estimator.kernel_slots import (
    I_DET_FULL,
    I_N_DIFF,
    I_N_RATE,
    I_N_RELEASE,
    I_NS,
    I_PO_DET_SOS,
    I_PO_DET_ZI,
    I_PO_DIFF_SOS,
    I_PO_LEVER,
    I_PO_LP_SOS,
    I_PO_LP_ZI,
    I_SHARED_LP,
    I_SO_DELAY,
    I_SO_DET_RING,
    I_SO_DET_ZI,
    I_SO_DIFF_ZI,
    I_SO_LP_ZI,
    I_SO_SWAY,
    I_SO_SWAY_DIFF,
    I_SPAN,
    J_DELAY_POS,
    J_DET_POS,
    J_SWAY_DIFF_POS,
    J_SWAY_POS,
    P_DIFF_SCALE,
    P_RATE_SCALE,
    P_RELEASE_SCALE,
    P_SWAY_SCALE,
    S_DET,
    S_DIFF,
    S_LP,
    S_RAW,
    S_RELEASE,
    S_SLOPE,
)


@inlined
def _sections(
    pf: np.ndarray, sos: int, ns: int, sf: np.ndarray, zi: int, src: int, dst: int, lanes: int
) -> None:
    """``lanes`` samples sf[src:src+lanes] through a cascade of ``ns`` second-order sections
    (pf[sos:]), one lane each, into sf[dst:]: scipy's ``sosfilt`` recursion (transposed
    direct form II), to the bit. The state sf[zi:] is (ns, 2, 6): a section's two memories
    of the six lanes side by side, so the lanes run together."""
    out = sf[dst : dst + 6]
    for s in range(ns):
        b = sos + 6 * s
        b0, b1, b2, a1, a2 = pf[b], pf[b + 1], pf[b + 2], pf[b + 4], pf[b + 5]
        z0 = sf[zi + 12 * s : zi + 12 * s + 6]
        z1 = sf[zi + 12 * s + 6 : zi + 12 * s + 12]
        inp = sf[src : src + 6]
        for lane in range(lanes):
            x = inp[lane]
            y = b0 * x + z0[lane]
            z0[lane] = b1 * x - a1 * y + z1[lane]
            z1[lane] = b2 * x - a2 * y
            out[lane] = y
        src = dst


@inlined
def _steady(pf: np.ndarray, unit: int, ns: int, sf: np.ndarray, zi: int, src: int) -> None:
    """The six lanes' sections set as if sf[src:src+6] had been the input forever (the
    state of a unit step, pf[unit:] (ns, 2), scaled)."""
    for s in range(ns):
        for j in range(2):
            for lane in range(6):
                sf[zi + 12 * s + 6 * j + lane] = sf[src + lane] * pf[unit + 2 * s + j]


@inlined
def _restart_filters(pf: np.ndarray, pi: np.ndarray, sf: np.ndarray, si: np.ndarray) -> None:
    """Every filter as if the sample in flight (S_RAW) had been the input forever (the
    first good sample, and after a gap)."""
    ns = pi[I_NS]
    _steady(pf, pi[I_PO_LP_ZI], ns, sf, pi[I_SO_LP_ZI], S_RAW)
    _steady(pf, pi[I_PO_DET_ZI], ns, sf, pi[I_SO_DET_ZI], S_RAW)
    for j in range(12 * ns):
        sf[pi[I_SO_DIFF_ZI] + j] = 0.0  # (the differentiated wrench: 0 when nothing moves)
    for j in range(pi[I_N_DIFF]):
        for lane in range(6):
            sf[pi[I_SO_DELAY] + 6 * j + lane] = sf[S_RAW + lane]
    for j in range(pi[I_N_RATE]):
        for lane in range(3):
            sf[pi[I_SO_DET_RING] + 3 * j + lane] = sf[S_RAW + lane]
    n2 = 2 * pi[I_SPAN]
    for j in range(n2):
        for lane in range(2):
            sf[pi[I_SO_SWAY] + 2 * j + lane] = sf[S_RAW + lane]
            sf[pi[I_SO_SWAY_DIFF] + 2 * j + lane] = 0.0
    si[J_DELAY_POS] = si[J_DET_POS] = si[J_SWAY_POS] = si[J_SWAY_DIFF_POS] = 0


@inlined
def _sway(
    pf: np.ndarray, pi: np.ndarray, sf: np.ndarray, si: np.ndarray, w: int, hist: int, pos_slot: int
) -> None:
    """Adds the sway's inertial wrench to the wrench sf[w:w+6] in place: the horizontal
    force's second difference over I_SPAN each way, F̈_h / ω_n², and its moment c × F̈_h
    (sway.py); the history of F_h is a ring of 2·I_SPAN."""
    span = pi[I_SPAN]
    n2 = 2 * span
    pos = si[pos_slot]
    mid = pos + span if pos + span < n2 else pos + span - n2
    fx, fy = sf[w], sf[w + 1]
    scale = pf[P_SWAY_SCALE]
    cx = (fx - 2.0 * sf[hist + 2 * mid] + sf[hist + 2 * pos]) * scale
    cy = (fy - 2.0 * sf[hist + 2 * mid + 1] + sf[hist + 2 * pos + 1]) * scale
    sf[hist + 2 * pos], sf[hist + 2 * pos + 1] = fx, fy
    si[pos_slot] = pos + 1 if pos + 1 < n2 else 0
    lever = pi[I_PO_LEVER]
    sf[w] = fx + cx
    sf[w + 1] = fy + cy
    sf[w + 3] += pf[lever] * cx + pf[lever + 1] * cy
    sf[w + 4] += pf[lever + 2] * cx + pf[lever + 3] * cy
    sf[w + 5] += pf[lever + 4] * cx + pf[lever + 5] * cy


@inlined
def _filters(pf: np.ndarray, pi: np.ndarray, sf: np.ndarray, si: np.ndarray) -> None:
    """The sample in flight (S_RAW) through the filter bank: the conventional low-pass
    (S_LP), the pseudo-differentiated wrench (S_DIFF, paper eq. 8: an n-sample difference,
    scaled, low-passed), the fast low-pass (S_DET) and its slope over I_N_RATE and
    I_N_RELEASE samples (S_SLOPE, S_RELEASE); with the sway compensated (I_SPAN > 0)."""
    ns = pi[I_NS]
    # the fast path: its force, and its moments too where they are used
    _sections(
        pf, pi[I_PO_DET_SOS], ns, sf, pi[I_SO_DET_ZI], S_RAW, S_DET, 6 if pi[I_DET_FULL] else 3
    )
    n_rate = pi[I_N_RATE]
    pos = si[J_DET_POS]
    recent = pos + n_rate - pi[I_N_RELEASE]
    if recent >= n_rate:
        recent -= n_rate
    oldest = sf[pi[I_SO_DET_RING] + 3 * pos : pi[I_SO_DET_RING] + 3 * pos + 3]
    then = sf[pi[I_SO_DET_RING] + 3 * recent : pi[I_SO_DET_RING] + 3 * recent + 3]
    for lane in range(3):
        f = sf[S_DET + lane]
        sf[S_SLOPE + lane] = (f - oldest[lane]) * pf[P_RATE_SCALE]
        sf[S_RELEASE + lane] = (f - then[lane]) * pf[P_RELEASE_SCALE]
    for lane in range(3):
        oldest[lane] = sf[S_DET + lane]
    si[J_DET_POS] = pos + 1 if pos + 1 < n_rate else 0
    n_diff = pi[I_N_DIFF]
    pos = si[J_DELAY_POS]
    delayed = sf[pi[I_SO_DELAY] + 6 * pos : pi[I_SO_DELAY] + 6 * pos + 6]
    scale = pf[P_DIFF_SCALE]
    if pi[I_SHARED_LP]:
        # a difference commutes with an LTI filter: the difference of the low-passed wrench
        _sections(pf, pi[I_PO_LP_SOS], ns, sf, pi[I_SO_LP_ZI], S_RAW, S_LP, 6)
        if pi[I_SPAN]:
            _sway(pf, pi, sf, si, S_LP, pi[I_SO_SWAY], J_SWAY_POS)
        for lane in range(6):
            x = sf[S_LP + lane]
            sf[S_DIFF + lane] = (x - delayed[lane]) * scale  # paper eq. (8)
            delayed[lane] = x
    else:
        for lane in range(6):
            x = sf[S_RAW + lane]
            sf[S_DIFF + lane] = (x - delayed[lane]) * scale  # paper eq. (8) ...
            delayed[lane] = x
        _sections(
            pf, pi[I_PO_DIFF_SOS], ns, sf, pi[I_SO_DIFF_ZI], S_DIFF, S_DIFF, 6
        )  # ... low-passed
        _sections(pf, pi[I_PO_LP_SOS], ns, sf, pi[I_SO_LP_ZI], S_RAW, S_LP, 6)
        if pi[I_SPAN]:
            _sway(pf, pi, sf, si, S_LP, pi[I_SO_SWAY], J_SWAY_POS)
            _sway(pf, pi, sf, si, S_DIFF, pi[I_SO_SWAY_DIFF], J_SWAY_DIFF_POS)
    si[J_DELAY_POS] = pos + 1 if pos + 1 < n_diff else 0
