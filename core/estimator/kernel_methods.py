"""The point of a sample in contact, compiled: its candidates and the method's choice.

Stages 5 and 6 of the kernel (:mod:`hapticdesk.estimator.kernel`), the per-sample side of
:mod:`hapticdesk.estimator.candidates` and :mod:`hapticdesk.estimator.methods`:
:func:`_locate` makes P_er from the tared low-passed wrench, P_ed from the differentiated one
(its sign from the motion, paper Fig. 3 step 2; its variance with the term eq. 11 drops) and,
for ``fused``, a candidate from the fast wrench, each with its covariance
(:func:`~hapticdesk.estimator.kernel_geometry.intersect`, eqs. 5, 11, 12); then ``force``,
``diff``, ``switched`` (Fig. 3, with F_tth and F_rth) or ``fused`` (:func:`_fuse`, the
inverse-covariance combination) picks the point, and :func:`_emit` writes it out.
"""

from __future__ import annotations

import math

import numpy as np

from hapticdesk.estimator.contacts import (
    SOURCE_DIFF,
    SOURCE_FORCE,
    SOURCE_FUSED,
)
from hapticdesk.estimator.kernel_compile import inlined
from hapticdesk.estimator.kernel_geometry import intersect, to_desk
from hapticdesk.estimator.kernel_rounding import rounding_floor
from hapticdesk.estimator.kernel_slots import (
    C_COV_UV,
    C_INV_FZ,
    C_SURFACE,
    C_U,
    C_V,
    C_VAR_U,
    C_VAR_V,
    COV_DET,
    COV_DIFF,
    COV_DRIFT,
    COV_LP,
    I_METHOD,
    I_N_SURF,
    I_SO_COVS,
    I_SO_TRACE,
    I_TRACE,
    METHOD_DIFF,
    METHOD_FORCE,
    METHOD_FUSED,
    METHOD_SWITCHED,
    OUT_B_LOCATED,
    OUT_B_SOURCE,
    OUT_SIGMA,
    OUT_X,
    OUT_Y,
    OUT_Z,
    P_CONTACT,
    P_DET_FLOOR,
    P_DIFF_INFO_RATIO,
    P_MAX_SIGMA,
    P_RELEASE_THRESHOLD,
    P_SPEED,
    P_TOUCH_THRESHOLD,
    P_VAR_CAP,
    S_DIFF,
    S_TARED_Q,
    S_TARED_W,
    S_ZERO_T,
    TRACE_CANDIDATES,
    TRACE_FORCE,
    TRACE_PER_CANDIDATE,
    TRACE_RATE,
    Candidate,
)


@inlined
def _information(vu: float, vv: float, cov: float, floor: float) -> tuple[float, float, float]:
    """Σ⁻¹ = [[ia, ib], [ib, ic]] of a candidate's in-plane covariance."""
    product = vu * vv
    det = max(max(product - cov * cov, floor * product), 1e-300)
    weight = 1.0 / det
    return vv * weight, -cov * weight, vu * weight


@inlined
def _inv_fz_on(c: Candidate, s: int) -> float:
    """1/F'z of candidate ``c``'s wrench on surface ``s`` where ``c`` was made on it (its
    C_INV_FZ), else 0 (not known: the rounding floor makes it)."""
    return c[C_INV_FZ] if c[C_SURFACE] == s else 0.0


@inlined
def _fusion_surface(pi: np.ndarray, cf: Candidate, cd: Candidate, cq: Candidate) -> int:
    """The surface the candidates are fused on: the surest valid one's (−1: none valid). On
    a desk of one surface every valid candidate is on it: no ranking needed."""
    if pi[I_N_SURF] == 1:
        valid = cf[C_SURFACE] >= 0 or cd[C_SURFACE] >= 0 or cq[C_SURFACE] >= 0
        return 0 if valid else -1
    best = 0
    best_sigma = math.inf
    k = 0
    for c in (cf, cd, cq):
        if c[C_SURFACE] >= 0:
            sigma = math.sqrt(c[C_VAR_U] + c[C_VAR_V])
            if sigma < best_sigma:
                best, best_sigma = k, sigma
        k += 1
    return (cf, cd, cq)[best][C_SURFACE]


