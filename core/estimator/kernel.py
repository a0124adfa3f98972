"""The estimator's per-sample work, compiled (numba): one function over flat arrays, two entries.

Every sample goes through :func:`_sample` once, whether it came in a block of a million or
alone: the block entry :func:`run_block` loops it over a push, writing into preallocated
output columns, and the one-sample entry :func:`run_step` calls it for a single sample, into
a reused one-sample record. So streaming equals batch by construction.

The arrays (built once per estimator by :mod:`hapticdesk.estimator.params`):

- ``pf`` (float64) and ``pi`` (int64), the **parameters**: the desk's settings flattened once
  (the channels→wrench matrix, the channels' limits, the filters' sections, the surfaces, the
  thresholds). The ``P_*`` and ``I_*`` names below are their fixed slots; desk-sized parts
  sit at offsets stored in ``pi`` (``I_PO_*`` into ``pf``, ``I_SO_*``/``I_JO_*`` into the
  state).
- ``sf`` (float64) and ``si`` (int64), the **state**: filter memories, delay rings, the
  current zero, the window being filled, the detector's and the second-finger stage's
  state. ``S_*`` and ``J_*`` name the fixed slots. A snapshot is a copy of both; a re-tare
  resets slices of them.
- ``out_f`` (float64, rows ``OUT_*``), ``out_b`` (int8, rows ``OUT_B_*``: the booleans and
  small codes) and ``out_s`` (int16, the surface): the output columns, one per sample.

What happens rarely leaves the loop as an **event**: :func:`_sample` returns the ``EV_*``
bits it raised, the entry returns them with the sample's index in ``si[J_EVENT_AT]``, and
Python (:class:`hapticdesk.estimator.contact_estimator.ContactEstimator`) handles them — a
notice, a zero window's end (the tare and the object rule are judged there, five times a
second), the covariances made anew, the second finger's fit, the stray it learns at a
contact's end, the gain of partial accelerometer readings — then calls the entry again from
where ``si[J_RESUME]`` says: the next sample, the second half of the same one (new
covariances are used by the sample whose reading brought them), or the same one again
(the gain of its pattern of usable readings is ready, and kept for the next sample alike).

The stages, in the order a sample meets them (the paper's equations where they are
followed): bad samples and the channels→wrench matrix (eqs. 1–4) with the resolution steps
learned; the accelerometer's inertial wrench; the filter bank (second-order sections, the
n-sample pseudo-difference of eq. 8, the fast 30 Hz path), the sway; the window of the zero;
the detector; the candidates with their covariances (eqs. 5, 11, 12) and the methods (force,
diff, switched = Fig. 3, fused); the second finger. Each stage's Python side (its settings,
its notices, what it decides at an event) is in the module of its name.

The desk-sized regions are read through views taken once per call (``pf[at : at + n]``):
indexed from zero, their loops compile to plain array walks, where an offset index would keep
LLVM from proving it non-negative (measured: the channel checks took 107 ns a sample with
offsets, 20 with views). Compiled without numba's reference counting and with its helpers inlined
into the entries (:mod:`.kernel_compile`).

The fixed slots and codes (``P_*``, ``I_*``, ``S_*``, ``J_*``, ``OUT_*``, ``EV_*``…) are in
:mod:`.kernel_slots`; how the kernel is compiled and its cache stamped (with every
``kernel*.py`` file, so a cache never outlives a change of the code it was made from) in
:mod:`.kernel_compile`. (The ``FLAG_*``, ``SOURCE_*`` and ``PHASE_*`` codes come from
:mod:`.contacts`: they are contracts and never change.)
"""

from __future__ import annotations

import logging
import math
import sys
import time
from typing import Any

import numpy as np
from numba import types
from numba.core import event

from hapticdesk.estimator.contacts import (
    BAD_SAMPLE,
    FLAG_GAP,
    FLAG_MULTI,
    FLAG_NAN,
    FLAG_NO_ACCEL,
    FLAG_NOT_TARED,
    FLAG_SATURATED,
    FLAG_STUCK,
    FLAG_TIME_BACK,
    PHASE_HOLD,
    PHASE_RELEASE,
    PHASE_TOUCH,
    SOURCE_DIFF,
    SOURCE_FORCE,
    SOURCE_FUSED,
)
from hapticdesk.estimator.kernel_compile import compiled, inlined, vectorized
from hapticdesk.estimator.kernel_geometry import contains, intersect, shear_of, surface_at, to_desk
from hapticdesk.estimator.kernel_slots import (
    COV_DET,
    COV_DIFF,
    COV_DRIFT,
    COV_LP,
    EV_CONTACT_END,
    EV_COVS,
    EV_FIT,
    EV_GAP,
    EV_LIVE,
    EV_NOISE_FREE,
    EV_PARTIAL_ACCEL,
    EV_STUCK,
    EV_TIME_BACK,
    I_A,
    I_C,
    I_CHECK_N,
    I_CONFIRM,
    I_DET_FULL,
    I_IO_SURF,
    I_IO_UP,
    I_JO_CHANGES,
    I_JO_LEARNING,
    I_JO_MT_HIST,
    I_LIVE_N,
    I_METHOD,
    I_MT_BOARD,
    I_MT_LAG,
    I_MT_LANDING,
    I_MULTI_ACCEL,
    I_N_DIFF,
    I_N_RATE,
    I_N_RELEASE,
    I_N_SURF,
    I_N_UP,
    I_NOISE_FREE_REPEATS,
    I_NS,
    I_PO_ALIMIT,
    I_PO_DET_SOS,
    I_PO_DET_ZI,
    I_PO_DIFF_SOS,
    I_PO_GAIN,
    I_PO_LEVER,
    I_PO_LIMIT,
    I_PO_LP_SOS,
    I_PO_LP_ZI,
    I_PO_MAP,
    I_PO_MT_SOS,
    I_PO_MT_ZI,
    I_PO_REST,
    I_SHARED_LP,
    I_SO_COVS,
    I_SO_DELAY,
    I_SO_DET_RING,
    I_SO_DET_ZI,
    I_SO_DIFF_ZI,
    I_SO_GUARD,
    I_SO_LANDING,
    I_SO_LAST_ROW,
    I_SO_LP_ZI,
    I_SO_MT_HIST,
    I_SO_MT_ZI,
    I_SO_PARTIAL_GAIN,
    I_SO_PREV_ROW,
    I_SO_STEP,
    I_SO_SWAY,
    I_SO_SWAY_DIFF,
    I_SO_TRACE,
    I_SO_USED,
    I_SPAN,
    I_STUCK_RUN,
    I_TRACE,
    I_ZEROED,
    J_BLOCKED,
    J_DELAY_POS,
    J_DET_POS,
    J_DIRTY,
    J_EVENT_AT,
    J_FLAGS,
    J_HAVE_LAST_ROW,
    J_HAVE_PREV,
    J_IN_CONTACT,
    J_LIVE,
    J_MT_COUNT,
    J_MT_END_FLAGGED,
    J_MT_FLAGGED,
    J_MT_HAS_SECOND,
    J_MT_LANDING,
    J_MT_NEED,
    J_MT_ON,
    J_MT_POS,
    J_MT_PREV_IN,
    J_MT_ROWS,
    J_MT_STARTED,
    J_N_LEARNING,
    J_PARTIAL,
    J_PARTIAL_PATTERN,
    J_REPEATS,
    J_RESTING,
    J_RESTING_OFF,
    J_RESUME,
    J_SEEN,
    J_SEEN_REPEATS,
    J_STARTED,
    J_STUCK_CHECK,
    J_SWAY_DIFF_POS,
    J_SWAY_POS,
    J_TARED,
    J_TIME_BACK,
    J_ZERO_VERSION,
    METHOD_DIFF,
    METHOD_FORCE,
    METHOD_FUSED,
    METHOD_SWITCHED,
    MT_F,
    MT_FORCE,
    MT_I,
    MT_INSIDE,
    MT_LOCATED,
    MT_SURFACE,
    MT_X,
    MT_Y,
    MT_Z,
    N_OUT_F,
    OUT_B_FLAGS,
    OUT_B_IN_CONTACT,
    OUT_B_LOCATED,
    OUT_B_LOCATED2,
    OUT_B_PHASE,
    OUT_B_RESTING,
    OUT_B_SOURCE,
    OUT_B_TRACED,
    OUT_DRAG_X,
    OUT_DRAG_Y,
    OUT_FORCE,
    OUT_SHEAR,
    OUT_SIGMA,
    OUT_T,
    OUT_X,
    OUT_X2,
    OUT_Y,
    OUT_Y2,
    OUT_Z,
    OUT_Z2,
    P_CONTACT,
    P_DET_DELAY,
    P_DET_FLOOR,
    P_DIFF_INFO_RATIO,
    P_DIFF_SCALE,
    P_HYSTERESIS,
    P_MAX_GAP,
    P_MAX_SIGMA,
    P_MIN_COS,
    P_MT_MAX_FIRST_MOVE,
    P_MT_MIN_NORMAL_SHARE,
    P_MT_MIN_STEP,
    P_MT_MIN_STEP_SHARE,
    P_PHASE_RATE,
    P_RATE_SCALE,
    P_RELEASE_SCALE,
    P_RELEASE_SLOPE,
    P_RELEASE_THRESHOLD,
    P_RING_DECAY,
    P_SHEAR_CAP,
    P_SPEED,
    P_STEP_CHANGE,
    P_SWAY_SCALE,
    P_TOUCH_THRESHOLD,
    P_UNCERTAINTY_CAP,
    P_VAR_CAP,
    RESUME_AGAIN,
    RESUME_BACK,
    RESUME_NEXT,
    S_DET,
    S_DIFF,
    S_EV_LATEST,
    S_EV_T,
    S_LAST_GOOD,
    S_LAST_STUCK_T,
    S_LAST_T,
    S_LP,
    S_MAX_T,
    S_MT_END_STRAY,
    S_MT_FIRST,
    S_MT_MIN_APART,
    S_MT_SECOND,
    S_MT_STRAY,
    S_RAW,
    S_RELEASE,
    S_SLOPE,
    S_STUCK_SINCE,
    S_TARED_Q,
    S_TARED_W,
    S_ZERO,
    S_ZERO_T,
    SURF_DESK_XY,
    SURF_F,
    SURF_I,
    SURF_NORMAL,
    SURF_ORIGIN,
    SURF_U,
    SURF_V,
    TRACE_CANDIDATES,
    TRACE_FORCE,
    TRACE_PER_CANDIDATE,
    TRACE_RATE,
    TRACE_ROWS,
    Candidate,
)
from hapticdesk.estimator.kernel_zero import window_add

