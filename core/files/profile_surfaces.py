"""The desk profile's ``surfaces:`` read and checked: each touchable plane's origin, normal,
in-plane axes and outline, and that a touch on it can be located with the desk's sensors
(:mod:`.sensing`). Every error at ``file:line:column``. Part of :mod:`.profile_reader`."""

from __future__ import annotations

from typing import Any

import numpy as np

from hapticdesk.errors import ConfigError
from hapticdesk.files.marked_values import MarkedDict, MarkedList
from hapticdesk.files.profile import DeskProfile, SensorSpec, Surface
from hapticdesk.files.sensing import MIN_FOOTPRINT_SHARE, surface_locatable, thin_footprint
from hapticdesk.files.validators import check_keys, place, require_mapping, vector

#: enough for any surface outline drawn by hand (as a layout's regions)
MAX_SURFACE_POINTS = 500
SURFACE_KEYS = {"name", "origin", "normal", "polygon", "u_axis"}


def read_surfaces(doc: MarkedDict, sensors: tuple[SensorSpec, ...]) -> tuple[Surface, ...]:
    """The profile's ``surfaces:`` (none when absent), each name used once, each one a touch
    on can be located with ``sensors``."""
    items = doc.get("surfaces", MarkedList())
    if not isinstance(items, list):
        raise ConfigError(doc.where("surfaces"), "`surfaces` must be a list")
    surfaces = tuple(_surface(item, items.where(i)) for i, item in enumerate(items))  # type: ignore[attr-defined]
    names = [s.name for s in surfaces]
    for i, n in enumerate(names):
        if names.index(n) != i:
            raise ConfigError(items.where(i), f"surface name `{n}` is used twice")  # type: ignore[attr-defined]
    _check_locatable(sensors, surfaces, doc, items)
    return surfaces


def _check_locatable(
    sensors: tuple[SensorSpec, ...],
    surfaces: tuple[Surface, ...],
    doc: MarkedDict,
    surfaces_raw: Any,
) -> None:
    """Every surface must be one a touch on can be located on: the sensors see the force
    into it and the moments about its axes (3 upright load cells not on one line, or one
    six-axis sensor, for a horizontal board; :mod:`hapticdesk.files.sensing`)."""
    if not surfaces:
        return
    probe = DeskProfile(name="", sample_rate_hz=1.0, sensors=sensors, surfaces=surfaces)
    wrench_map = probe.wrench_map()
    for i, surface in enumerate(surfaces):
        if surface_locatable(wrench_map, surface):
            _check_footprint(probe, surface, doc)
            continue
        kinds = sorted({" ".join(s.channels) for s in sensors})
        raise ConfigError(
            surfaces_raw.where(i) if isinstance(surfaces_raw, MarkedList) else doc.where(),
            f"a touch on surface `{surface.name}` cannot be located with these sensors "
            f"({len(sensors)}, delivering {'; '.join(kinds)}): they must see the force into "
            "it and the moments about its two axes (a horizontal board needs 3 or more "
            "sensors not on one line, or one six-axis sensor)",
        )


def _check_footprint(probe: DeskProfile, surface: Surface, doc: MarkedDict) -> None:
    """Sensors that locate a touch on ``surface`` by their forces' moments must not stand
    nearly on one line (:func:`.sensing.thin_footprint`): refused at the `position` of the
    sensor that sets the footprint's width."""
    thin = thin_footprint(probe, surface)
    if thin is None:
        return
    sensor = probe.sensors[thin.widest]
    items = doc["sensors"]
    where = items[thin.widest].where("position") if isinstance(items, MarkedList) else doc.where()
    needed_mm = MIN_FOOTPRINT_SHARE * thin.length_m * 1000
    raise ConfigError(
        where,
        f"the sensors under surface `{surface.name}` stand nearly on one line: their footprint "
        f"is {thin.width_m * 1000:.3g} mm wide and {thin.length_m:.3g} m long "
        f"({thin.share:.2%}, sensor `{sensor.name}` the farthest off it). They locate a touch "
        "by the moments their forces make, which across a strip this thin a millimetre's "
        f"error in a sensor's place turns into centimetres: a footprint needs a width of at "
        f"least {MIN_FOOTPRINT_SHARE:.0%} of its length ({needed_mm:.0f} mm here)",
    )


def _unit(v: list[float], where: Any, what: str) -> np.ndarray:
    arr = np.array(v)
    norm = float(np.linalg.norm(arr))
    if norm < 1e-12:
        raise ConfigError(where, f"{what} must not be the zero vector")
    return arr / norm


def _surface(item: Any, where: Any) -> Surface:
    m = require_mapping(item, where, "a surface")
    check_keys(m, SURFACE_KEYS, "a surface", required={"name", "origin", "normal", "polygon"})
    name = m["name"]
    if not isinstance(name, str) or not name:
        raise ConfigError(m.where("name"), "surface `name` must be a non-empty text")
    what = f"surface `{name}`"
    origin = np.array(place(m["origin"], m.where("origin"), f"`origin` of {what}", 3))
    normal = _unit(
        vector(m["normal"], m.where("normal"), f"`normal` of {what}", 3),
        m.where("normal"),
        f"`normal` of {what}",
    )
    u, v, offset = _plane_axes(m, origin, normal, what)
    return Surface(name, origin, normal, u, v, _outline(m, what), offset)


def _plane_axes(
    m: MarkedDict, origin: np.ndarray, normal: np.ndarray, what: str
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The surface's in-plane axes u, v and the offset of its (u, v): from ``u_axis``, or,
    for a horizontal surface without one, the desk's x and y (its polygon in desk (x, y))."""
    if "u_axis" not in m:
        if abs(abs(normal[2]) - 1.0) > 1e-9:
            raise ConfigError(
                m.where("normal"),
                f"{what} is not horizontal: give `u_axis` so its polygon has axes",
            )
        return np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]), origin[:2].copy()
    u_raw = _unit(
        vector(m["u_axis"], m.where("u_axis"), f"`u_axis` of {what}", 3),
        m.where("u_axis"),
        f"`u_axis` of {what}",
    )
    u = u_raw - (u_raw @ normal) * normal  # keep it in the plane
    if np.linalg.norm(u) < 1e-6:
        raise ConfigError(
            m.where("u_axis"), f"`u_axis` of {what} must not be parallel to its normal"
        )
    u = u / np.linalg.norm(u)
    return u, np.cross(normal, u), np.zeros(2)


def _outline(m: MarkedDict, what: str) -> np.ndarray:
    """``polygon``: (N, 2) [u, v] points, 3 to :data:`MAX_SURFACE_POINTS`, enclosing an area."""
    poly_raw = m["polygon"]
    if not isinstance(poly_raw, list) or not 3 <= len(poly_raw) <= MAX_SURFACE_POINTS:
        found = f", found {len(poly_raw)}" if isinstance(poly_raw, list) else ""
        raise ConfigError(
            m.where("polygon"),
            f"`polygon` of {what} must list 3 to {MAX_SURFACE_POINTS} [u, v] points{found}",
        )
    pts = np.array(
        [
            place(p, poly_raw.where(i), f"polygon point {i + 1} of {what}", 2, "its origin")  # type: ignore[attr-defined]
            for i, p in enumerate(poly_raw)
        ]
    )
    area = 0.5 * float(
        np.sum(pts[:, 0] * np.roll(pts[:, 1], -1) - np.roll(pts[:, 0], -1) * pts[:, 1])
    )
    if abs(area) < 1e-12:
        raise ConfigError(m.where("polygon"), f"`polygon` of {what} has no area")
    return pts
