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
    I_METHOD,
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
    I_TRACE,
    J_DELAY_POS,
    J_DET_POS,
    J_SWAY_DIFF_POS,
    J_SWAY_POS,
    METHOD_FORCE,
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
    Wrench,
)


@inlined
def _sections(
    pf: np.ndarray, sos: int, ns: int, sf: np.ndarray, zi: int, src: int, dst: int
) -> Wrench:
    """The six lanes sf[src:src+6] through a cascade of ``ns`` second-order sections
    (pf[sos:]), one lane each, into sf[dst:dst+6] (``src`` may be ``dst``): scipy's
    ``sosfilt`` recursion (transposed direct form II), to the bit. The state sf[zi:] is
    (ns, 2, 6): a section's two memories of the six lanes side by side. Each section reads
    its six inputs and twelve memories before it writes any, so that the six lanes run side
    by side in vector registers (a caller that needs three lanes gets six at the same cost).
    Returns the output as well, in registers: a stage that reads it back at once from sf
    in another width than it was stored in waits for the stores to reach the cache (the
    CPU forwards a store only to a load it contains)."""
    inp = sf[src : src + 6]
    x0, x1, x2, x3, x4, x5 = inp[0], inp[1], inp[2], inp[3], inp[4], inp[5]
    for s in range(ns):
        b = pf[sos + 6 * s : sos + 6 * s + 6]
        b0, b1, b2, a1, a2 = b[0], b[1], b[2], b[4], b[5]
        z = sf[zi + 12 * s : zi + 12 * s + 12]
        p0, p1, p2, p3, p4, p5 = z[0], z[1], z[2], z[3], z[4], z[5]
        q0, q1, q2, q3, q4, q5 = z[6], z[7], z[8], z[9], z[10], z[11]
        y0, y1, y2 = b0 * x0 + p0, b0 * x1 + p1, b0 * x2 + p2
        y3, y4, y5 = b0 * x3 + p3, b0 * x4 + p4, b0 * x5 + p5
        z[0], z[1], z[2] = b1 * x0 - a1 * y0 + q0, b1 * x1 - a1 * y1 + q1, b1 * x2 - a1 * y2 + q2
        z[3], z[4], z[5] = b1 * x3 - a1 * y3 + q3, b1 * x4 - a1 * y4 + q4, b1 * x5 - a1 * y5 + q5
        z[6], z[7], z[8] = b2 * x0 - a2 * y0, b2 * x1 - a2 * y1, b2 * x2 - a2 * y2
        z[9], z[10], z[11] = b2 * x3 - a2 * y3, b2 * x4 - a2 * y4, b2 * x5 - a2 * y5
        x0, x1, x2, x3, x4, x5 = y0, y1, y2, y3, y4, y5  # (the next section's input)
    out = sf[dst : dst + 6]
    out[0], out[1], out[2], out[3], out[4], out[5] = x0, x1, x2, x3, x4, x5
    return x0, x1, x2, x3, x4, x5


@inlined
def _difference(sf: np.ndarray, now: Wrench, delayed: np.ndarray, scale: float) -> None:
    """Paper eq. (8) for the six lanes: (``now`` − the same n samples ago, ``delayed``) ·
    ``scale`` into S_DIFF; ``delayed`` takes ``now`` in its place (read first, then written:
    side by side in vector registers, as :func:`_sections`)."""
    x0, x1, x2, x3, x4, x5 = now
    o0, o1, o2 = delayed[0], delayed[1], delayed[2]
    o3, o4, o5 = delayed[3], delayed[4], delayed[5]
    d = sf[S_DIFF : S_DIFF + 6]
    d[0], d[1], d[2] = (x0 - o0) * scale, (x1 - o1) * scale, (x2 - o2) * scale
    d[3], d[4], d[5] = (x3 - o3) * scale, (x4 - o4) * scale, (x5 - o5) * scale
    delayed[0], delayed[1], delayed[2] = x0, x1, x2
    delayed[3], delayed[4], delayed[5] = x3, x4, x5


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
    pf: np.ndarray,
    pi: np.ndarray,
    sf: np.ndarray,
    si: np.ndarray,
    w: int,
    wrench: Wrench,
    hist: int,
    pos_slot: int,
) -> Wrench:
    """Adds the sway's inertial wrench to the wrench sf[w:w+6] in place (``wrench``: its
    values, in registers, as :func:`_sections` returns them): the horizontal force's second
    difference over I_SPAN each way, F̈_h / ω_n², and its moment c × F̈_h (sway.py); the
    history of F_h is a ring of 2·I_SPAN. Returns the new wrench as well (in registers: see
    :func:`_sections`)."""
    span = pi[I_SPAN]
    n2 = 2 * span
    pos = si[pos_slot]
    mid = pos + span if pos + span < n2 else pos + span - n2
    fx, fy, fz, mx, my, mz = wrench
    scale = pf[P_SWAY_SCALE]
    cx = (fx - 2.0 * sf[hist + 2 * mid] + sf[hist + 2 * pos]) * scale
    cy = (fy - 2.0 * sf[hist + 2 * mid + 1] + sf[hist + 2 * pos + 1]) * scale
    sf[hist + 2 * pos], sf[hist + 2 * pos + 1] = fx, fy
    si[pos_slot] = pos + 1 if pos + 1 < n2 else 0
    lever = pi[I_PO_LEVER]
    fx, fy = fx + cx, fy + cy
    mx += pf[lever] * cx + pf[lever + 1] * cy
    my += pf[lever + 2] * cx + pf[lever + 3] * cy
    mz += pf[lever + 4] * cx + pf[lever + 5] * cy
    now = sf[w : w + 6]
    now[0], now[1], now[3], now[4], now[5] = fx, fy, mx, my, mz
    return fx, fy, fz, mx, my, mz