# --- small pieces -------------------------------------------------------------------------------


@inlined
def _sections(
    pf: np.ndarray, sos: int, ns: int, sf: np.ndarray, zi: int, src: int, dst: int
) -> None:
    """The six lanes sf[src:src+6] through a cascade of ``ns`` second-order sections
    (pf[sos:]), one lane each, into sf[dst:dst+6] (``src`` may be ``dst``): scipy's
    ``sosfilt`` recursion (transposed direct form II), to the bit. The state sf[zi:] is
    (ns, 2, 6): a section's two memories of the six lanes side by side. Each section reads
    its six inputs and twelve memories before it writes any, so that the six lanes run side
    by side in vector registers (a caller that needs three lanes gets six at the same cost)."""
    for s in range(ns):
        b = pf[sos + 6 * s : sos + 6 * s + 6]
        b0, b1, b2, a1, a2 = b[0], b[1], b[2], b[4], b[5]
        z = sf[zi + 12 * s : zi + 12 * s + 12]
        inp = sf[src : src + 6]
        x0, x1, x2, x3, x4, x5 = inp[0], inp[1], inp[2], inp[3], inp[4], inp[5]
        p0, p1, p2, p3, p4, p5 = z[0], z[1], z[2], z[3], z[4], z[5]
        q0, q1, q2, q3, q4, q5 = z[6], z[7], z[8], z[9], z[10], z[11]
        y0, y1, y2 = b0 * x0 + p0, b0 * x1 + p1, b0 * x2 + p2
        y3, y4, y5 = b0 * x3 + p3, b0 * x4 + p4, b0 * x5 + p5
        z[0], z[1], z[2] = b1 * x0 - a1 * y0 + q0, b1 * x1 - a1 * y1 + q1, b1 * x2 - a1 * y2 + q2
        z[3], z[4], z[5] = b1 * x3 - a1 * y3 + q3, b1 * x4 - a1 * y4 + q4, b1 * x5 - a1 * y5 + q5
        z[6], z[7], z[8] = b2 * x0 - a2 * y0, b2 * x1 - a2 * y1, b2 * x2 - a2 * y2
        z[9], z[10], z[11] = b2 * x3 - a2 * y3, b2 * x4 - a2 * y4, b2 * x5 - a2 * y5
        out = sf[dst : dst + 6]
        out[0], out[1], out[2], out[3], out[4], out[5] = y0, y1, y2, y3, y4, y5
        src = dst


@inlined
def _difference(sf: np.ndarray, src: int, delayed: np.ndarray, scale: float) -> None:
    """Paper eq. (8) for the six lanes: (sf[src:src+6] − the same n samples ago, ``delayed``)
    · ``scale`` into S_DIFF; ``delayed`` takes the sample in its place (read first, then
    written: side by side in vector registers, as :func:`_sections`)."""
    now = sf[src : src + 6]
    x0, x1, x2, x3, x4, x5 = now[0], now[1], now[2], now[3], now[4], now[5]
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
def _information(vu: float, vv: float, cov: float, floor: float) -> tuple[float, float, float]:
    """Σ⁻¹ = [[ia, ib], [ib, ic]] of a candidate's in-plane covariance."""
    product = vu * vv
    det = max(max(product - cov * cov, floor * product), 1e-300)
    weight = 1.0 / det
    return vv * weight, -cov * weight, vu * weight


