"""A scene's `stroke` item read into strokes: its one source (a path, a shape, a text or a
stroke file), placed by `center`, `size` and `rotation_deg`; a text gives one stroke a pen-down."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hapticdesk.errors import ConfigError
from hapticdesk.files.marked_values import MarkedList
from hapticdesk.files.strokefile import read_stroke
from hapticdesk.files.validators import flag, number, vector
from hapticdesk.sim.actions import Step, Stroke
from hapticdesk.sim.paths import SHAPES, shape_path, text_paths
from hapticdesk.sim.scene_fields import ActionFields
from hapticdesk.sim.scene_limits import MAX_FORCE_N, MAX_SCENE_S

#: where a stroke's points come from: one of these keys
STROKE_SOURCES = ("path", "shape", "text", "file")


@dataclass(frozen=True)
class StrokePlacement:
    """Where a stroke goes: ``center`` and ``size`` (m) when given, turned by ``rotation_deg``,
    a shape drawn ``clockwise`` or not."""

    center: tuple[float, float] | None
    size: float | None
    rotation_deg: float
    clockwise: bool

    @property
    def middle(self) -> tuple[float, float]:
        """The centre, or the origin when none is given."""
        return self.center if self.center is not None else (0.0, 0.0)


def stroke_steps(f: ActionFields, timing: dict[str, Any], speed: float | None) -> list[Step]:
    """The strokes of one `stroke` item (one a pen-down), labelled ``label#1``, ``label#2`` …
    when there are several."""
    p, what = f.p, f.what
    source = _stroke_source(f)
    place = _placement(f, source)
    force = (
        number(p, "force_n", what, minimum=0.0, exclusive_minimum=True, maximum=MAX_FORCE_N)
        if "force_n" in p
        else None
    )
    surface = f.surface()
    paths = _stroke_paths(f, source, place)
    pen_up = number(p, "pen_up_s", what, default=0.45, minimum=0.0, maximum=MAX_SCENE_S)
    label = timing["label"] or (str(p["text"]) if source == "text" else str(p.get("shape", "")))
    out: list[Step] = []
    for i, pts in enumerate(paths):
        t = dict(timing)
        if i > 0:
            t.update(start_s=None, wait_s=pen_up)
        t["label"] = f"{label}#{i + 1}" if len(paths) > 1 else label
        out.append(Stroke(pts, force_n=force, speed=speed, surface=surface, **t))
    return out


def _stroke_source(f: ActionFields) -> str:
    """The one source key; a second is reported where it stands (in file order)."""
    p = f.p
    sources = sorted(
        (k for k in STROKE_SOURCES if k in p),
        key=lambda k: (p.where(k, of_key=True).line, p.where(k, of_key=True).column),
    )
    if len(sources) != 1:
        raise ConfigError(
            p.where(sources[1], of_key=True) if len(sources) > 1 else p.where(),
            f"{f.what} needs exactly one of `path`, `shape`, `text` or `file`, found "
            f"{', '.join(f'`{s}`' for s in sources) or 'none'}",
        )
    return sources[0]


def _placement(f: ActionFields, source: str) -> StrokePlacement:
    p, what = f.p, f.what
    center = (
        tuple(np.array(vector(p["center"], p.where("center"), f"`center` of {what}", 2)) * f.unit)
        if "center" in p
        else None
    )
    size = (
        number(p, "size", what, minimum=0.0, exclusive_minimum=True) * f.unit
        if "size" in p
        else None
    )
    rotation = number(p, "rotation_deg", what, default=0.0)
    clockwise = flag(p, "clockwise", what, default=False)
    if "clockwise" in p and source != "shape":
        raise ConfigError(
            p.where("clockwise", of_key=True), f"`clockwise` in {what} applies to `shape` only"
        )
    if "pen_up_s" in p and source != "text":
        raise ConfigError(
            p.where("pen_up_s", of_key=True), f"`pen_up_s` in {what} applies to `text` only"
        )
    middle = (float(center[0]), float(center[1])) if center is not None else None
    return StrokePlacement(middle, size, rotation, clockwise)


def _stroke_paths(f: ActionFields, source: str, place: StrokePlacement) -> list[np.ndarray]:
    p, what = f.p, f.what
    if source == "shape":
        name = p["shape"]
        if not isinstance(name, str) or name not in SHAPES:
            raise ConfigError(
                p.where("shape"),
                f"unknown shape {name!r} in {what}; one of {', '.join(sorted(SHAPES))}",
            )
        size = place.size if place.size is not None else 0.15
        return [shape_path(name, place.middle, size, place.rotation_deg, place.clockwise)]
    if source == "text":
        text = p["text"]
        if not isinstance(text, str) or not text.strip():
            raise ConfigError(p.where("text"), f"`text` of {what} must be non-empty text")
        size = place.size if place.size is not None else 0.2
        try:
            return text_paths(text, place.middle, size, place.rotation_deg)
        except KeyError as err:
            raise ConfigError(p.where("text"), str(err.args[0])) from None
    pts = _placed(_drawn_points(f, source), place)
    if not np.any(np.linalg.norm(np.diff(pts, axis=0), axis=1) > 0):
        raise ConfigError(p.where(source), f"`{source}` of {what} needs two distinct points")
    return [pts]


def _drawn_points(f: ActionFields, source: str) -> np.ndarray:
    """The points of a `path` (in the scene's unit) or a stroke `file` (metres)."""
    p, what = f.p, f.what
    if source == "path":
        raw = p["path"]
        if not isinstance(raw, MarkedList) or len(raw) < 2:
            raise ConfigError(
                p.where("path"), f"`path` of {what} must list two or more [u, v] points"
            )
        points = [vector(q, raw.where(i), f"point {i + 1} of `path`", 2) for i, q in enumerate(raw)]
        return np.array(points) * f.unit
    file = p["file"]
    if not isinstance(file, str):
        raise ConfigError(p.where("file"), f"`file` of {what} must be a path")
    target = Path(file) if Path(file).is_absolute() else f.path.parent / file
    try:
        return read_stroke(target)  # metres, as the stroke file format says
    except ConfigError as err:
        raise ConfigError(p.where("file"), f"{what}: {err}") from None


def _placed(pts: np.ndarray, place: StrokePlacement) -> np.ndarray:
    """``pts`` fitted into ``size`` (keeping its proportions) at ``center``, then turned."""
    if place.size is not None or place.center is not None:
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        extent = float(np.max(hi - lo))
        mid = (lo + hi) / 2.0
        scale = (place.size / extent) if place.size is not None and extent > 0 else 1.0
        pts = np.array(place.center if place.center is not None else mid) + (pts - mid) * scale
    if place.rotation_deg:
        a = np.radians(place.rotation_deg)
        rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
        mid = (pts.min(axis=0) + pts.max(axis=0)) / 2.0
        pts = mid + (pts - mid) @ rot.T
    return pts
