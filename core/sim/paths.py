"""Paths for strokes: common shapes, a few characters (北 of the paper's Fig. 15) and files.

Every path is a sequence of points (n, 2) on a surface, in page orientation: x to the right
and y away from the person at the desk ("up" on a page lying on the desk). Shapes and glyphs
are defined in a unit box [-0.5, 0.5]² and placed with a centre, a size and a rotation.
"""

from __future__ import annotations

import math

import numpy as np


def _circle() -> np.ndarray:
    # starts at the top and runs counter-clockwise, as most people draw a circle
    a = np.radians(np.arange(90.0, 450.0 + 1e-9, 5.0))
    return 0.5 * np.stack([np.cos(a), np.sin(a)], axis=1)


def _star() -> np.ndarray:
    a = np.radians(90.0 + 144.0 * np.arange(6))
    return 0.5 * np.stack([np.cos(a), np.sin(a)], axis=1)


def _fit(points: np.ndarray) -> np.ndarray:
    """Centre a path on its bounding box and scale its larger side to 1."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    return (points - (lo + hi) / 2.0) / float(np.max(hi - lo))


def _pigtail() -> np.ndarray:
    # a prolate cycloid: up from the lower left, one loop, down to the right
    t = np.linspace(-math.pi, math.pi, 73)
    return _fit(np.stack([t - 2.0 * np.sin(t), 2.0 * np.cos(t) - 1.0], axis=1))


def _question_mark() -> np.ndarray:
    a = np.radians(np.linspace(160.0, -90.0, 46))  # over the top, clockwise, to the middle
    hook = np.stack([0.28 * np.cos(a), 0.22 + 0.28 * np.sin(a)], axis=1)
    return np.vstack([hook, [[0.0, -0.5]]])


# Closed shapes run counter-clockwise; ``clockwise=True`` mirrors them. The names follow the
# gesture recogniser's shapes (the $1 gesture set) where they overlap.
SHAPES: dict[str, np.ndarray] = {
    "line": np.array([[-0.5, 0.0], [0.5, 0.0]]),
    "circle": _circle(),
    "triangle": np.array([[0.0, 0.5], [-0.5, -0.5], [0.5, -0.5], [0.0, 0.5]]),
    "rectangle": np.array([[-0.5, 0.3], [-0.5, -0.3], [0.5, -0.3], [0.5, 0.3], [-0.5, 0.3]]),
    "square": np.array([[-0.5, 0.5], [-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]]),
    "check": np.array([[-0.5, 0.1], [-0.15, -0.35], [0.5, 0.45]]),
    "zigzag": np.array([[-0.5, -0.25], [-0.25, 0.25], [0.0, -0.25], [0.25, 0.25], [0.5, -0.25]]),
    "v": np.array([[-0.4, 0.5], [0.0, -0.5], [0.4, 0.5]]),
    "caret": np.array([[-0.4, -0.5], [0.0, 0.5], [0.4, -0.5]]),
    "star": _star(),
    "x": np.array([[-0.5, 0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, -0.5]]),
    "delete": np.array([[-0.5, 0.5], [0.5, -0.5], [-0.5, -0.5], [0.5, 0.5]]),
    "arrow": np.array([[-0.5, 0.0], [0.5, 0.0], [0.25, 0.25], [0.5, 0.0], [0.25, -0.25]]),
    "left_bracket": np.array([[0.25, 0.5], [-0.25, 0.5], [-0.25, -0.5], [0.25, -0.5]]),
    "right_bracket": np.array([[-0.25, 0.5], [0.25, 0.5], [0.25, -0.5], [-0.25, -0.5]]),
    "pigtail": _pigtail(),
    "question_mark": _question_mark(),
}

# Characters as strokes in writing order, each stroke a polyline in the unit box.
# 北 ("kita", the paper's Fig. 15), five strokes in the standard order 丨 一 ㇀ ノ 乚: the left
# part's vertical, its short horizontal and rising stroke, then the right part's left-falling
# stroke and its vertical that bends right into a hook.
GLYPHS: dict[str, list[list[tuple[float, float]]]] = {
    "北": [
        [(-0.12, 0.42), (-0.12, -0.45)],
        [(-0.42, 0.12), (-0.12, 0.12)],
        [(-0.45, -0.22), (-0.12, -0.05)],
        [(0.38, 0.22), (0.12, 0.08)],
        [(0.12, 0.45), (0.12, -0.38), (0.2, -0.45), (0.42, -0.45), (0.45, -0.33)],
    ],
    "一": [[(-0.45, 0.0), (0.45, 0.0)]],
    "二": [[(-0.3, 0.22), (0.3, 0.22)], [(-0.45, -0.25), (0.45, -0.25)]],
    "三": [
        [(-0.35, 0.35), (0.35, 0.35)],
        [(-0.25, 0.0), (0.25, 0.0)],
        [(-0.45, -0.38), (0.45, -0.38)],
    ],
    "十": [[(-0.45, 0.05), (0.45, 0.05)], [(0.0, 0.45), (0.0, -0.45)]],
    "口": [
        [(-0.35, 0.35), (-0.35, -0.35)],
        [(-0.35, 0.35), (0.35, 0.35), (0.35, -0.35)],
        [(-0.35, -0.35), (0.35, -0.35)],
    ],
    "人": [[(0.0, 0.45), (-0.1, 0.0), (-0.45, -0.45)], [(0.0, 0.1), (0.45, -0.45)]],
}


def place(
    unit: np.ndarray, center: tuple[float, float], size: float, rotation_deg: float = 0.0
) -> np.ndarray:
    """Scale unit-box points by ``size``, rotate counter-clockwise, move to ``center``."""
    a = math.radians(rotation_deg)
    rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    return np.asarray(center, dtype=float) + size * (np.asarray(unit, dtype=float) @ rot.T)


def shape_path(
    name: str,
    center: tuple[float, float] = (0.0, 0.0),
    size: float = 0.15,
    rotation_deg: float = 0.0,
    clockwise: bool = False,
) -> np.ndarray:
    """The path (n, 2) of a named shape (see :data:`SHAPES`)."""
    if name not in SHAPES:
        raise KeyError(f"unknown shape {name!r}; known shapes: {', '.join(sorted(SHAPES))}")
    unit = SHAPES[name].copy()
    if clockwise:
        unit[:, 0] = -unit[:, 0]
    return place(unit, center, size, rotation_deg)


def text_paths(
    text: str,
    center: tuple[float, float] = (0.0, 0.0),
    size: float = 0.2,
    rotation_deg: float = 0.0,
) -> list[np.ndarray]:
    """Strokes (each (n, 2)) writing ``text`` left to right, characters ``size`` apart."""
    missing = sorted({c for c in text if c not in GLYPHS and not c.isspace()})
    if missing:
        raise KeyError(
            f"no built-in strokes for {', '.join(repr(c) for c in missing)}; built-in "
            f"characters: {' '.join(GLYPHS)} (give the strokes as `path` points instead)"
        )
    strokes: list[np.ndarray] = []
    n = len(text)
    for i, ch in enumerate(text):
        if ch.isspace():
            continue
        shift = np.array([i - (n - 1) / 2.0, 0.0])
        for stroke in GLYPHS[ch]:
            strokes.append(place(np.array(stroke) + shift, center, size, rotation_deg))
    return strokes


def path_length(points: np.ndarray) -> float:
    """Length of a polyline (n, 2)."""
    return float(np.sum(np.linalg.norm(np.diff(points, axis=0), axis=1)))