@inlined
def _fuse(
    pf: np.ndarray, pi: np.ndarray, cf: Candidate, cd: Candidate, cq: Candidate
) -> tuple[Candidate, int]:
    """The valid candidates on the surface of the surest one, fused: p = (Σ Σ_i⁻¹)⁻¹ Σ Σ_i⁻¹ p_i
    in closed form (2×2). Returns the fused candidate and how many were fused."""
    cap, floor = pf[P_VAR_CAP], pf[P_DET_FLOOR]
    surface = _fusion_surface(pi, cf, cd, cq)
    if surface < 0:
        return (-1, 0.0, 0.0, cap, cap, 0.0, 0.0), 0
    a = b = c_ = ru = rv = 0.0
    members = 0
    for c in (cf, cd, cq):
        # (a candidate left out would add zeros: skipped, the same sums)
        if c[C_SURFACE] == surface:
            ia, ib, ic = _information(c[C_VAR_U], c[C_VAR_V], c[C_COV_UV], floor)
            members += 1
            a, b, c_ = a + ia, b + ib, c_ + ic
            ru = ru + ia * c[C_U] + ib * c[C_V]
            rv = rv + ib * c[C_U] + ic * c[C_V]
    inv_det = 1.0 / max(max(a * c_ - b * b, floor * a * c_), 1e-300)
    u = (c_ * ru - b * rv) * inv_det
    v = (a * rv - b * ru) * inv_det
    var_u, var_v = min(c_ * inv_det, cap), min(a * inv_det, cap)
    return (surface, u, v, var_u, var_v, -b * inv_det, 0.0), members


@inlined
def _emit(
    pf: np.ndarray,
    pi: np.ndarray,
    sf: np.ndarray,
    c: Candidate,
    source: int,
    inv_fz: float,
    out_f: np.ndarray,
    out_b: np.ndarray,
    out_s: np.ndarray,
    col: int,
) -> None:
    """A chosen candidate into the outputs; its 1-σ with the zero's rounding offset
    (:func:`rounding_floor`, at the force of the tared wrench the method locates with: the
    fast one for ``fused``; ``inv_fz`` that wrench's 1/F'z on the candidate's surface where
    a candidate made from it has it, else 0), which the choice and the weights leave out
    (every candidate shares it)."""
    x, y, z = to_desk(pf, pi, c[C_SURFACE], c[C_U], c[C_V])
    out_f[OUT_X, col], out_f[OUT_Y, col], out_f[OUT_Z, col] = x, y, z
    w = S_TARED_Q if pi[I_METHOD] == METHOD_FUSED else S_TARED_W
    floor = rounding_floor(pf, pi, sf, w, c[C_SURFACE], c[C_U], c[C_V], inv_fz)
    out_f[OUT_SIGMA, col] = math.sqrt(c[C_VAR_U] + c[C_VAR_V] + floor)
    out_b[OUT_B_LOCATED, col] = 1
    out_b[OUT_B_SOURCE, col] = source
    out_s[col] = c[C_SURFACE]


