"""Layout regions: rectangles, circles and polygons on a desk surface, and slider axes.

Coordinates are the surface's local (u, v) in metres; for a horizontal surface without
``u_axis`` (the usual top board) that is the desk's (x, y). ``contains`` and ``value_along``
take arrays, so a whole trace is judged at once.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Overlap is judged on a grid of this many cells per side over the shared bounding box.
_OVERLAP_GRID = 240


@dataclass(frozen=True)
class Region:
    """A named area on one surface; optionally a slider with an axis.

    ``kind`` is ``rect``, ``circle`` or ``polygon``; ``outline`` is the closed boundary as
    (N, 2) points (for a circle, a fine polygon used for drawing and overlap checks only;
    ``contains`` is exact). ``axis`` is a slider's start and end point, (2, 2), or None.
    """

    name: str
    kind: str
    surface: str
    surface_index: int
    outline: np.ndarray
    center: np.ndarray | None = None  # circle only
    radius: float = 0.0  # circle only
    axis: np.ndarray | None = None

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """(x0, y0, x1, y1) of the bounding box."""
        lo = self.outline.min(axis=0)
        hi = self.outline.max(axis=0)
        return float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])

    def contains(self, x: np.ndarray | float, y: np.ndarray | float) -> np.ndarray:
        """Boolean array: which points (x, y) lie inside or on the boundary."""
        xa = np.asarray(x, dtype=float)
        ya = np.asarray(y, dtype=float)
        if self.kind == "circle":
            assert self.center is not None
            return np.asarray(
                (xa - self.center[0]) ** 2 + (ya - self.center[1]) ** 2 <= self.radius**2
            )
        if self.kind == "rect":
            x0, y0, x1, y1 = self.bounds
            return np.asarray((xa >= x0) & (xa <= x1) & (ya >= y0) & (ya <= y1))
        return points_in_polygon(xa, ya, self.outline)

    def distance(self, x: float, y: float) -> float:
        """How far the point (x, y) lies outside the region, metres (0 inside or on it)."""
        if self.kind == "circle":
            assert self.center is not None
            return max(0.0, math.hypot(x - self.center[0], y - self.center[1]) - self.radius)
        if self.kind == "rect":
            x0, y0, x1, y1 = self.bounds
            return math.hypot(max(x0 - x, 0.0, x - x1), max(y0 - y, 0.0, y - y1))
        if bool(points_in_polygon(np.asarray(x), np.asarray(y), self.outline)):
            return 0.0
        a, b = self.outline, np.roll(self.outline, -1, axis=0)
        e = b - a
        length2 = np.maximum((e * e).sum(1), 1e-18)  # a repeated vertex: an edge of length 0
        s = np.clip(((x - a[:, 0]) * e[:, 0] + (y - a[:, 1]) * e[:, 1]) / length2, 0, 1)
        return float(np.hypot(a[:, 0] + s * e[:, 0] - x, a[:, 1] + s * e[:, 1] - y).min())

    def value_along(self, x: np.ndarray | float, y: np.ndarray | float) -> np.ndarray:
        """Slider value 0..1: the projection of (x, y) on the axis, clipped to its ends."""
        if self.axis is None:
            raise ValueError(f"region {self.name!r} is not a slider (it has no axis)")
        a, b = self.axis
        d = b - a
        s = (
            (np.asarray(x, dtype=float) - a[0]) * d[0] + (np.asarray(y, dtype=float) - a[1]) * d[1]
        ) / float(d @ d)
        return np.clip(s, 0.0, 1.0)


def polygon_area(points: np.ndarray) -> float:
    """Signed area (shoelace formula); positive when counter-clockwise."""
    x, y = points[:, 0], points[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def polygon_self_crossing(points: np.ndarray) -> tuple[int, int] | None:
    """The first pair of edges (i, j), i < j, that properly cross, or None for a simple outline.

    Edge i runs from point i to point i + 1 (the last back to the first). Neighbouring edges
    share a point and are not compared. All pairs at once: O(n²) memory, so callers bound n.
    """
    a = np.asarray(points, dtype=float)
    b = np.roll(a, -1, axis=0)

    def side(p: np.ndarray, q: np.ndarray, r: np.ndarray) -> np.ndarray:
        # sign of the cross product (q - p) × (r - p) for every edge p->q against points r
        d = q - p
        return np.sign(
            d[:, None, 0] * (r[None, :, 1] - p[:, None, 1])
            - d[:, None, 1] * (r[None, :, 0] - p[:, None, 0])
        )

    apart = side(a, b, a) * side(a, b, b) < 0  # [i, j]: edge j's ends on both sides of edge i
    crosses = apart & apart.T
    n = len(a)
    i, j = np.triu_indices(n, k=2)
    hits = crosses[i, j] & ~((i == 0) & (j == n - 1))
    if not hits.any():
        return None
    k = int(np.argmax(hits))
    return int(i[k]), int(j[k])


def points_in_polygon(
    x: np.ndarray, y: np.ndarray, polygon: np.ndarray, boundary: bool = True
) -> np.ndarray:
    """Even-odd rule, vectorised over points × edges; points on an edge count as inside
    when ``boundary`` is True, as outside otherwise."""
    xs = np.asarray(x, dtype=float)
    ys = np.asarray(y, dtype=float)
    px = xs.reshape(-1, 1)
    py = ys.reshape(-1, 1)
    x0, y0 = polygon[:, 0], polygon[:, 1]
    x1, y1 = np.roll(x0, -1), np.roll(y0, -1)
    # a horizontal ray to the right crosses edges that straddle py
    straddles = (y0 > py) != (y1 > py)
    with np.errstate(divide="ignore", invalid="ignore"):
        x_cross = x0 + (py - y0) * (x1 - x0) / (y1 - y0)
    inside = np.logical_xor.reduce(straddles & (px < x_cross), axis=1)
    # boundary points: distance to some edge ~ 0
    ex, ey = x1 - x0, y1 - y0
    length2 = ex**2 + ey**2
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.clip(((px - x0) * ex + (py - y0) * ey) / np.where(length2 > 0, length2, 1.0), 0, 1)
    dist2 = (x0 + s * ex - px) ** 2 + (y0 + s * ey - py) ** 2
    on_edge = np.any(dist2 <= 1e-18, axis=1)
    result = (inside | on_edge) if boundary else (inside & ~on_edge)
    return result.reshape(xs.shape)


def circle_outline(center: np.ndarray, radius: float, n: int = 96) -> np.ndarray:
    """A closed polygon on the circle (for drawing and bounding boxes)."""
    a = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    return np.stack([center[0] + radius * np.cos(a), center[1] + radius * np.sin(a)], axis=1)


def regions_overlap(a: Region, b: Region) -> bool:
    """True when two regions on the same surface share an area (touching edges do not count).

    Rectangles and circles are judged exactly; anything with a polygon is sampled on a grid
    over the shared bounding box (an overlap thinner than 1/240 of that box may be missed).
    """
    if a.surface_index != b.surface_index:
        return False
    ax0, ay0, ax1, ay1 = a.bounds
    bx0, by0, bx1, by1 = b.bounds
    x0, y0, x1, y1 = max(ax0, bx0), max(ay0, by0), min(ax1, bx1), min(ay1, by1)
    if x1 <= x0 or y1 <= y0:
        return False
    kinds = {a.kind, b.kind}
    if kinds == {"rect"}:
        return True
    if kinds == {"circle"}:
        assert a.center is not None and b.center is not None
        return float(np.hypot(*(a.center - b.center))) < a.radius + b.radius
    if kinds == {"rect", "circle"}:
        circle, rect = (a, b) if a.kind == "circle" else (b, a)
        assert circle.center is not None
        rx0, ry0, rx1, ry1 = rect.bounds
        nearest = np.clip(circle.center, [rx0, ry0], [rx1, ry1])
        return float(np.hypot(*(nearest - circle.center))) < circle.radius
    # cell centres of a grid over the shared box; the boundary itself never decides
    step_x = (x1 - x0) / _OVERLAP_GRID
    step_y = (y1 - y0) / _OVERLAP_GRID
    gx, gy = np.meshgrid(
        x0 + step_x * (np.arange(_OVERLAP_GRID) + 0.5),
        y0 + step_y * (np.arange(_OVERLAP_GRID) + 0.5),
    )
    gx, gy = gx.ravel(), gy.ravel()
    return bool(np.any(_interior(a, gx, gy) & _interior(b, gx, gy)))


def _interior(region: Region, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Like ``contains`` but without the boundary, so shared edges are not an overlap."""
    if region.kind == "circle":
        assert region.center is not None
        return (x - region.center[0]) ** 2 + (y - region.center[1]) ** 2 < region.radius**2
    if region.kind == "rect":
        x0, y0, x1, y1 = region.bounds
        return (x > x0) & (x < x1) & (y > y0) & (y < y1)
    return points_in_polygon(x, y, region.outline, boundary=False)