@inlined
def _slopes(
    pf: np.ndarray, pi: np.ndarray, sf: np.ndarray, si: np.ndarray, f0: float, f1: float, f2: float
) -> None:
    """The fast force (``f0``, ``f1``, ``f2``: S_DET's, in registers as :func:`_sections`
    returns them) less itself I_N_RATE and I_N_RELEASE samples ago, scaled, into S_SLOPE and
    S_RELEASE; it takes its place in their ring."""
    n_rate = pi[I_N_RATE]
    pos = si[J_DET_POS]
    recent = pos + n_rate - pi[I_N_RELEASE]
    if recent >= n_rate:
        recent -= n_rate
    oldest = sf[pi[I_SO_DET_RING] + 3 * pos : pi[I_SO_DET_RING] + 3 * pos + 3]
    then = sf[pi[I_SO_DET_RING] + 3 * recent : pi[I_SO_DET_RING] + 3 * recent + 3]
    rate, release = pf[P_RATE_SCALE], pf[P_RELEASE_SCALE]
    o0, o1, o2, r0, r1, r2 = oldest[0], oldest[1], oldest[2], then[0], then[1], then[2]
    slope, falling = sf[S_SLOPE : S_SLOPE + 3], sf[S_RELEASE : S_RELEASE + 3]
    slope[0], slope[1], slope[2] = (f0 - o0) * rate, (f1 - o1) * rate, (f2 - o2) * rate
    falling[0], falling[1] = (f0 - r0) * release, (f1 - r1) * release
    falling[2] = (f2 - r2) * release
    oldest[0], oldest[1], oldest[2] = f0, f1, f2
    si[J_DET_POS] = pos + 1 if pos + 1 < n_rate else 0


@inlined
def _filters(pf: np.ndarray, pi: np.ndarray, sf: np.ndarray, si: np.ndarray) -> None:
    """The sample in flight (S_RAW) through the filter bank: the conventional low-pass
    (S_LP), the pseudo-differentiated wrench (S_DIFF, paper eq. 8: an n-sample difference,
    scaled, low-passed), the fast low-pass (S_DET) and its slope over I_N_RATE and
    I_N_RELEASE samples (S_SLOPE, S_RELEASE); with the sway compensated (I_SPAN > 0)."""
    ns = pi[I_NS]
    # the fast path (its moments are used where I_DET_FULL, its force always)
    det = _sections(pf, pi[I_PO_DET_SOS], ns, sf, pi[I_SO_DET_ZI], S_RAW, S_DET)
    _slopes(pf, pi, sf, si, det[0], det[1], det[2])
    n_diff = pi[I_N_DIFF]
    pos = si[J_DELAY_POS]
    delayed = sf[pi[I_SO_DELAY] + 6 * pos : pi[I_SO_DELAY] + 6 * pos + 6]
    scale = pf[P_DIFF_SCALE]
    # the differentiated wrench makes P_ed only: a `force` estimator that traces nothing never
    # reads it, and skips it (its ring and memories are then never read either)
    diff = pi[I_METHOD] != METHOD_FORCE or pi[I_TRACE] == 1
    if pi[I_SHARED_LP]:
        # a difference commutes with an LTI filter: the difference of the low-passed wrench
        lp = _sections(pf, pi[I_PO_LP_SOS], ns, sf, pi[I_SO_LP_ZI], S_RAW, S_LP)
        if pi[I_SPAN]:
            lp = _sway(pf, pi, sf, si, S_LP, lp, pi[I_SO_SWAY], J_SWAY_POS)
        if diff:
            _difference(sf, lp, delayed, scale)  # paper eq. (8)
    else:
        d = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
        if diff:
            raw = sf[S_RAW : S_RAW + 6]
            now = (raw[0], raw[1], raw[2], raw[3], raw[4], raw[5])
            _difference(sf, now, delayed, scale)  # paper eq. (8), low-passed
            d = _sections(pf, pi[I_PO_DIFF_SOS], ns, sf, pi[I_SO_DIFF_ZI], S_DIFF, S_DIFF)
        lp = _sections(pf, pi[I_PO_LP_SOS], ns, sf, pi[I_SO_LP_ZI], S_RAW, S_LP)
        if pi[I_SPAN]:
            _sway(pf, pi, sf, si, S_LP, lp, pi[I_SO_SWAY], J_SWAY_POS)
            if diff:
                _sway(pf, pi, sf, si, S_DIFF, d, pi[I_SO_SWAY_DIFF], J_SWAY_DIFF_POS)
    si[J_DELAY_POS] = pos + 1 if pos + 1 < n_diff else 0