@inlined
def _trace(pf: np.ndarray, pi: np.ndarray, sf: np.ndarray, k: int, c: Candidate) -> None:
    """One candidate of the sample in flight into the trace slots (point 0 where none)."""
    at = pi[I_SO_TRACE] + TRACE_CANDIDATES + TRACE_PER_CANDIDATE * k
    x = y = z = 0.0
    if c[C_SURFACE] >= 0:
        x, y, z = to_desk(pf, pi, c[C_SURFACE], c[C_U], c[C_V])
    sf[at], sf[at + 1], sf[at + 2] = x, y, z
    sf[at + 3] = 1.0 if c[C_SURFACE] >= 0 else 0.0
    sf[at + 4] = math.sqrt(c[C_VAR_U] + c[C_VAR_V])


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
    none = (-1, 0.0, 0.0, cap, cap, 0.0, 0.0)
    covs = pi[I_SO_COVS]
    age2 = (t - sf[S_ZERO_T]) ** 2
    w = S_TARED_W
    f_mag = math.sqrt(sf[w] * sf[w] + sf[w + 1] * sf[w + 1] + sf[w + 2] * sf[w + 2])
    cf = cd = cq = none
    if trace or method != METHOD_DIFF:
        cf = intersect(
            pf, pi, sf, w, 1.0, sf, covs + 6 * COV_LP, covs + 6 * COV_DRIFT, age2, 0.0, f_mag
        )
    if trace or method == METHOD_FUSED:
        # (next to P_er's, which it does not wait for: the two run side by side)
        cq = intersect(
            pf, pi, sf, S_TARED_Q, 1.0, sf, covs + 6 * COV_DET, covs + 6 * COV_DRIFT, age2, 0.0, mag
        )
    want_d = False
    rate = 0.0
    if trace or method != METHOD_FORCE:
        cd, want_d, rate = _diff_candidate(mag, f_mag, cf, pf, pi, sf)
    if trace:
        at = pi[I_SO_TRACE]
        sf[at + TRACE_FORCE], sf[at + TRACE_RATE] = f_mag, rate
        _trace(pf, pi, sf, 0, cf)
        _trace(pf, pi, sf, 1, cd)
        _trace(pf, pi, sf, 2, cq)
    _choose(pf, pi, sf, cf, cd, cq, f_mag, want_d, out_f, out_b, out_s, col)


@inlined
def _diff_candidate(
    mag: float, f_mag: float, cf: Candidate, pf: np.ndarray, pi: np.ndarray, sf: np.ndarray
) -> tuple[Candidate, bool, float]:
    """P_ed from the differentiated wrench (S_DIFF), made where the method wants it or the
    trace shows it (none otherwise); ``mag`` and ``f_mag`` the fast and the low-passed
    force's magnitudes, ``cf`` P_er. Returns (P_ed, whether the method wants it, the rate
    of the force along the fast force)."""
    method, trace = pi[I_METHOD], pi[I_TRACE] == 1
    cap = pf[P_VAR_CAP]
    cd = (-1, 0.0, 0.0, cap, cap, 0.0, 0.0)
    q = S_TARED_Q
    inv_mag = 1.0 / mag if mag > 0 else 1.0
    rate = (sf[q] * sf[S_DIFF] + sf[q + 1] * sf[S_DIFF + 1] + sf[q + 2] * sf[S_DIFF + 2]) * inv_mag
    motion = 1.0 if rate >= 0 else -1.0
    d_mag = math.sqrt(sf[S_DIFF] ** 2 + sf[S_DIFF + 1] ** 2 + sf[S_DIFF + 2] ** 2)
    model = (f_mag * pf[P_SPEED] / max(d_mag, 1e-9)) ** 2  # eq. (11)'s dropped term
    want_d = True
    if method == METHOD_SWITCHED:  # P_ed only at small forces (paper Fig. 3, steps 3–4)
        threshold = pf[P_TOUCH_THRESHOLD] if motion > 0 else pf[P_RELEASE_THRESHOLD]
        want_d = f_mag >= pf[P_CONTACT] and (f_mag <= threshold or cf[C_SURFACE] < 0)
    elif method == METHOD_FUSED:
        # the model term alone (in both variances) makes most of P_ed far less sure than
        # P_er while a press is held: fused would leave those out (P_DIFF_INFO_RATIO)
        want_d = cf[C_SURFACE] < 0 or 2.0 * min(model, cap) <= pf[P_DIFF_INFO_RATIO] * (
            cf[C_VAR_U] + cf[C_VAR_V]
        )
    if want_d or trace:
        covs = pi[I_SO_COVS]
        cd = intersect(pf, pi, sf, S_DIFF, motion, sf, covs + 6 * COV_DIFF, -1, 0.0, model, d_mag)
    return cd, want_d, rate


