"""Where the line of action of a force meets the desk's surfaces (paper eqs. 5, 6, 12).

From the equilibrium r × F_o = M_o (METHOD.md), the contact lies on the line
r(s) = (F_o × M_o)/|F_o|² + s·F_o. Each surface is a plane with an outline; in the surface's
own frame (axes u, v, normal n, origin c) the wrench moved to c is F' = Rᵀ F,
M' = Rᵀ (M − c × F), and the plane z' = 0 is met at

    u = −M'_y / F'_z ,   v = M'_x / F'_z                      (paper eq. 5 with h = 0)

The same formula holds for the differentiated wrench (Ḟ_o, Ṁ_o), paper eq. (12). Noise in
the wrench with covariance Σ is carried to (u, v) through the Jacobian of these formulas.
The formulas run per sample in :mod:`hapticdesk.estimator.kernel_geometry` (``intersect``); here
each surface is prepared for them (:class:`SurfaceFrame`), and :func:`intersect` runs that
same code over many wrenches for those who need it outside the estimator (the paper's error
model, the tests). Nothing returned is NaN or infinite.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

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
        bounds = (float(u0), float(v0), float(u1), float(v1))
        return cls(surface, t, poly, bounds, bool(rect), surface.is_desk_xy)

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


VAR_CAP = 1e2  # m², stands for "unknown" so the arrays stay finite


@dataclass
class Intersection:
    """Where wrenches meet the desk, per wrench ((n,) arrays)."""

    valid: np.ndarray  # bool: pressing into a surface, inside its outline, not too oblique
    surface: np.ndarray  # int16 index, -1 where not valid
    uv: np.ndarray  # (2, n) in the chosen surface's plane, about its origin; 0 where not valid
    var_uu: np.ndarray  # in-plane variances (m²), finite; VAR_CAP where not valid
    var_vv: np.ndarray
    cov_uv: np.ndarray

    def sigma(self) -> np.ndarray:
        """1-σ radial uncertainty: the square root of the covariance's trace."""
        return np.sqrt(self.var_uu + self.var_vv)

    def points(self, frames: list[SurfaceFrame]) -> np.ndarray:
        """Desk-frame points (3, n); 0 where not valid."""
        out = np.zeros((3, len(self.surface)))
        for index, frame in enumerate(frames):
            on = self.surface == index
            if on.any():
                out[:, on] = frame.to_desk(self.uv[0, on], self.uv[1, on])
        return out


def pack_cov(c: np.ndarray) -> tuple[float, float, float, float, float, float]:
    """The six entries of a (3, 3) covariance of (F'z, M'x, M'y) as the kernel reads them:
    (zz, zx, zy, xx, xy, yy)."""
    return (
        float(c[0, 0]),
        float(c[0, 1]),
        float(c[0, 2]),
        float(c[1, 1]),
        float(c[1, 2]),
        float(c[2, 2]),
    )