@inlined
def _fuse(pf: np.ndarray, cf: Candidate, cd: Candidate, cq: Candidate) -> tuple[Candidate, int]:
    """The valid candidates on the surface of the surest one, fused: p = (Σ Σ_i⁻¹)⁻¹ Σ Σ_i⁻¹ p_i
    in closed form (2×2). Returns the fused candidate and how many were fused."""
    cap, floor = pf[P_VAR_CAP], pf[P_DET_FLOOR]
    best = 0
    best_sigma = math.inf
    k = 0
    for c in (cf, cd, cq):
        if c[0] >= 0:
            sigma = math.sqrt(c[3] + c[4])
            if sigma < best_sigma:
                best, best_sigma = k, sigma
        k += 1
    surface = (cf, cd, cq)[best][0]
    if surface < 0:
        return (-1, 0.0, 0.0, cap, cap, 0.0), 0
    a = b = c_ = ru = rv = 0.0
    members = 0
    for c in (cf, cd, cq):
        take = 1.0 if c[0] >= 0 and c[0] == surface else 0.0
        ia, ib, ic = _information(c[3], c[4], c[5], floor)
        ia, ib, ic = ia * take, ib * take, ic * take
        members += int(take)
        a, b, c_ = a + ia, b + ib, c_ + ic
        ru = ru + ia * c[1] + ib * c[2]
        rv = rv + ib * c[1] + ic * c[2]
    inv_det = 1.0 / max(max(a * c_ - b * b, floor * a * c_), 1e-300)
    u = (c_ * ru - b * rv) * inv_det
    v = (a * rv - b * ru) * inv_det
    return (surface, u, v, min(c_ * inv_det, cap), min(a * inv_det, cap), -b * inv_det), members


# --- stage 1: bad samples, the wrench, the resolution -------------------------------------------