@inlined
def _choose(
    pf: np.ndarray,
    pi: np.ndarray,
    sf: np.ndarray,
    cf: Candidate,
    cd: Candidate,
    cq: Candidate,
    f_mag: float,
    want_d: bool,
    out_f: np.ndarray,
    out_b: np.ndarray,
    out_s: np.ndarray,
    col: int,
) -> None:
    """The method's point from the candidates (P_er ``cf``, P_ed ``cd``, the fast ``cq``;
    ``f_mag`` the low-passed force's magnitude, ``want_d`` whether the method wants P_ed)
    into the outputs, if any is sure enough."""
    method = pi[I_METHOD]
    max_sigma = pf[P_MAX_SIGMA]
    if method == METHOD_FORCE:
        if cf[C_SURFACE] >= 0 and f_mag >= pf[P_CONTACT]:
            _emit(pf, pi, sf, cf, SOURCE_FORCE, cf[C_INV_FZ], out_f, out_b, out_s, col)
    elif method == METHOD_DIFF:
        # (the floor is at the low-passed wrench's force: P_er's where it was made)
        if cd[C_SURFACE] >= 0 and math.sqrt(cd[C_VAR_U] + cd[C_VAR_V]) <= max_sigma:
            inv_fz = _inv_fz_on(cf, cd[C_SURFACE])
            _emit(pf, pi, sf, cd, SOURCE_DIFF, inv_fz, out_f, out_b, out_s, col)
    elif method == METHOD_SWITCHED:
        if cd[C_SURFACE] >= 0 and want_d:  # step 3
            inv_fz = _inv_fz_on(cf, cd[C_SURFACE])
            _emit(pf, pi, sf, cd, SOURCE_DIFF, inv_fz, out_f, out_b, out_s, col)
        elif f_mag >= pf[P_CONTACT] and cf[C_SURFACE] >= 0:  # step 4
            _emit(pf, pi, sf, cf, SOURCE_FORCE, cf[C_INV_FZ], out_f, out_b, out_s, col)
    else:
        _choose_fused(pf, pi, sf, cf, cd, cq, out_f, out_b, out_s, col)


@inlined
def _choose_fused(
    pf: np.ndarray,
    pi: np.ndarray,
    sf: np.ndarray,
    cf: Candidate,
    cd: Candidate,
    cq: Candidate,
    out_f: np.ndarray,
    out_b: np.ndarray,
    out_s: np.ndarray,
    col: int,
) -> None:
    """``fused``'s point: the candidates that add information, combined (:func:`_fuse`)."""
    cap = pf[P_VAR_CAP]
    none = (-1, 0.0, 0.0, cap, cap, 0.0, 0.0)
    max_sigma = pf[P_MAX_SIGMA]
    var_f = cf[C_VAR_U] + cf[C_VAR_V]
    fast = cq  # (the floor is at the fast wrench's force: its 1/F'z kept)
    if cf[C_SURFACE] >= 0:
        # the fast and the low-passed candidates share their noise (one is filtered from
        # the other's input), so they are not fused: the fast one stands in where it is
        # the surer; a differentiated one P_DIFF_INFO_RATIO times less sure than the
        # force's adds under 4 % of the information: it is left out
        if cq[C_SURFACE] >= 0 and not cq[C_VAR_U] + cq[C_VAR_V] < var_f:
            cq = none
        if cd[C_SURFACE] >= 0 and not cd[C_VAR_U] + cd[C_VAR_V] <= pf[P_DIFF_INFO_RATIO] * var_f:
            cd = none
    if cd[C_SURFACE] < 0 and cq[C_SURFACE] < 0:
        # the low-passed force's candidate alone (most samples of a held press): as it is
        if cf[C_SURFACE] >= 0 and var_f <= max_sigma * max_sigma:
            inv_fz = _inv_fz_on(fast, cf[C_SURFACE])
            _emit(pf, pi, sf, cf, SOURCE_FORCE, inv_fz, out_f, out_b, out_s, col)
    else:
        fused, members = _fuse(pf, pi, cf, cd, cq)
        if fused[C_SURFACE] >= 0 and math.sqrt(fused[C_VAR_U] + fused[C_VAR_V]) <= max_sigma:
            source = SOURCE_FUSED
            if members == 1:  # one candidate alone: say which
                source = (
                    SOURCE_DIFF
                    if cd[C_SURFACE] >= 0 and cd[C_SURFACE] == fused[C_SURFACE]
                    else SOURCE_FORCE
                )
            inv_fz = _inv_fz_on(fast, fused[C_SURFACE])
            _emit(pf, pi, sf, fused, source, inv_fz, out_f, out_b, out_s, col)
