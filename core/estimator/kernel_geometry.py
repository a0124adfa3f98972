"""The surfaces' geometry, compiled: where a wrench's line of action meets them, and how sure.

The kernel's side of :mod:`hapticdesk.estimator.geometry` (the same formulas on arrays):
:func:`intersect` finds the point of a wrench on the surfaces, in a surface's frame
u = −M'y / F'z, v = M'x / F'z (paper eqs. 5, 6, 12), with its covariance through the
Jacobian of those formulas plus the model error (eq. 11); :func:`contains` says whether a
point lies on a surface's outline, :func:`to_desk` where it is on the desk, and
:func:`shear_of` how much a finger drags for how hard it presses. A surface's record is at
:func:`surface_at` in the parameters (``SURF_*`` in :mod:`.kernel_slots`).
"""

from __future__ import annotations

import math

import numpy as np

from hapticdesk.estimator.kernel_compile import inlined, inlined_entry
from hapticdesk.estimator.kernel_slots import (
    I_IO_SURF,
    I_N_SURF,
    I_PO_SURF,
    P_EDGE_TOLERANCE,
    P_MIN_COS,
    P_VAR_CAP,
    SURF_BOUNDS,
    SURF_DESK_XY,
    SURF_F,
    SURF_I,
    SURF_N_POLY,
    SURF_ORIGIN,
    SURF_POLY,
    SURF_RECT,
    SURF_U,
    SURF_V,
    Candidate,
)


@inlined
def shear_of(into: float, magnitude: float, cap: float, inv_cap: float) -> float:
    """|F_t| / |F_n| of a force whose component along a surface's unit normal is ``into``
    and whose magnitude is ``magnitude``: how much a finger drags along the surface for how
    hard it presses into it, at most ``cap`` (``inv_cap`` its reciprocal, made once per desk;
    finite where F_n is 0)."""
    along = magnitude * magnitude
    along -= into * into
    along = math.sqrt(max(along, 0.0))
    pressed = max(abs(into), along * inv_cap + 1e-300)
    return min(along / pressed, cap)


@inlined
def surface_at(pi: np.ndarray, s: int) -> int:
    """Where surface ``s``'s record is in the parameters (SURF_F floats: SURF_ROWS,
    SURF_ORIGIN…; read through a view, ``pf[at : at + SURF_F]``)."""
    return pi[I_PO_SURF] + s * SURF_F


@inlined_entry
def contains(pf: np.ndarray, pi: np.ndarray, s: int, u: float, v: float) -> bool:
    """Whether (u, v) lies on surface ``s``: inside its outline or on it (edges and corners
    within P_EDGE_TOLERANCE); a crossing-number test for a polygon."""
    at = surface_at(pi, s)
    r = pf[at : at + SURF_F]
    b = SURF_BOUNDS
    tol = pf[P_EDGE_TOLERANCE]
    if not (r[b] - tol <= u <= r[b + 2] + tol and r[b + 1] - tol <= v <= r[b + 3] + tol):
        return False
    ints = pi[I_IO_SURF] + s * SURF_I
    if pi[ints + SURF_RECT]:
        return True
    poly, n = pi[ints + SURF_POLY], pi[ints + SURF_N_POLY]
    crossings = 0
    on_edge = False
    for k in range(n):
        au, av = pf[poly + 2 * k], pf[poly + 2 * k + 1]
        kb = k + 1 if k + 1 < n else 0
        bu, bv = pf[poly + 2 * kb], pf[poly + 2 * kb + 1]
        if (av > v) != (bv > v):
            cross_u = au + (v - av) * (bu - au) / (1.0 if bv == av else bv - av)
            if u < cross_u:
                crossings += 1
        eu, ev = bu - au, bv - av
        length2 = max(eu * eu + ev * ev, 1e-300)
        t = ((u - au) * eu + (v - av) * ev) / length2
        t = min(max(t, 0.0), 1.0)
        du, dv = u - (au + t * eu), v - (av + t * ev)
        if du * du + dv * dv <= tol * tol:
            on_edge = True
    return crossings % 2 == 1 or on_edge


@inlined
def surface_force(
    r: np.ndarray, fx: float, fy: float, fz: float, mx: float, my: float, mz: float
) -> float:
    """F'z: the wrench's force into the surface whose record is ``r`` (its first row; the
    denominator of eq. 5). The one sum :func:`intersect` and the rounding floor both make, so
    that the floor's 1/F'z equals a candidate's to the bit (kernel_rounding.rounding_floor)."""
    return r[0] * fx + r[1] * fy + r[2] * fz + r[3] * mx + r[4] * my + r[5] * mz


@inlined
def to_desk(
    pf: np.ndarray, pi: np.ndarray, s: int, u: float, v: float
) -> tuple[float, float, float]:
    """The desk point of (u, v) on surface ``s`` (about its origin)."""
    at = surface_at(pi, s)
    r = pf[at : at + SURF_F]
    o, ua, va = SURF_ORIGIN, SURF_U, SURF_V
    if pi[pi[I_IO_SURF] + s * SURF_I + SURF_DESK_XY]:  # a horizontal board: u, v are x, y
        return u + r[o], v + r[o + 1], r[o + 2]
    return (
        r[o] + r[ua] * u + r[va] * v,
        r[o + 1] + r[ua + 1] * u + r[va + 1] * v,
        r[o + 2] + r[ua + 2] * u + r[va + 2] * v,
    )