@inlined
def _samples(
    t: float, x: np.ndarray, pf: np.ndarray, pi: np.ndarray, sf: np.ndarray, si: np.ndarray
) -> tuple[int, int]:
    """Flags of one input sample (NaN, saturated, time back, stuck, gap) and, for a good one,
    its resultant [F_o; M_o] = M x (paper eqs. 1–4) into S_LAST_GOOD and its channels'
    changes into the resolution steps. Returns (flags, events)."""
    c_n = pi[I_C]
    flags = 0
    events = 0
    # one pass over the channels, without branches: each within its limit (so finite: False
    # for NaN too), equal to the sample before (a repeat, for the stuck check below), kept
    # as the sample before the next (read only while the stuck check runs)
    within = abs(t) < math.inf
    repeat = si[J_HAVE_PREV] == 1
    limit = pf[pi[I_PO_LIMIT] : pi[I_PO_LIMIT] + c_n]
    prev = sf[pi[I_SO_PREV_ROW] : pi[I_SO_PREV_ROW] + c_n]
    for c in range(c_n):
        v = x[c]
        within &= abs(v) < limit[c]
        repeat &= v == prev[c]
        prev[c] = v
    finite, saturated = True, False
    if not within:  # (rare) which of the two
        finite = abs(t) < math.inf
        for c in range(c_n):
            finite &= abs(x[c]) < math.inf
            saturated |= abs(x[c]) >= limit[c]
    if not finite:
        flags |= FLAG_NAN
    else:
        if saturated:
            flags |= FLAG_SATURATED
        if t <= sf[S_MAX_T]:  # not after an earlier finite sample
            flags |= FLAG_TIME_BACK
            si[J_TIME_BACK] += 1
            count = si[J_TIME_BACK]
            mark = 1
            while mark < count:
                mark *= 10
            if mark == count:
                sf[S_EV_T], sf[S_EV_LATEST] = t, sf[S_MAX_T]
                events |= EV_TIME_BACK
        else:
            sf[S_MAX_T] = t
    # a stuck input repeats its last sample bit for bit; a noise-free one does so all the
    # time, so the first CHECK_N samples decide whether to look at all
    check = si[J_STUCK_CHECK]
    if check != 0:
        si[J_HAVE_PREV] = 1
        if check < 0:
            if repeat:
                si[J_SEEN_REPEATS] += 1
            si[J_SEEN] += 1
            if si[J_SEEN_REPEATS] >= pi[I_NOISE_FREE_REPEATS]:
                si[J_STUCK_CHECK] = 0
                events |= EV_NOISE_FREE
            elif si[J_SEEN] >= pi[I_CHECK_N]:
                si[J_STUCK_CHECK] = 1
        else:
            si[J_REPEATS] = si[J_REPEATS] + 1 if repeat and finite else 0
            if si[J_REPEATS] >= pi[I_STUCK_RUN]:
                flags |= FLAG_STUCK
                if si[J_LIVE] >= pi[I_LIVE_N]:
                    sf[S_STUCK_SINCE] = t
                    events |= EV_STUCK
                si[J_LIVE] = 0
                sf[S_LAST_STUCK_T] = t
            elif si[J_LIVE] < pi[I_LIVE_N]:
                si[J_LIVE] += 1
                if si[J_LIVE] == pi[I_LIVE_N]:
                    sf[S_EV_T] = t
                    events |= EV_LIVE
    if flags:
        return flags, events
    if sf[S_LAST_T] > -math.inf and t - sf[S_LAST_T] > pf[P_MAX_GAP]:
        flags |= FLAG_GAP
    sf[S_LAST_T] = t
    _learn_steps(x, pi, sf, si)
    # paper eqs. (1)–(4): [F_o; M_o] = M x, the matrix stored by channel (C, 6), its six
    # sums side by side and each split in two (even and odd channels) so that no long chain
    # of additions waits on itself
    m = pf[pi[I_PO_MAP] : pi[I_PO_MAP] + 6 * c_n]
    f0 = f1 = f2 = m0 = m1 = m2 = 0.0
    g0 = g1 = g2 = n0 = n1 = n2 = 0.0
    for h in range(c_n // 2):
        c = 2 * h
        v, u = x[c], x[c + 1]
        a, b = 6 * c, 6 * c + 6
        f0 += m[a] * v
        f1 += m[a + 1] * v
        f2 += m[a + 2] * v
        m0 += m[a + 3] * v
        m1 += m[a + 4] * v
        m2 += m[a + 5] * v
        g0 += m[b] * u
        g1 += m[b + 1] * u
        g2 += m[b + 2] * u
        n0 += m[b + 3] * u
        n1 += m[b + 4] * u
        n2 += m[b + 5] * u
    if c_n % 2:
        v, a = x[c_n - 1], 6 * (c_n - 1)
        f0 += m[a] * v
        f1 += m[a + 1] * v
        f2 += m[a + 2] * v
        m0 += m[a + 3] * v
        m1 += m[a + 4] * v
        m2 += m[a + 5] * v
    sf[S_LAST_GOOD], sf[S_LAST_GOOD + 1], sf[S_LAST_GOOD + 2] = f0 + g0, f1 + g1, f2 + g2
    sf[S_LAST_GOOD + 3], sf[S_LAST_GOOD + 4], sf[S_LAST_GOOD + 5] = m0 + n0, m1 + n1, m2 + n2
    return flags, events


@inlined
def _learn_steps(x: np.ndarray, pi: np.ndarray, sf: np.ndarray, si: np.ndarray) -> None:
    """Each channel's smallest change between good readings (its resolution step), until
    I_CONFIRM changes confirm it (resolution.py)."""
    if si[J_N_LEARNING] == 0:
        return
    c_n = pi[I_C]
    last = sf[pi[I_SO_LAST_ROW] : pi[I_SO_LAST_ROW] + c_n]
    step = sf[pi[I_SO_STEP] : pi[I_SO_STEP] + c_n]
    changes = si[pi[I_JO_CHANGES] : pi[I_JO_CHANGES] + c_n]
    learning = si[pi[I_JO_LEARNING] : pi[I_JO_LEARNING] + c_n]
    if si[J_HAVE_LAST_ROW]:
        for c in range(c_n):
            if not learning[c]:
                continue
            change = abs(x[c] - last[c])
            if change > 0:
                before = step[c]
                now = min(before, change) if before > 0 else change
                if now != before:
                    step[c] = now
                    si[J_DIRTY] = 1
                changes[c] += 1
                if changes[c] >= pi[I_CONFIRM]:
                    learning[c] = 0
                    si[J_N_LEARNING] -= 1
    for c in range(c_n):
        last[c] = x[c]
    si[J_HAVE_LAST_ROW] = 1


@inlined
def steps_changed(pf: np.ndarray, pi: np.ndarray, sf: np.ndarray, si: np.ndarray) -> bool:
    """Once tared: whether a step is new or shrank by over P_STEP_CHANGE since the
    covariances were made (the steps they use become the current ones)."""
    if not si[J_DIRTY] or not si[J_TARED]:
        return False
    si[J_DIRTY] = 0
    step, used = pi[I_SO_STEP], pi[I_SO_USED]
    changed = False
    for c in range(pi[I_C]):
        if (sf[used + c] == 0 and sf[step + c] > 0) or sf[step + c] < sf[used + c] * (
            1.0 - pf[P_STEP_CHANGE]
        ):
            changed = True
    if changed:
        for c in range(pi[I_C]):
            sf[used + c] = sf[step + c]
    return changed


# --- stage 1b: the accelerometers ---------------------------------------------------------------


@inlined
def _inertial(
    a: np.ndarray,
    gain: np.ndarray,
    pf: np.ndarray,
    pi: np.ndarray,
    sf: np.ndarray,
    g: int,
    usable_only: bool,
) -> None:
    """Takes the desk's inertial wrench G (a − a_rest) off the sample in flight (S_RAW), the
    gain G (6, A) at gain[g:] (inertia.py). ``usable_only``: a reading that is not usable
    counts as at rest (the gain of partial readings has no column for it)."""
    n_a = pi[I_A]
    rest, alimit = pi[I_PO_REST], pi[I_PO_ALIMIT]
    for r in range(6):
        acc = 0.0
        for k in range(n_a):
            reading = a[k]
            if usable_only and not abs(reading) < pf[alimit + k]:
                reading = pf[rest + k]
            acc += gain[g + r * n_a + k] * (reading - pf[rest + k])
        sf[S_RAW + r] -= acc


# --- stage 2: the filter bank -------------------------------------------------------------------


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
    # the fast path (its moments are used where I_DET_FULL, its force always)
    _sections(pf, pi[I_PO_DET_SOS], ns, sf, pi[I_SO_DET_ZI], S_RAW, S_DET)
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
        _sections(pf, pi[I_PO_LP_SOS], ns, sf, pi[I_SO_LP_ZI], S_RAW, S_LP)
        if pi[I_SPAN]:
            _sway(pf, pi, sf, si, S_LP, pi[I_SO_SWAY], J_SWAY_POS)
        _difference(sf, S_LP, delayed, scale)  # paper eq. (8)
    else:
        _difference(sf, S_RAW, delayed, scale)  # paper eq. (8) ...
        _sections(pf, pi[I_PO_DIFF_SOS], ns, sf, pi[I_SO_DIFF_ZI], S_DIFF, S_DIFF)  # ... low-passed
        _sections(pf, pi[I_PO_LP_SOS], ns, sf, pi[I_SO_LP_ZI], S_RAW, S_LP)
        if pi[I_SPAN]:
            _sway(pf, pi, sf, si, S_LP, pi[I_SO_SWAY], J_SWAY_POS)
            _sway(pf, pi, sf, si, S_DIFF, pi[I_SO_SWAY_DIFF], J_SWAY_DIFF_POS)
    si[J_DELAY_POS] = pos + 1 if pos + 1 < n_diff else 0


# --- stage 4: the detector ----------------------------------------------------------------------


@inlined
def detect(
    pf: np.ndarray,
    pi: np.ndarray,
    sf: np.ndarray,
    si: np.ndarray,
    fx: float,
    fy: float,
    fz: float,
    mag: float,
) -> tuple[bool, float]:
    """In contact from the tared fast force (its magnitude ``mag``) with hysteresis; a steep
    fall predicted through the contact force releases early, a contact ended above the
    release level re-arms only below it, and on an upright surface the largest pull along
    its normal lately (the ring guard) is taken off the push (detector.py). Returns
    (in contact, the force's slope along itself over I_N_RATE)."""
    inv = 1.0 / mag if mag > 0 else 0.0
    slope = (fx * sf[S_SLOPE] + fy * sf[S_SLOPE + 1] + fz * sf[S_SLOPE + 2]) * inv
    falling = (fx * sf[S_RELEASE] + fy * sf[S_RELEASE + 1] + fz * sf[S_RELEASE + 2]) * inv
    n_surf = pi[I_N_SURF]
    least = pf[P_MIN_COS] * mag
    pressing = holding = False
    if n_surf:
        top = -math.inf
        for s in range(n_surf):
            at, n = surface_at(pi, s), SURF_NORMAL
            r = pf[at : at + SURF_F]
            top = max(top, r[n] * fx + r[n + 1] * fy + r[n + 2] * fz)
        holding = top >= least
        pressing = holding
        n_up = pi[I_N_UP]
        if n_up:
            guard, decay = pi[I_SO_GUARD], pf[P_RING_DECAY]
            top = -math.inf
            for s in range(n_surf):
                at, n = surface_at(pi, s), SURF_NORMAL
                r = pf[at : at + SURF_F]
                along = r[n] * fx + r[n + 1] * fy + r[n + 2] * fz
                for j in range(n_up):
                    if pi[pi[I_IO_UP] + j] == s:
                        held = sf[guard + j] * decay
                        pull = -along
                        held = pull if pull > held else held
                        sf[guard + j] = held
                        along -= held
                top = max(top, along)
            pressing = top >= least
    threshold, hysteresis, steep = pf[P_CONTACT], pf[P_HYSTERESIS], pf[P_RELEASE_SLOPE]
    through = 0 < steep < -falling and mag + falling * pf[P_DET_DELAY] < threshold
    above = pressing and mag >= threshold and not through
    below = not holding or mag < threshold - hysteresis or through
    low = threshold - hysteresis
    if mag < low:
        si[J_BLOCKED] = 0
    elif si[J_BLOCKED] and mag < threshold + hysteresis:
        above = False
    was = si[J_IN_CONTACT] == 1
    now = above or (was and not below)
    si[J_IN_CONTACT] = 1 if now else 0
    if was and not now and mag >= low:
        si[J_BLOCKED] = 1
    return now, slope


# --- stages 5 and 6: the candidates and the methods ---------------------------------------------


@inlined
def _emit(
    pf: np.ndarray,
    pi: np.ndarray,
    c: Candidate,
    source: int,
    out_f: np.ndarray,
    out_b: np.ndarray,
    out_s: np.ndarray,
    col: int,
) -> None:
    """A chosen candidate into the outputs."""
    x, y, z = to_desk(pf, pi, c[0], c[1], c[2])
    out_f[OUT_X, col], out_f[OUT_Y, col], out_f[OUT_Z, col] = x, y, z
    out_f[OUT_SIGMA, col] = math.sqrt(c[3] + c[4])
    out_b[OUT_B_LOCATED, col] = 1
    out_b[OUT_B_SOURCE, col] = source
    out_s[col] = c[0]


@inlined
def _trace(pf: np.ndarray, pi: np.ndarray, sf: np.ndarray, k: int, c: Candidate) -> None:
    """One candidate of the sample in flight into the trace slots (point 0 where none)."""
    at = pi[I_SO_TRACE] + TRACE_CANDIDATES + TRACE_PER_CANDIDATE * k
    x = y = z = 0.0
    if c[0] >= 0:
        x, y, z = to_desk(pf, pi, c[0], c[1], c[2])
    sf[at], sf[at + 1], sf[at + 2] = x, y, z
    sf[at + 3] = 1.0 if c[0] >= 0 else 0.0
    sf[at + 4] = math.sqrt(c[3] + c[4])


@inlined
def _locate(
    t: float,
    mag: float,
    pf: np.ndarray,
    pi: np.ndarray,
    sf: np.ndarray,
    out_f: np.ndarray,
    out_b: np.ndarray,
    out_s: np.ndarray,
    col: int,
) -> None:
    """The method's point for a good sample in contact: P_er from the tared low-passed
    wrench (S_TARED_W), P_ed from the differentiated one (S_DIFF; its sign from the motion,
    paper Fig. 3 step 2, its variance with the term eq. 11 drops), for ``fused`` one from the
    tared fast wrench (S_TARED_Q); then ``force``, ``diff``, ``switched`` (Fig. 3 with
    F_tth, F_rth) or ``fused`` (the inverse-covariance combination, no threshold)."""
    method, trace = pi[I_METHOD], pi[I_TRACE] == 1
    cap = pf[P_VAR_CAP]
    none = (-1, 0.0, 0.0, cap, cap, 0.0)
    covs = pi[I_SO_COVS]
    age2 = (t - sf[S_ZERO_T]) ** 2
    w = S_TARED_W
    f_mag = math.sqrt(sf[w] * sf[w] + sf[w + 1] * sf[w + 1] + sf[w + 2] * sf[w + 2])
    cf = cd = cq = none
    if trace or method != METHOD_DIFF:
        cf = intersect(
            pf, pi, sf, w, 1.0, sf, covs + 6 * COV_LP, covs + 6 * COV_DRIFT, age2, 0.0, f_mag
        )
    want_d = False
    rate = 0.0
    if trace or method != METHOD_FORCE:
        q = S_TARED_Q
        inv_mag = 1.0 / mag if mag > 0 else 1.0
        rate = (
            sf[q] * sf[S_DIFF] + sf[q + 1] * sf[S_DIFF + 1] + sf[q + 2] * sf[S_DIFF + 2]
        ) * inv_mag
        motion = 1.0 if rate >= 0 else -1.0
        d_mag = math.sqrt(sf[S_DIFF] ** 2 + sf[S_DIFF + 1] ** 2 + sf[S_DIFF + 2] ** 2)
        model = (f_mag * pf[P_SPEED] / max(d_mag, 1e-9)) ** 2  # eq. (11)'s dropped term
        want_d = True
        if method == METHOD_SWITCHED:  # P_ed only at small forces (paper Fig. 3, steps 3–4)
            threshold = pf[P_TOUCH_THRESHOLD] if motion > 0 else pf[P_RELEASE_THRESHOLD]
            want_d = f_mag >= pf[P_CONTACT] and (f_mag <= threshold or cf[0] < 0)
        elif method == METHOD_FUSED:
            # the model term alone (in both variances) makes most of P_ed far less sure than
            # P_er while a press is held: fused would leave those out (P_DIFF_INFO_RATIO)
            want_d = cf[0] < 0 or 2.0 * min(model, cap) <= pf[P_DIFF_INFO_RATIO] * (cf[3] + cf[4])
        if want_d or trace:
            cd = intersect(
                pf, pi, sf, S_DIFF, motion, sf, covs + 6 * COV_DIFF, -1, 0.0, model, d_mag
            )
    if trace or method == METHOD_FUSED:
        cq = intersect(
            pf, pi, sf, S_TARED_Q, 1.0, sf, covs + 6 * COV_DET, covs + 6 * COV_DRIFT, age2, 0.0, mag
        )
    if trace:
        at = pi[I_SO_TRACE]
        sf[at + TRACE_FORCE], sf[at + TRACE_RATE] = f_mag, rate
        _trace(pf, pi, sf, 0, cf)
        _trace(pf, pi, sf, 1, cd)
        _trace(pf, pi, sf, 2, cq)
    max_sigma = pf[P_MAX_SIGMA]
    if method == METHOD_FORCE:
        if cf[0] >= 0 and f_mag >= pf[P_CONTACT]:
            _emit(pf, pi, cf, SOURCE_FORCE, out_f, out_b, out_s, col)
    elif method == METHOD_DIFF:
        if cd[0] >= 0 and math.sqrt(cd[3] + cd[4]) <= max_sigma:
            _emit(pf, pi, cd, SOURCE_DIFF, out_f, out_b, out_s, col)
    elif method == METHOD_SWITCHED:
        if cd[0] >= 0 and want_d:  # step 3
            _emit(pf, pi, cd, SOURCE_DIFF, out_f, out_b, out_s, col)
        elif f_mag >= pf[P_CONTACT] and cf[0] >= 0:  # step 4
            _emit(pf, pi, cf, SOURCE_FORCE, out_f, out_b, out_s, col)
    else:
        var_f = cf[3] + cf[4]
        if cf[0] >= 0:
            # the fast and the low-passed candidates share their noise (one is filtered from
            # the other's input), so they are not fused: the fast one stands in where it is
            # the surer; a differentiated one P_DIFF_INFO_RATIO times less sure than the
            # force's adds under 4 % of the information: it is left out
            if cq[0] >= 0 and not cq[3] + cq[4] < var_f:
                cq = none
            if cd[0] >= 0 and not cd[3] + cd[4] <= pf[P_DIFF_INFO_RATIO] * var_f:
                cd = none
        if cd[0] < 0 and cq[0] < 0:
            # the low-passed force's candidate alone (most samples of a held press): as it is
            if cf[0] >= 0 and var_f <= max_sigma * max_sigma:
                _emit(pf, pi, cf, SOURCE_FORCE, out_f, out_b, out_s, col)
        else:
            fused, members = _fuse(pf, cf, cd, cq)
            if fused[0] >= 0 and math.sqrt(fused[3] + fused[4]) <= max_sigma:
                source = SOURCE_FUSED
                if members == 1:  # one candidate alone: say which
                    source = SOURCE_DIFF if cd[0] >= 0 and cd[0] == fused[0] else SOURCE_FORCE
                _emit(pf, pi, fused, source, out_f, out_b, out_s, col)


# --- stage 7: the second finger -----------------------------------------------------------------


@inlined
def _mt_restart(pf: np.ndarray, pi: np.ndarray, sf: np.ndarray, si: np.ndarray) -> int:
    """The second-finger stage afresh (at a gap, as the filters): its smoothing from the
    sample in flight, no history; the open contact ends. Returns the events."""
    _steady(pf, pi[I_PO_MT_ZI], pi[I_NS], sf, pi[I_SO_MT_ZI], S_RAW)
    si[J_MT_STARTED] = 1
    si[J_MT_COUNT] = 0
    si[J_MT_POS] = 0
    events = _mt_end_contact(sf, si)
    si[J_MT_PREV_IN] = 0
    return events


@inlined
def _mt_end_contact(sf: np.ndarray, si: np.ndarray) -> int:
    """The open contact ended: what it showed goes to Python (EV_CONTACT_END, the desk's
    stray learned there) if anything; the contact's state is cleared."""
    events = 0
    if si[J_MT_FLAGGED] or sf[S_MT_STRAY] > 0:
        si[J_MT_END_FLAGGED] = si[J_MT_FLAGGED]
        sf[S_MT_END_STRAY] = sf[S_MT_STRAY]
        events = EV_CONTACT_END
    sf[S_MT_STRAY] = 0.0
    si[J_MT_FLAGGED] = si[J_MT_LANDING] = si[J_MT_HAS_SECOND] = 0
    return events


@inlined
def _mt_landing(pf: np.ndarray, pi: np.ndarray, sf: np.ndarray, si: np.ndarray) -> float:
    """Whether the change of the smoothed wrench over the lag before the sample in flight is
    a single force on the board, rising and pressing down, while the first finger was in
    contact, located and still over the lag before that: how far from the first finger it
    lies (its line of action met with the board, paper eqs. 1–2), or −1 where it is no
    such change (multitouch.py)."""
    lag = pi[I_MT_LAG]
    size = 2 * lag + 1
    if si[J_MT_COUNT] < size or pi[I_MT_BOARD] < 0:
        return -1.0
    hist, ints = pi[I_SO_MT_HIST], pi[I_JO_MT_HIST]
    now = si[J_MT_POS]
    before = now - lag if now >= lag else now - lag + size
    earlier = now + 1 if now + 1 < size else 0
    fn, ib, ie = hist + MT_F * now, ints + MT_I * before, ints + MT_I * earlier
    fb, fe = hist + MT_F * before, hist + MT_F * earlier
    moved = math.hypot(sf[fb + MT_X] - sf[fe + MT_X], sf[fb + MT_Y] - sf[fe + MT_Y])
    if not (
        si[ib + MT_INSIDE]
        and si[ib + MT_LOCATED]
        and si[ie + MT_LOCATED]
        and si[ib + MT_SURFACE] == 0  # the first finger on the board, as the second
        and si[ie + MT_SURFACE] == 0
        and moved <= pf[P_MT_MAX_FIRST_MOVE]
        and si[ints + MT_I * now + MT_INSIDE]
        and sf[fn + MT_FORCE] - sf[fb + MT_FORCE] >= pf[P_MT_MIN_STEP]
    ):
        return -1.0
    dfx, dfy, dfz = sf[fn] - sf[fb], sf[fn + 1] - sf[fb + 1], sf[fn + 2] - sf[fb + 2]
    dmx, dmy, dmz = sf[fn + 3] - sf[fb + 3], sf[fn + 4] - sf[fb + 4], sf[fn + 5] - sf[fb + 5]
    step = math.sqrt(dfx * dfx + dfy * dfy + dfz * dfz)
    at = surface_at(pi, pi[I_MT_BOARD])
    board = pf[at : at + SURF_F]
    o, n = SURF_ORIGIN, SURF_NORMAL
    ox, oy, oz = board[o], board[o + 1], board[o + 2]
    nx, ny, nz = board[n], board[n + 1], board[n + 2]
    # the point P with ΔM = P × ΔF on the board's plane
    f2 = dfx * dfx + dfy * dfy + dfz * dfz
    ok = f2 > 0
    safe_f2 = f2 if ok else 1.0
    footx = (dfy * dmz - dfz * dmy) / safe_f2
    footy = (dfz * dmx - dfx * dmz) / safe_f2
    footz = (dfx * dmy - dfy * dmx) / safe_f2
    across = dfx * nx + dfy * ny + dfz * nz
    ok = ok and abs(across) > 1e-3 * math.sqrt(safe_f2)
    lam = ((ox - footx) * nx + (oy - footy) * ny + (oz - footz) * nz) / (across if ok else 1.0)
    px, py, pz = footx + lam * dfx, footy + lam * dfy, footz + lam * dfz
    ax, ay, az = px - sf[fb + MT_X], py - sf[fb + MT_Y], pz - sf[fb + MT_Z]
    apart = math.sqrt(ax * ax + ay * ay + az * az)
    rx, ry, rz = px - ox, py - oy, pz - oz
    ua, va = SURF_U, SURF_V
    on_board = contains(
        pf,
        pi,
        pi[I_MT_BOARD],
        rx * board[ua] + ry * board[ua + 1] + rz * board[ua + 2],
        rx * board[va] + ry * board[va + 1] + rz * board[va + 2],
    )
    pressing = abs(dfx * nx + dfy * ny + dfz * nz) >= pf[P_MT_MIN_NORMAL_SHARE] * step
    if ok and step >= pf[P_MT_MIN_STEP_SHARE] * sf[fb + MT_FORCE] and pressing and on_board:
        return apart
    return -1.0


@inlined
def _second_finger(
    pf: np.ndarray,
    pi: np.ndarray,
    sf: np.ndarray,
    si: np.ndarray,
    flags: int,
    out_f: np.ndarray,
    out_b: np.ndarray,
    out_s: np.ndarray,
    col: int,
) -> int:
    """A second finger that lands while the first holds: flagged FLAG_MULTI from its landing
    to the contact's end, placed once its fit window is over (multitouch.py). Returns the
    events (the fit and a contact's end are Python's)."""
    events = 0
    if flags & FLAG_GAP or not si[J_MT_STARTED]:
        events |= _mt_restart(pf, pi, sf, si)
    ns = pi[I_NS]
    lag = pi[I_MT_LAG]
    size = 2 * lag + 1
    pos = si[J_MT_POS] + 1 if si[J_MT_COUNT] else 0
    if pos >= size:
        pos = 0
    si[J_MT_POS] = pos
    hist, ints = pi[I_SO_MT_HIST] + MT_F * pos, pi[I_JO_MT_HIST] + MT_I * pos
    _sections(pf, pi[I_PO_MT_SOS], ns, sf, pi[I_SO_MT_ZI], S_RAW, hist)
    inside = out_b[OUT_B_IN_CONTACT, col] == 1
    sf[hist + MT_X], sf[hist + MT_Y], sf[hist + MT_Z] = (
        out_f[OUT_X, col],
        out_f[OUT_Y, col],
        out_f[OUT_Z, col],
    )
    sf[hist + MT_FORCE] = out_f[OUT_FORCE, col]
    si[ints + MT_LOCATED] = out_b[OUT_B_LOCATED, col]
    si[ints + MT_SURFACE] = out_s[col]
    si[ints + MT_INSIDE] = 1 if inside else 0
    si[J_MT_COUNT] = min(si[J_MT_COUNT] + 1, size)
    apart = _mt_landing(pf, pi, sf, si)
    if not inside:
        if si[J_MT_PREV_IN]:
            events |= _mt_end_contact(sf, si)
        si[J_MT_PREV_IN] = 0
        return events
    si[J_MT_PREV_IN] = 1
    if not si[J_MT_FLAGGED]:
        if apart < 0 or apart < sf[S_MT_MIN_APART]:
            sf[S_MT_STRAY] = max(sf[S_MT_STRAY], max(apart, 0.0))
            return events
        # landed: its fit window holds the smoothed wrench from 2·lag before to I_MT_LANDING
        # after; the first finger's point is where it was a lag before
        si[J_MT_FLAGGED] = 1
        out_b[OUT_B_FLAGS, col] |= FLAG_MULTI
        before = pos - lag if pos >= lag else pos - lag + size
        fb = pi[I_SO_MT_HIST] + MT_F * before
        sf[S_MT_FIRST], sf[S_MT_FIRST + 1], sf[S_MT_FIRST + 2] = (
            sf[fb + MT_X],
            sf[fb + MT_Y],
            sf[fb + MT_Z],
        )
        rows = si[J_MT_COUNT]
        landing = pi[I_SO_LANDING]
        for j in range(rows):
            at = pos - rows + 1 + j
            if at < 0:
                at += size
            for lane in range(6):
                sf[landing + 6 * j + lane] = sf[pi[I_SO_MT_HIST] + MT_F * at + lane]
        si[J_MT_ROWS] = rows
        si[J_MT_LANDING] = 1
        si[J_MT_NEED] = pi[I_MT_LANDING]
        return events
    out_b[OUT_B_FLAGS, col] |= FLAG_MULTI
    if si[J_MT_LANDING]:
        landing = pi[I_SO_LANDING] + 6 * si[J_MT_ROWS]
        for lane in range(6):
            sf[landing + lane] = sf[hist + lane]
        si[J_MT_ROWS] += 1
        si[J_MT_NEED] -= 1
        if si[J_MT_NEED] == 0:
            si[J_MT_LANDING] = 0
            events |= EV_FIT  # its point is known at this sample
    elif si[J_MT_HAS_SECOND]:
        out_f[OUT_X2, col], out_f[OUT_Y2, col], out_f[OUT_Z2, col] = (
            sf[S_MT_SECOND],
            sf[S_MT_SECOND + 1],
            sf[S_MT_SECOND + 2],
        )
        out_b[OUT_B_LOCATED2, col] = 1
    return events


# --- one sample ---------------------------------------------------------------------------------


@inlined
def _front(
    t: float,
    x: np.ndarray,
    a: np.ndarray,
    given: bool,
    pf: np.ndarray,
    pi: np.ndarray,
    sf: np.ndarray,
    si: np.ndarray,
) -> int:
    """The first half of a sample: its flags and wrench (stages 1, 1b), the filters
    (stage 2) and the zero's window (stage 3). Leaves the sample in flight in S_RAW, S_LP,
    S_DET, S_DIFF, S_SLOPE, S_RELEASE and J_FLAGS; returns its events."""
    n_a = pi[I_A]
    accel = 0  # 0: no inertial wrench; 1: from all readings; 2: from the usable ones
    no_accel = n_a > 0 and not given
    if n_a > 0 and given:
        pattern = 0  # which readings are usable (finite, inside the range), one bit each
        alimit = pi[I_PO_ALIMIT]
        for j in range(n_a):
            if abs(a[j]) < pf[alimit + j]:
                pattern |= 1 << j
        if pattern == (1 << n_a) - 1:
            accel = 1
        elif not pi[I_MULTI_ACCEL]:
            no_accel = True  # one accelerometer: uncompensated, flagged
        elif si[J_PARTIAL_PATTERN] != pattern + 1:
            return EV_PARTIAL_ACCEL  # its gain from Python (before anything moves on)
        elif si[J_PARTIAL] == 1:
            accel = 2  # from the usable readings (a board lost for good costs nothing more)
        else:
            no_accel = True
    flags, events = _samples(t, x, pf, pi, sf, si)
    first_good = False
    zeroed = pi[I_ZEROED] == 1
    if flags == 0 or flags == FLAG_GAP:
        first_good = si[J_STARTED] == 0
        si[J_STARTED] = 1
        if zeroed and not si[J_TARED]:
            # readings that come zeroed: the zero is 0 from here on (never tared, no drift, no
            # object); the covariances from the profile's noise (zero.py), before this sample
            # is located
            for r in range(6):
                sf[S_ZERO + r] = 0.0
            sf[S_ZERO_T] = t
            si[J_TARED] = 1
            si[J_ZERO_VERSION] += 1
            si[J_DIRTY] = 1
            steps_changed(pf, pi, sf, si)  # (the steps the covariances use)
            events |= EV_COVS
        elif steps_changed(pf, pi, sf, si):
            events |= EV_COVS
    started = si[J_STARTED] == 1
    for r in range(6):
        sf[S_RAW + r] = sf[S_LAST_GOOD + r] if started else 0.0
    if accel == 1:
        _inertial(a, pf, pf, pi, sf, pi[I_PO_GAIN], False)
    elif accel == 2:
        _inertial(a, sf, pf, pi, sf, pi[I_SO_PARTIAL_GAIN], True)
    if no_accel:
        flags |= FLAG_NO_ACCEL
    if started:
        if first_good:
            _restart_filters(pf, pi, sf, si)
        elif flags & FLAG_GAP:
            _restart_filters(pf, pi, sf, si)
            sf[S_EV_T] = t
            events |= EV_GAP
        _filters(pf, pi, sf, si)
    else:
        for r in range(6):
            sf[S_LP + r] = sf[S_DET + r] = sf[S_DIFF + r] = 0.0
    si[J_FLAGS] = flags
    if zeroed:
        return events
    return events | window_add(t, flags, first_good, pf, pi, sf, si)


@inlined
def _back(
    t: float,
    pf: np.ndarray,
    pi: np.ndarray,
    sf: np.ndarray,
    si: np.ndarray,
    out_f: np.ndarray,
    out_b: np.ndarray,
    out_s: np.ndarray,
    col: int,
) -> int:
    """The second half of a sample: contact and position from the filtered wrenches less the
    zero (stages 4–6), the outputs, the second finger (stage 7). Returns its events."""
    flags = si[J_FLAGS]
    out_f[OUT_T, col] = t
    for row in range(OUT_X, N_OUT_F):
        out_f[row, col] = 0.0
    out_f[OUT_SIGMA, col] = pf[P_UNCERTAINTY_CAP]
    out_b[OUT_B_LOCATED, col] = out_b[OUT_B_LOCATED2, col] = 0
    out_b[OUT_B_SOURCE, col] = out_b[OUT_B_PHASE, col] = out_b[OUT_B_TRACED, col] = 0
    out_s[col] = -1
    inside = False
    if si[J_TARED]:
        det_full = pi[I_DET_FULL] == 1
        for r in range(6):
            sf[S_TARED_W + r] = sf[S_LP + r] - sf[S_ZERO + r]
            sf[S_TARED_Q + r] = sf[S_DET + r] - sf[S_ZERO + r] if det_full or r < 3 else 0.0
        fx, fy, fz = sf[S_TARED_Q], sf[S_TARED_Q + 1], sf[S_TARED_Q + 2]
        mag = math.sqrt(fx * fx + fy * fy + fz * fz)
        inside, slope = detect(pf, pi, sf, si, fx, fy, fz, mag)
        out_f[OUT_FORCE, col] = mag
        if inside and flags & BAD_SAMPLE == 0:
            # the phase from the fast path's slope, which does not wait for the 166 ms window
            rate = pf[P_PHASE_RATE]
            out_b[OUT_B_PHASE, col] = (
                PHASE_TOUCH if slope > rate else PHASE_RELEASE if slope < -rate else PHASE_HOLD
            )
            _locate(t, mag, pf, pi, sf, out_f, out_b, out_s, col)
            if pi[I_TRACE]:
                out_b[OUT_B_TRACED, col] = 1
                at = pi[I_SO_TRACE]
                for row in range(TRACE_ROWS):
                    out_f[N_OUT_F + row, col] = sf[at + row]
            if out_b[OUT_B_LOCATED, col]:
                # the shear from the fast force and the surface's normal; the finger's drag
                # along a horizontal board (F is the desk's reaction: the force along it)
                s = out_s[col]
                at, n = surface_at(pi, s), SURF_NORMAL
                surf = pf[at : at + SURF_F]
                into = fx * surf[n] + fy * surf[n + 1] + fz * surf[n + 2]
                out_f[OUT_SHEAR, col] = shear_of(into, mag, pf[P_SHEAR_CAP])
                if pi[pi[I_IO_SURF] + s * SURF_I + SURF_DESK_XY]:
                    out_f[OUT_DRAG_X, col] = into * surf[n] - fx
                    out_f[OUT_DRAG_Y, col] = into * surf[n + 1] - fy
    else:
        flags |= FLAG_NOT_TARED
    out_b[OUT_B_IN_CONTACT, col] = 1 if inside else 0
    out_b[OUT_B_RESTING, col] = 1 if inside and si[J_RESTING] else 0
    out_b[OUT_B_FLAGS, col] = flags  # (int8 holds the uint8 bits: read as uint8)
    if si[J_MT_ON] and si[J_STARTED]:
        return _second_finger(pf, pi, sf, si, flags, out_f, out_b, out_s, col)
    return 0


@inlined
def _sample(
    t: float,
    x: np.ndarray,
    a: np.ndarray,
    given: bool,
    pf: np.ndarray,
    pi: np.ndarray,
    sf: np.ndarray,
    si: np.ndarray,
    out_f: np.ndarray,
    out_b: np.ndarray,
    out_s: np.ndarray,
    col: int,
) -> int:
    """One sample through every stage, from where si[J_RESUME] says; returns the events it
    raised (0: none)."""
    resume = si[J_RESUME]
    si[J_RESUME] = RESUME_NEXT
    events = 0
    if resume != RESUME_BACK:
        events = _front(t, x, a, given, pf, pi, sf, si)
        if events & EV_PARTIAL_ACCEL:
            si[J_RESUME] = RESUME_AGAIN
            return events
        if events & EV_COVS:  # the sample's own candidates use them: after Python made them
            si[J_RESUME] = RESUME_BACK
            return events
    events |= _back(t, pf, pi, sf, si, out_f, out_b, out_s, col)
    if si[J_RESTING_OFF]:
        si[J_RESTING_OFF] = si[J_RESTING] = 0
    return events


# --- the two entries ----------------------------------------------------------------------------


@compiled
def run_block(
    t: np.ndarray,
    x: np.ndarray,
    accel: np.ndarray,
    given: bool,
    pf: np.ndarray,
    pi: np.ndarray,
    sf: np.ndarray,
    si: np.ndarray,
    out_f: np.ndarray,
    out_b: np.ndarray,
    out_s: np.ndarray,
    start: int,
    stop: int,
) -> int:
    """Samples ``start`` to ``stop`` of a push (``t`` (k,), ``x`` (k, C), ``accel`` (k, A),
    used if ``given``) into the output columns of the same index; stops at the first
    sample that raises an event, its index in si[J_EVENT_AT]. Returns the events (0: the
    push is done). Releases the GIL."""
    for i in range(start, stop):
        a = accel[i if given else 0]
        events = _sample(t[i], x[i], a, given, pf, pi, sf, si, out_f, out_b, out_s, i)
        if events:
            si[J_EVENT_AT] = i
            return events
    return 0


@compiled
def run_step(
    t: float,
    x: np.ndarray,
    accel: np.ndarray,
    given: bool,
    pf: np.ndarray,
    pi: np.ndarray,
    sf: np.ndarray,
    si: np.ndarray,
    out_f: np.ndarray,
    out_b: np.ndarray,
    out_s: np.ndarray,
) -> int:
    """One sample (``x`` (1, C), ``accel`` (A,), used if ``given``) into the one-sample
    record's columns; returns its events, as :func:`run_block` (si[J_EVENT_AT] 0)."""
    events = _sample(t, x[0], accel, given, pf, pi, sf, si, out_f, out_b, out_s, 0)
    si[J_EVENT_AT] = 0
    return events


@compiled
def intersect_block(
    pf: np.ndarray,
    pi: np.ndarray,
    wrench: np.ndarray,
    sign: np.ndarray,
    covs: np.ndarray,
    cov_at: int,
    drift_at: int,
    age2: np.ndarray,
    extra_var: np.ndarray,
    norm: np.ndarray,
    out: np.ndarray,
) -> None:
    """:func:`intersect` for the wrenches (n, 6) one by one, into ``out`` (n, 6): surface,
    u, v, var_u, var_v, cov_uv (for intersection.intersect, the same code the kernel runs)."""
    for i in range(wrench.shape[0]):
        c = intersect(
            pf, pi, wrench[i], 0, sign[i], covs, cov_at, drift_at, age2[i], extra_var[i], norm[i]
        )
        out[i, 0], out[i, 1], out[i, 2], out[i, 3], out[i, 4], out[i, 5] = c


# --- compiled once --------------------------------------------------------------------------

#: how long the first compile took on the machine of docs/performance.md (a cached load:
#: well under a second); said once on stderr while it runs
FIRST_COMPILE_S = 30
log = logging.getLogger("hapticdesk.estimator")
_warm = False


def _signatures() -> list[tuple[Any, tuple[Any, ...]]]:
    """The entries and the argument types the estimator calls them with (C-contiguous
    float64 inputs, the state and output arrays as params.py and the estimator make them)."""
    f1, f2 = types.float64[::1], types.float64[:, ::1]
    i1 = types.int64[::1]
    state = (f1, i1, f1, i1)
    outputs = (f2, types.int8[:, ::1], types.int16[::1])
    flag, index = types.boolean, types.int64
    return [
        (run_block, (f1, f2, f2, flag, *state, *outputs, index, index)),
        (run_step, (types.float64, f2, f1, flag, *state, *outputs)),
        (steps_changed, state),
        (contains, (f1, i1, index, types.float64, types.float64)),
    ]


class _FirstCompile(event.Listener):
    """Says once on stderr that the kernels are being compiled (numba raises a compile event
    only on a cache miss)."""

    told = False

    def on_start(self, event: event.Event) -> None:
        if not _FirstCompile.told:
            _FirstCompile.told = True
            print(
                f"hapticdesk: compiling the estimator's kernels, once: ~{FIRST_COMPILE_S} s",
                file=sys.stderr,
                flush=True,
            )

    def on_end(self, event: event.Event) -> None:
        pass


def warm() -> None:
    """Compile the entries for the estimator's argument types, or load them from numba's
    cache (beside this file, or the user's cache directory where this folder cannot be
    written: numba's own choice); once per process."""
    global _warm
    if _warm:
        return
    start = time.perf_counter()
    with event.install_listener("numba:compile", _FirstCompile()), vectorized():
        for dispatcher, signature in _signatures():
            dispatcher.compile(signature)
    _warm = True
    log.debug("the estimator's kernels ready in %.2f s", time.perf_counter() - start)
