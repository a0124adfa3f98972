"""Reading a layout's ``regions:``: rectangles, circles and polygons on a desk's surfaces.

Each region is checked where a person can get it wrong: its shape (a rect with x0 < x1, a
polygon that has an area and does not cross itself), its slider axis, and whether it lies on
its surface (partly off is a warning, wholly off an error with a hint about units).
"""

from __future__ import annotations

import re
from typing import Any

import numpy as np

from hapticdesk.errors import ConfigError, Position
from hapticdesk.files.marked_values import MarkedDict, MarkedList
from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.validators import (
    MAX_REACH_M,  # (a radius of 1e200 had crashed)
    check_keys,
    choice,
    number,
    require_mapping,
    vector,
)
from hapticdesk.gestures.regions import (
    Region,
    circle_outline,
    points_in_polygon,
    polygon_area,
    polygon_self_crossing,
)

REGION_KINDS = ("rect", "circle", "polygon")
REGION_KEYS = frozenset({*REGION_KINDS, "surface", "axis", "description"})
REGION_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_-]*$")
REGION_RULE = "must start with a letter and hold only letters, digits, _ and -"
#: enough for any outline drawn by hand; the self-crossing check compares every pair of edges
MAX_POLYGON_POINTS = 500


class RegionReader:
    """Reads ``regions:`` of a layout in ``units`` (``scale`` metres each) on ``desk``.

    Warnings (a region reaching beyond its surface) are appended to ``warnings``.
    """

    def __init__(self, desk: DeskProfile, scale: float, units: str, warnings: list[str]) -> None:
        self.desk = desk
        self.scale = scale
        self.units = units
        self.warnings = warnings

    def read(self, value: Any, where: Position) -> dict[str, Region]:
        """The regions by name from the ``regions:`` mapping ``value``."""
        raw = require_mapping(value, where, "`regions`")
        out: dict[str, Region] = {}
        for name in raw:
            if not REGION_NAME.match(name):
                raise ConfigError(
                    raw.where(name, of_key=True),
                    f"region name {name!r} {REGION_RULE}",
                )
            out[name] = self._region(name, raw[name], raw.where(name))
        return out

    def _region(self, name: str, value: Any, where: Position) -> Region:
        what = f"region `{name}`"
        m = require_mapping(value, where, what)
        check_keys(m, REGION_KEYS, what)
        kinds = [k for k in REGION_KINDS if k in m]
        if len(kinds) != 1:
            found = ", ".join(kinds) if kinds else "none"
            raise ConfigError(
                m.where(), f"{what} needs exactly one of rect, circle, polygon; found {found}"
            )
        kind = kinds[0]
        surfaces = [s.name for s in self.desk.surfaces]
        if not surfaces:  # (a bare sensor's profile, e.g. ati-bench: nothing to touch)
            raise ConfigError(
                m.where(),
                f"{what}: the desk `{self.desk.name}` has no surfaces to put a region on; "
                "its profile needs `surfaces:`",
            )
        surface = choice(m, "surface", tuple(surfaces), what, default=surfaces[0])
        index = surfaces.index(surface)
        center = None
        radius = 0.0
        if kind == "rect":
            outline = self._rect(m, what)
        elif kind == "circle":
            center, radius = self._circle(m, what)
            outline = circle_outline(center, radius)
        else:
            outline = self._polygon(m, what)
        axis = self._axis(m, what, outline) if "axis" in m else None
        region = Region(name, kind, surface, index, outline, center, radius, axis)
        self._check_on_surface(region, m.where(kind))
        return region

    def _within_reach(self, values: np.ndarray, where: Position, what: str) -> None:
        """ConfigError when a coordinate or length (metres) is beyond :data:`MAX_REACH_M`."""
        far = float(np.max(np.abs(values)))
        if far > MAX_REACH_M:
            raise ConfigError(
                where,
                f"{what} reaches {far / self.scale:g} {self.units} from the desk's origin; a "
                f"region lies within {MAX_REACH_M / self.scale:g} {self.units} of it",
            )

    def _rect(self, m: MarkedDict, what: str) -> np.ndarray:
        x0, y0, x1, y1 = (
            v * self.scale
            for v in vector(m["rect"], m.where("rect"), f"`rect` of {what} ([x0, y0, x1, y1])", 4)
        )
        if not (x0 < x1 and y0 < y1):
            raise ConfigError(
                m.where("rect"),
                f"`rect` of {what} is [x0, y0, x1, y1] with x0 < x1 and y0 < y1, "
                f"found {list(m['rect'])}",
            )
        outline = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
        self._within_reach(outline, m.where("rect"), what)
        return outline

    def _circle(self, m: MarkedDict, what: str) -> tuple[np.ndarray, float]:
        c = require_mapping(
            m["circle"], m.where("circle"), f"`circle` of {what} ({{center: [x, y], radius: r}})"
        )
        check_keys(c, {"center", "radius"}, f"`circle` of {what}", required={"center", "radius"})
        center = np.array(vector(c["center"], c.where("center"), f"`center` of {what}", 2))
        radius = number(c, "radius", f"`circle` of {what}", minimum=0.0, exclusive_minimum=True)
        center, radius = center * self.scale, radius * self.scale
        # (before its outline's arithmetic: a radius of 1e200 had overflowed into a crash)
        self._within_reach(np.append(np.abs(center), radius), m.where("circle"), what)
        return center, radius

    def _polygon(self, m: MarkedDict, what: str) -> np.ndarray:
        pts = m["polygon"]
        if not isinstance(pts, MarkedList) or not 3 <= len(pts) <= MAX_POLYGON_POINTS:
            raise ConfigError(
                m.where("polygon"),
                f"`polygon` of {what} must list 3 to {MAX_POLYGON_POINTS} [x, y] points",
            )
        outline = self.scale * np.array(
            [vector(p, pts.where(i), f"point {i + 1} of {what}", 2) for i, p in enumerate(pts)]
        )
        self._within_reach(outline, m.where("polygon"), what)  # (before the crossing's arithmetic)
        crossing = polygon_self_crossing(outline)
        if crossing is not None:
            i, j = crossing
            raise ConfigError(
                pts.where(i),
                f"`polygon` of {what} crosses itself: the edge from point {i + 1} crosses the "
                f"edge from point {j + 1}; list the points in order around the outline",
            )
        if abs(polygon_area(outline)) < 1e-12:
            raise ConfigError(m.where("polygon"), f"`polygon` of {what} has no area")
        return outline

    def _axis(self, m: MarkedDict, what: str, outline: np.ndarray) -> np.ndarray:
        value = m["axis"]
        lo, hi = outline.min(axis=0), outline.max(axis=0)
        mid = (lo + hi) / 2
        if value == "x":
            return np.array([[lo[0], mid[1]], [hi[0], mid[1]]])
        if value == "y":
            return np.array([[mid[0], lo[1]], [mid[0], hi[1]]])
        if isinstance(value, MarkedList) and len(value) == 2:
            a, b = (
                np.array(vector(p, value.where(i), f"axis point {i + 1} of {what}", 2)) * self.scale
                for i, p in enumerate(value)
            )
            self._within_reach(np.array([a, b]), m.where("axis"), f"the `axis` of {what}")
            if np.hypot(*(b - a)) <= 0:
                raise ConfigError(m.where("axis"), f"the two `axis` points of {what} are the same")
            return np.array([a, b])
        raise ConfigError(
            m.where("axis"),
            f"`axis` of {what} must be x, y or two points [[x0, y0], [x1, y1]] "
            f"(value 0 at the first), found {value!r}",
        )

    def _check_on_surface(self, region: Region, where: Position) -> None:
        surface = self.desk.surfaces[region.surface_index]
        x0, y0, x1, y1 = region.bounds
        grid = np.meshgrid(np.linspace(x0, x1, 41), np.linspace(y0, y1, 41))
        gx, gy = grid[0].ravel(), grid[1].ravel()
        inside = region.contains(gx, gy)
        on_surface = points_in_polygon(gx[inside], gy[inside], surface.polygon)
        if on_surface.all():
            return
        sx0, sy0 = surface.polygon.min(axis=0) / self.scale
        sx1, sy1 = surface.polygon.max(axis=0) / self.scale
        extent = f"x {sx0:g}..{sx1:g} and y {sy0:g}..{sy1:g} {self.units}"
        if on_surface.any():
            self.warnings.append(
                f"{where}: region `{region.name}` reaches beyond surface `{surface.name}` "
                f"({extent})"
            )
            return
        hint = ""
        if self.units == "m" and np.all(
            np.abs(region.outline) * 0.01 <= np.abs(surface.polygon).max()
        ):
            hint = "; are the numbers in cm? add `units: cm`"
        raise ConfigError(
            where,
            f"region `{region.name}` lies entirely outside surface `{surface.name}` of desk "
            f"`{self.desk.name}`, which spans {extent}{hint}",
        )
