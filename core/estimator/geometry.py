"""Where the line of action of a force meets the desk's surfaces (paper eqs. 5, 6, 12).

From the equilibrium r × F_o = M_o (METHOD.md), the contact lies on the line
r(s) = (F_o × M_o)/|F_o|² + s·F_o. Each surface is a plane with an outline; in the surface's
own frame (axes u, v, normal n, origin c) the wrench moved to c is F' = Rᵀ F,
M' = Rᵀ (M − c × F), and the plane z' = 0 is met at

    u = −M'_y / F'_z ,   v = M'_x / F'_z                      (paper eq. 5 with h = 0)

The same formula holds for the differentiated wrench (Ḟ_o, Ṁ_o), paper eq. (12). Noise in
the wrench with covariance Σ is carried to (u, v) through the Jacobian of these formulas.
All functions work on channels-first arrays (3, k) and never return NaN or infinity.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from hapticdesk.estimator.contacts import SHEAR_CAP
from hapticdesk.files.profile import Surface

EDGE_TOLERANCE_M = 1e-9  # a point this close to an outline counts as inside


@dataclass(frozen=True)
class SurfaceFrame:
    """A surface prepared for fast intersection: its 6×6 wrench transform and its outline."""

    surface: Surface
    transform: np.ndarray  # (6, 6): [F'; M'] = T [F; M]
    polygon: np.ndarray  # (N, 2) outline in (u − offset_u, v − offset_v), i.e. about the origin
    bounds: tuple[float, float, float, float]  # u0, v0, u1, v1 of the outline
    is_rectangle: bool
    rows: tuple[tuple[float, ...], ...]  # transform rows of F'z, M'x, M'y as plain floats
    desk_xy: bool  # a horizontal board whose (u, v) are the desk's (x, y)

    @classmethod
    def of(cls, surface: Surface) -> SurfaceFrame:
        rot = np.stack([surface.u_axis, surface.v_axis, surface.normal], axis=1)  # columns
        c = surface.origin
        cx = np.array([[0, -c[2], c[1]], [c[2], 0, -c[0]], [-c[1], c[0], 0]])
        t = np.zeros((6, 6))
        t[:3, :3] = rot.T
        t[3:, 3:] = rot.T
        t[3:, :3] = -rot.T @ cx
        poly = surface.polygon - surface.offset_uv
        u0, v0 = poly.min(axis=0)
        u1, v1 = poly.max(axis=0)
        rect = (
            len(poly) == 4
            and all(np.isclose(p[0], u0) or np.isclose(p[0], u1) for p in poly)
            and all(np.isclose(p[1], v0) or np.isclose(p[1], v1) for p in poly)
        )
        rows = tuple(tuple(float(x) for x in row) for row in t[2:5])
        bounds = (float(u0), float(v0), float(u1), float(v1))
        return cls(surface, t, poly, bounds, bool(rect), rows, surface.is_desk_xy)

    def contains_one(self, u: float, v: float) -> bool:
        """:meth:`contains` for one point."""
        u0, v0, u1, v1 = self.bounds
        tol = EDGE_TOLERANCE_M
        if not (u0 - tol <= u <= u1 + tol and v0 - tol <= v <= v1 + tol):
            return False
        return self.is_rectangle or bool(
            _in_polygon(self.polygon, np.array([u]), np.array([v]), tol)[0]
        )

    def project_cov(self, wrench_cov: np.ndarray) -> np.ndarray:
        """The (3, 3) covariance of (F'z, M'x, M'y) for a (6, 6) covariance of [F; M]."""
        rows = self.transform[2:5]
        return rows @ wrench_cov @ rows.T

    def to_desk(self, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Local (u, v) about the origin -> desk points (3, k)."""
        s = self.surface
        if self.desk_xy:  # a horizontal board: (u, v) are x, y about the origin
            out = np.empty((3, len(u)))
            np.add(u, s.origin[0], out=out[0])
            np.add(v, s.origin[1], out=out[1])
            out[2] = s.origin[2]
            return out
        return s.origin[:, None] + s.u_axis[:, None] * u + s.v_axis[:, None] * v

    def contains(self, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Inside or on the outline (edges and corners count, within EDGE_TOLERANCE_M)."""
        u0, v0, u1, v1 = self.bounds
        tol = EDGE_TOLERANCE_M
        inside = (u >= u0 - tol) & (u <= u1 + tol) & (v >= v0 - tol) & (v <= v1 + tol)
        if self.is_rectangle or not inside.any():
            return inside
        return inside & _in_polygon(self.polygon, u, v, tol)


def _in_polygon(poly: np.ndarray, u: np.ndarray, v: np.ndarray, tol: float) -> np.ndarray:
    """Crossing-number test, vectorised over points; points on an edge count as inside."""
    a = poly
    b = np.roll(poly, -1, axis=0)
    pu, pv = u[None, :], v[None, :]
    au, av, bu, bv = a[:, 0:1], a[:, 1:2], b[:, 0:1], b[:, 1:2]
    straddles = (av > pv) != (bv > pv)
    with np.errstate(divide="ignore", invalid="ignore"):
        cross_u = au + (pv - av) * (bu - au) / np.where(bv == av, 1.0, bv - av)
    inside = (np.count_nonzero(straddles & (pu < cross_u), axis=0) % 2) == 1
    # distance to each edge, so the outline itself belongs to the surface
    eu, ev = bu - au, bv - av
    length2 = np.maximum(eu * eu + ev * ev, 1e-300)
    s = np.clip(((pu - au) * eu + (pv - av) * ev) / length2, 0.0, 1.0)
    du, dv = pu - (au + s * eu), pv - (av + s * ev)
    on_edge = np.any(du * du + dv * dv <= tol * tol, axis=0)
    return inside | on_edge


@dataclass
class Intersection:
    """Where one candidate wrench meets the desk, per sample ((n,) arrays)."""

    valid: np.ndarray  # bool: pressing into a surface, inside its outline, not too oblique
    surface: np.ndarray  # int16 index, -1 where not valid
    uv: np.ndarray  # (2, n) in the chosen surface's plane, about its origin; 0 where not valid
    var_uu: np.ndarray  # in-plane variances (m²), finite; VAR_CAP where not valid
    var_vv: np.ndarray
    cov_uv: np.ndarray

    def sigma(self) -> np.ndarray:
        """1-σ radial uncertainty: the square root of the covariance's trace."""
        return np.sqrt(self.var_uu + self.var_vv)

    def points(self, frames: list[SurfaceFrame], at: np.ndarray | None = None) -> np.ndarray:
        """Desk-frame points (3, n), or for the samples ``at`` (indices, or a boolean mask);
        0 where not valid."""
        if at is not None and at.dtype == bool:
            at = np.flatnonzero(at)
        surface = self.surface if at is None else self.surface[at]
        # np.take, not uv[:, at]: 2-D fancy indexing is several times slower
        uv = self.uv if at is None else np.take(self.uv, at, axis=1)
        out = np.zeros((3, len(surface)))
        for index, frame in enumerate(frames):
            if len(frames) == 1:
                on = surface == 0
                if on.all():  # the common case: no per-sample selection
                    return frame.to_desk(uv[0], uv[1])
            else:
                on = surface == index
            if on.any():
                out[:, on] = frame.to_desk(uv[0, on], uv[1, on])
        return out

    def take(self, index: np.ndarray) -> Intersection:
        """The samples at ``index`` (an integer array) as a candidate of their own."""
        return Intersection(
            self.valid[index],
            self.surface[index],
            np.take(self.uv, index, axis=1),
            self.var_uu[index],
            self.var_vv[index],
            self.cov_uv[index],
        )


VAR_CAP = 1e2  # m², stands for "unknown" so the arrays stay finite

Candidate = tuple[int, float, float, float, float, float]  # surface, u, v, var_u, var_v, cov
NO_CANDIDATE: Candidate = (-1, 0.0, 0.0, VAR_CAP, VAR_CAP, 0.0)
PackedCov = tuple[float, float, float, float, float, float]  # zz, zx, zy, xx, xy, yy


def with_drift(c: PackedCov, d: PackedCov, scale: Any) -> tuple[Any, ...]:
    """The covariance ``c`` of (F'z, M'x, M'y) plus the zero's drift ``d`` times ``scale``
    (its age², (n,) or one float); packed as by :func:`pack_cov`."""
    return (
        c[0] + d[0] * scale,
        c[1] + d[1] * scale,
        c[2] + d[2] * scale,
        c[3] + d[3] * scale,
        c[4] + d[4] * scale,
        c[5] + d[5] * scale,
    )


def propagate(u: Any, v: Any, c: tuple[Any, ...], inv2: Any, extra_var: Any) -> tuple[Any, ...]:
    """(var_u, var_v, cov_uv) of the point (u, v) for the covariance ``c`` of (F'z, M'x, M'y)
    (packed) and 1/F'z² ``inv2``, before capping; arrays or plain floats. From
    du = −(u dF'z + dM'y)/F'z, dv = −(v dF'z − dM'x)/F'z."""
    cz, czx, czy, cx, cxy, cy = c
    var_u = (u * u * cz + 2 * u * czy + cy) * inv2 + extra_var
    var_v = (v * v * cz - 2 * v * czx + cx) * inv2 + extra_var
    cov = (u * v * cz - u * czx + v * czy - cxy) * inv2
    return var_u, var_v, cov


def intersect(
    frames: list[SurfaceFrame],
    wrench: np.ndarray,
    direction_sign: np.ndarray | float,
    covs: list[np.ndarray] | None,
    min_normal_cos: float,
    extra_var: np.ndarray | float = 0.0,
    drift_covs: list[np.ndarray] | None = None,
    drift_scale: np.ndarray | float = 0.0,
    force_norm: np.ndarray | None = None,
) -> Intersection:
    """Intersect the lines of action of ``wrench`` (6, n) = [F; M] with every surface.

    ``direction_sign`` (n,) or scalar: +1 where F points like the supports' force F_o (the
    finger pushes along −F_o), −1 where it points the other way (a releasing differentiated
    force). ``covs``: per surface, :meth:`SurfaceFrame.project_cov` of the wrench's noise
    covariance (None: no uncertainty). ``extra_var`` (n,) is added to both in-plane variances
    (a model error). ``force_norm`` (n,): |F| when the caller has it. ``drift_covs`` (like
    ``covs``) times ``drift_scale`` (n,) is added to
    the wrench covariance: the zero's uncertainty, growing with its age. Where surfaces
    overlap, the one the finger reaches first along its push wins. :func:`intersect_one` is
    the same for one sample, on plain floats.
    """
    n = wrench.shape[1]
    force = wrench[:3]
    norm = np.sqrt(np.einsum("ik,ik->k", force, force)) if force_norm is None else force_norm
    best: Intersection | None = None
    best_key = np.full(n if len(frames) > 1 else 0, -np.inf)  # (one surface: not needed)
    for index, frame in enumerate(frames):
        cov = None
        if covs is not None:
            cov = pack_cov(covs[index])
            if drift_covs is not None:  # with the zero's drift, each entry is (n,)
                cov = with_drift(cov, pack_cov(drift_covs[index]), drift_scale)
        ok, surface, uv, inv2 = _on_surface(
            frame, index, wrench, direction_sign, norm, min_normal_cos
        )
        if cov is None:
            var_u = np.where(ok, 0.0, VAR_CAP)
            here = Intersection(ok, surface, uv, var_u, var_u.copy(), np.zeros(n))
        else:
            var_u, var_v, cov_uv = propagate(uv[0], uv[1], cov, inv2, extra_var)
            here = _capped(ok, surface, uv, var_u, var_v, cov_uv)
        if len(frames) == 1:
            return here
        point = frame.to_desk(here.uv[0], here.uv[1])
        key = np.einsum("ik,ik->k", point, force) * direction_sign / np.where(norm > 0, norm, 1)
        take = here.valid & (key > best_key)
        best_key = np.where(take, key, best_key)
        if best is None:
            best = here
            continue
        best.valid |= take
        best.surface[take] = index
        best.uv[:, take] = here.uv[:, take]
        best.var_uu[take] = here.var_uu[take]
        best.var_vv[take] = here.var_vv[take]
        best.cov_uv[take] = here.cov_uv[take]
    if best is None:
        z = np.zeros(n)
        return Intersection(
            np.zeros(n, bool), np.full(n, -1, np.int16), np.zeros((2, n)), z + VAR_CAP,
            z + VAR_CAP, z,
        )  # fmt: skip
    return best


def _on_surface(
    frame: SurfaceFrame,
    index: int,
    wrench: np.ndarray,
    direction_sign: np.ndarray | float,
    norm: np.ndarray,
    min_cos: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Where the lines of action meet one surface: valid, surface index, (u, v) (2, n) and
    1/F'z² for :func:`propagate`."""
    n = wrench.shape[1]
    local = frame.transform[2:5] @ wrench  # F'z, M'x, M'y
    fz = local[0]
    ok = fz * direction_sign > min_cos * norm  # pressing into this surface
    all_press = bool(ok.all())
    safe_fz = fz if all_press else np.where(ok, fz, 1.0)
    uv = np.empty((2, n))
    u, v = uv
    np.divide(local[2], safe_fz, out=u)  # paper eq. (5) in the surface's frame
    np.negative(u, out=u)
    np.divide(local[1], safe_fz, out=v)
    ok &= frame.contains(u, v)
    everywhere = all_press and bool(ok.all())  # the usual case: no masks needed below
    if not everywhere:
        not_ok = ~ok
        u[not_ok] = 0.0  # (not needed, but no stray numbers where there is no point)
        v[not_ok] = 0.0
    surface = (
        np.full(n, index, np.int16) if everywhere else np.where(ok, index, -1).astype(np.int16)
    )
    return ok, surface, uv, 1.0 / (safe_fz * safe_fz)


def _capped(
    ok: np.ndarray,
    surface: np.ndarray,
    uv: np.ndarray,
    var_u: np.ndarray,
    var_v: np.ndarray,
    cov: np.ndarray,
) -> Intersection:
    """The candidate with its variances capped, and cleared where there is no point."""
    if bool(ok.all()):
        np.minimum(var_u, VAR_CAP, out=var_u)
        np.minimum(var_v, VAR_CAP, out=var_v)
        np.clip(cov, -VAR_CAP, VAR_CAP, out=cov)
    else:
        var_u = np.where(ok, np.minimum(var_u, VAR_CAP), VAR_CAP)
        var_v = np.where(ok, np.minimum(var_v, VAR_CAP), VAR_CAP)
        cov = np.where(ok, np.clip(cov, -VAR_CAP, VAR_CAP), 0.0)
    return Intersection(ok, surface, uv, var_u, var_v, cov)


def intersect_one(
    frames: list[SurfaceFrame],
    wrench: list[float],
    direction_sign: float,
    covs: list[PackedCov] | None,
    min_normal_cos: float,
    extra_var: float = 0.0,
    drift_covs: list[PackedCov] | None = None,
    drift_scale: float = 0.0,
) -> Candidate:
    """:func:`intersect` for one sample on plain floats, where numpy's per-call cost would
    dominate (a single-sample push); covariances come packed (:func:`pack_cov`). Returns
    (surface or −1, u, v, var_u, var_v, cov_uv); the covariance by the same
    :func:`with_drift` and :func:`propagate`."""
    fx, fy, fz_, mx, my, mz = wrench
    norm = math.sqrt(fx * fx + fy * fy + fz_ * fz_)
    best = NO_CANDIDATE
    best_key = -math.inf
    for index, frame in enumerate(frames):
        r = frame.rows
        fz = (
            r[0][0] * fx + r[0][1] * fy + r[0][2] * fz_ + r[0][3] * mx + r[0][4] * my + r[0][5] * mz
        )
        if not fz * direction_sign > min_normal_cos * norm:
            continue
        lx = (
            r[1][0] * fx + r[1][1] * fy + r[1][2] * fz_ + r[1][3] * mx + r[1][4] * my + r[1][5] * mz
        )
        ly = (
            r[2][0] * fx + r[2][1] * fy + r[2][2] * fz_ + r[2][3] * mx + r[2][4] * my + r[2][5] * mz
        )
        u = -ly / fz  # paper eq. (5) in the surface's frame
        v = lx / fz
        if not frame.contains_one(u, v):
            continue
        if len(frames) > 1:
            s = frame.surface
            px = s.origin[0] + s.u_axis[0] * u + s.v_axis[0] * v
            py = s.origin[1] + s.u_axis[1] * u + s.v_axis[1] * v
            pz = s.origin[2] + s.u_axis[2] * u + s.v_axis[2] * v
            key = (px * fx + py * fy + pz * fz_) * direction_sign / (norm if norm > 0 else 1.0)
            if not key > best_key:
                continue
            best_key = key
        if covs is not None:
            c: tuple[Any, ...] = covs[index]
            if drift_covs is not None:
                c = with_drift(covs[index], drift_covs[index], drift_scale)
            var_u, var_v, cov = propagate(u, v, c, 1.0 / (fz * fz), extra_var)
            var_u = min(var_u, VAR_CAP)
            var_v = min(var_v, VAR_CAP)
            cov = min(max(cov, -VAR_CAP), VAR_CAP)
        else:
            var_u = var_v = cov = 0.0
        best = (index, u, v, float(var_u), float(var_v), float(cov))
        if len(frames) == 1:
            break
    return best


def pack_cov(c: np.ndarray) -> tuple[float, float, float, float, float, float]:
    """The six entries of a (3, 3) covariance of (F'z, M'x, M'y) as plain floats, for
    :func:`intersect_one`: (zz, zx, zy, xx, xy, yy)."""
    return (
        float(c[0, 0]),
        float(c[0, 1]),
        float(c[0, 2]),
        float(c[1, 1]),
        float(c[1, 2]),
        float(c[2, 2]),
    )


def shear_ratio(into: np.ndarray, magnitude: np.ndarray) -> np.ndarray:
    """|F_t| / |F_n| of forces whose component along the surface's unit normal is ``into``
    and whose magnitude is ``magnitude`` (arrays alike): how much a finger drags along the
    surface for how hard it presses into it, at most :data:`SHEAR_CAP` (finite where F_n is
    0). In place of temporaries where it can: it runs on every located sample."""
    along = np.multiply(magnitude, magnitude)
    along -= into * into
    np.maximum(along, 0.0, out=along)
    np.sqrt(along, out=along)
    pressed = np.abs(into)
    np.maximum(pressed, along * (1.0 / SHEAR_CAP) + 1e-300, out=pressed)
    along /= pressed
    return np.minimum(along, SHEAR_CAP, out=along)


def shear_ratio_one(into: float, magnitude: float) -> float:
    """:func:`shear_ratio` for one force, in plain floats."""
    along = math.sqrt(max(magnitude * magnitude - into * into, 0.0))
    return min(along / max(abs(into), along / SHEAR_CAP + 1e-300), SHEAR_CAP)