@inlined
def intersect(
    pf: np.ndarray,
    pi: np.ndarray,
    w: np.ndarray,
    wo: int,
    sign: float,
    covs: np.ndarray,
    cov_at: int,
    drift_at: int,
    age2: float,
    extra_var: float,
    norm: float,
) -> Candidate:
    """Where the line of action of the wrench w[wo:wo+6] = [F; M] meets the surfaces (paper
    eqs. 5, 6, 12): in a surface's frame (rows of F'z, M'x, M'y), u = −M'y / F'z,
    v = M'x / F'z. ``sign`` +1 where F points like the supports' force F_o, −1 where it points
    the other way (a releasing differentiated force); only a force pressing into a surface
    by at least P_MIN_COS of ``norm`` (|F|) counts, inside its outline. Where surfaces
    overlap, the one the finger reaches first along its push wins.

    The point's covariance: the packed covariance of (F'z, M'x, M'y) of surface s at
    covs[cov_at + 24·s] (``cov_at`` < 0: none, variances 0), plus the zero's drift at
    ``drift_at`` times ``age2`` (``drift_at`` < 0: none), carried through the Jacobian of the
    formulas, plus ``extra_var`` on both axes (the model error of eq. 11); capped at
    P_VAR_CAP. Returns (surface or −1, u, v, var_u, var_v, cov_uv, 1/F'z or 0)."""
    fx, fy, fz_, mx, my, mz = w[wo], w[wo + 1], w[wo + 2], w[wo + 3], w[wo + 4], w[wo + 5]
    cap = pf[P_VAR_CAP]
    best = (-1, 0.0, 0.0, cap, cap, 0.0, 0.0)
    best_key = -math.inf
    n_surf = pi[I_N_SURF]
    for s in range(n_surf):
        at = surface_at(pi, s)
        r = pf[at : at + SURF_F]
        fz = surface_force(r, fx, fy, fz_, mx, my, mz)
        if not fz * sign > pf[P_MIN_COS] * norm:
            continue
        lx = r[6] * fx + r[7] * fy + r[8] * fz_ + r[9] * mx + r[10] * my + r[11] * mz
        ly = r[12] * fx + r[13] * fy + r[14] * fz_ + r[15] * mx + r[16] * my + r[17] * mz
        inv = 1.0 / fz  # (one division for the point and its covariance)
        u = -(ly * inv)  # paper eq. (5) in the surface's frame
        v = lx * inv
        if not contains(pf, pi, s, u, v):
            continue
        if n_surf > 1:
            px, py, pz = to_desk(pf, pi, s, u, v)
            key = (px * fx + py * fy + pz * fz_) * sign / (norm if norm > 0 else 1.0)
            if not key > best_key:
                continue
            best_key = key
        if cov_at < 0:
            var_u = var_v = cov = 0.0
        else:
            var_u, var_v, cov = _point_covariance(
                covs, cov_at + 24 * s, drift_at, s, age2, u, v, inv, extra_var, cap
            )
        best = (s, u, v, var_u, var_v, cov, inv)
        if n_surf == 1:
            break
    return best


@inlined
def _point_covariance(
    covs: np.ndarray,
    c: int,
    drift_at: int,
    s: int,
    age2: float,
    u: float,
    v: float,
    inv_fz: float,
    extra_var: float,
    cap: float,
) -> tuple[float, float, float]:
    """(var_u, var_v, cov_uv) of the point (u, v) of surface ``s`` where 1 / F'z = ``inv_fz``: the
    packed covariance of (F'z, M'x, M'y) at covs[c], plus the zero's drift at ``drift_at``
    (< 0: none) times ``age2``, through the Jacobian of eq. (5), plus ``extra_var`` on both
    axes (eq. 11); capped at ``cap`` (see :func:`intersect`)."""
    cz, czx, czy, cx, cxy, cy = (
        covs[c],
        covs[c + 1],
        covs[c + 2],
        covs[c + 3],
        covs[c + 4],
        covs[c + 5],
    )
    if drift_at >= 0:
        d = drift_at + 24 * s
        cz += covs[d] * age2
        czx += covs[d + 1] * age2
        czy += covs[d + 2] * age2
        cx += covs[d + 3] * age2
        cxy += covs[d + 4] * age2
        cy += covs[d + 5] * age2
    inv2 = inv_fz * inv_fz
    # du = −(u dF'z + dM'y)/F'z, dv = −(v dF'z − dM'x)/F'z
    var_u = min((u * u * cz + 2 * u * czy + cy) * inv2 + extra_var, cap)
    var_v = min((v * v * cz - 2 * v * czx + cx) * inv2 + extra_var, cap)
    cov = min(max((u * v * cz - u * czx + v * czy - cxy) * inv2, -cap), cap)
    return var_u, var_v, cov
