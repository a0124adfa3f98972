"""Reading a layout's ``templates:``: the user's own stroke shapes.

``templates:`` is a folder of stroke files (beside the layout), or a mapping from a shape name
to stroke files, folders of them, or inline lists of [x, y] points in the layout's units.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from hapticdesk.errors import ConfigError, Position
from hapticdesk.files.file_safety import check_confined
from hapticdesk.files.marked_values import MarkedList
from hapticdesk.files.strokefile import SHAPE_NAME, read_stroke, read_template_dir, stroke_files
from hapticdesk.files.validators import require_mapping, vector


class TemplateReader:
    """Reads ``templates:`` of a layout whose relative paths start at ``base``."""

    def __init__(self, base: Path, scale: float) -> None:
        self.base = base
        self.scale = scale

    def read(self, value: Any, where: Position) -> dict[str, list[np.ndarray]]:
        """Shape name -> strokes (n, 2) in metres, from the ``templates:`` value."""
        base = self.base
        if isinstance(value, str):
            folder = base / value
            check_confined(folder, f"template folder `{value}`", where)  # (before it is looked at)
            if not folder.is_dir():
                raise ConfigError(where, f"no template folder `{value}` (looked in {folder})")
            return read_template_dir(folder)
        raw = require_mapping(value, where, "`templates` (a folder, or shape -> files or points)")
        out: dict[str, list[np.ndarray]] = {}
        for shape in raw:
            if not SHAPE_NAME.match(shape):
                raise ConfigError(
                    raw.where(shape, of_key=True),
                    f"shape name {shape!r} must be letters, digits and _, starting with a letter",
                )
            out[shape] = self._template_items(raw[shape], raw.where(shape), shape, base)
        return out

    def _template_items(
        self, value: Any, where: Position, shape: str, base: Path
    ) -> list[np.ndarray]:
        if _is_point_list(value):  # one inline template
            return [self._inline(value, where, shape)]
        items = value if isinstance(value, MarkedList) else [value]
        positions = (
            [value.where(i) for i in range(len(value))]
            if isinstance(value, MarkedList)
            else [where]
        )
        out: list[np.ndarray] = []
        for item, pos in zip(items, positions, strict=True):
            if isinstance(item, str):
                target = base / item
                check_confined(target, f"template `{item}`", pos)  # (before it is looked at)
                if target.is_dir():
                    files = stroke_files(target)
                    if not files:
                        raise ConfigError(
                            pos, f"template folder `{item}` holds no .csv or .json stroke"
                        )
                    out.extend(_read_at(f, pos) for f in files)
                elif target.is_file():
                    out.append(_read_at(target, pos))
                else:
                    raise ConfigError(
                        pos, f"no stroke file or folder `{item}` (looked in {target})"
                    )
            elif _is_point_list(item):
                out.append(self._inline(item, pos, shape))
            else:
                raise ConfigError(
                    pos,
                    f"a template of `{shape}` is a stroke file, a folder of them, or a list of "
                    f"[x, y] points; found {item!r}",
                )
        if not out:
            raise ConfigError(where, f"shape `{shape}` lists no templates")
        return out

    def _inline(self, value: MarkedList, where: Position, shape: str) -> np.ndarray:
        pts = (
            np.array(
                [
                    vector(p, value.where(i), f"point {i + 1} of template `{shape}`", 2)
                    for i, p in enumerate(value)
                ]
            )
            * self.scale
        )
        if len(pts) < 2 or float(np.sum(np.hypot(*np.diff(pts, axis=0).T))) <= 0:
            raise ConfigError(where, f"a template of `{shape}` needs at least 2 distinct points")
        return pts


def _is_point_list(value: Any) -> bool:
    return (
        isinstance(value, list)
        and len(value) > 0
        and all(
            isinstance(p, list) and len(p) == 2 and all(isinstance(v, int | float) for v in p)
            for p in value
        )
    )


def _read_at(path: Path, where: Position) -> np.ndarray:
    try:
        return read_stroke(path)
    except ConfigError as err:
        raise ConfigError(where, f"template {err}") from None
