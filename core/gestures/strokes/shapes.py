"""Geometric definitions of the built-in stroke shapes, and hand-drawn variations of them.

The sixteen shapes of the $1 gesture set (Wobbrock, Wilson, Li 2007) — triangle, x,
rectangle, circle, check, caret, question_mark, arrow, left_bracket, right_bracket, v,
delete, left_brace, right_brace, star, pigtail — plus zigzag and line. The original point
data is not used; these are our own drawings of the same shapes, in desk coordinates as the
person at the desk sees them (y away from them, so a ``v`` goes down then up: y decreasing,
then increasing).

``python -m hapticdesk.gestures.strokes.shapes`` writes the shipped templates (templates/*.json);
a test checks they match these definitions. :func:`hand_drawn` makes a differently drawn
instance (size, proportions, slant, wobble, start point, direction) for tests and for
scripts/stroke_accuracy.py.
"""

from __future__ import annotations

import json
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

TEMPLATE_POINTS = 64
TEMPLATE_SIZE_M = 0.1  # the shipped templates are 10 cm across


@dataclass(frozen=True)
class Shape:
    """A shape: one or more drawings (variants), each a dense (n, 2) path.

    ``closed``: the path returns to its start, so any start point is the same shape.
    ``reversible``: drawing it backwards is still the same shape.
    """

    name: str
    variants: tuple[np.ndarray, ...]
    closed: bool = False
    reversible: bool = False


def resample(points: np.ndarray, n: int) -> np.ndarray:
    """``n`` points equally spaced along the path (by arc length), ends kept."""
    p = np.asarray(points, dtype=float)
    seg = np.hypot(*np.diff(p, axis=0).T)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    if s[-1] <= 0:
        return np.repeat(p[:1], n, axis=0)
    u = np.linspace(0.0, s[-1], n)
    return np.column_stack([np.interp(u, s, p[:, 0]), np.interp(u, s, p[:, 1])])


def _poly(*points: tuple[float, float]) -> np.ndarray:
    return resample(np.array(points, dtype=float), 256)


def _chaikin(points: np.ndarray, rounds: int) -> np.ndarray:
    """Corner cutting that keeps both ends: a smooth curve through the keypoints' hull."""
    p = np.asarray(points, dtype=float)
    for _ in range(rounds):
        q = 0.75 * p[:-1] + 0.25 * p[1:]
        r = 0.25 * p[:-1] + 0.75 * p[1:]
        mid = np.empty((2 * len(q), 2))
        mid[0::2], mid[1::2] = q, r
        p = np.vstack([p[:1], mid, p[-1:]])
    return p


def _smooth(*points: tuple[float, float]) -> np.ndarray:
    return resample(_chaikin(np.array(points, dtype=float), 4), 256)


def _arc(cx: float, cy: float, r: float, a0_deg: float, a1_deg: float, n: int = 128) -> np.ndarray:
    a = np.radians(np.linspace(a0_deg, a1_deg, n))
    return np.column_stack([cx + r * np.cos(a), cy + r * np.sin(a)])


def _question_mark() -> np.ndarray:
    hook = _arc(0.5, 0.72, 0.28, 160.0, -90.0)  # over the top, clockwise, to the middle
    stem = np.array([[0.5, 0.44], [0.5, 0.12]])
    return resample(np.vstack([hook, stem]), 256)


def _pigtail() -> np.ndarray:
    # a prolate cycloid: up from the bottom left, one loop, down to the right
    t = np.linspace(-math.pi, math.pi, 256)
    b = 2.0
    return np.column_stack([t - b * np.sin(t), -(1.0 - b * np.cos(t))])


def _line(angle_deg: float) -> np.ndarray:
    a = math.radians(angle_deg)
    return _poly((0.0, 0.0), (math.cos(a), math.sin(a)))


SHAPES: dict[str, Shape] = {
    s.name: s
    for s in (
        Shape("triangle", (_poly((0.5, 0.87), (0, 0), (1, 0), (0.5, 0.87)),), True, True),
        Shape("x", (_poly((0, 1), (1, 0), (1, 1), (0, 0)),), False, True),
        Shape("rectangle", (_poly((0, 1), (0, 0), (1.4, 0), (1.4, 1), (0, 1)),), True, True),
        Shape("circle", (_arc(0, 0, 1, 90, 450, 256),), True, True),
        Shape("check", (_poly((0, 0.45), (0.3, 0), (1, 1)),)),
        Shape("caret", (_poly((0, 0), (0.5, 1), (1, 0)),), False, True),
        Shape("question_mark", (_question_mark(),)),
        Shape("arrow", (_poly((0, 0.5), (1, 0.5), (0.75, 0.75), (1, 0.5), (0.75, 0.25)),)),
        Shape("left_bracket", (_poly((0.5, 1), (0, 1), (0, 0), (0.5, 0)),), False, True),
        Shape("right_bracket", (_poly((0, 1), (0.5, 1), (0.5, 0), (0, 0)),), False, True),
        Shape("v", (_poly((0, 1), (0.5, 0), (1, 1)),), False, True),
        # not reversible: drawn backwards it follows a triangle started at a corner, and the
        # reversed template took triangles for delete marks (unistroke.builtin_templates)
        Shape("delete", (_poly((0, 1), (1, 0), (0, 0), (1, 1)),), False, False),
        Shape(
            "left_brace",
            (
                _smooth(
                    (0.5, 1),
                    (0.25, 0.97),
                    (0.25, 0.6),
                    (0, 0.5),
                    (0.25, 0.4),
                    (0.25, 0.03),
                    (0.5, 0),
                ),
            ),
            False,
            True,
        ),
        Shape(
            "right_brace",
            (
                _smooth(
                    (0, 1), (0.25, 0.97), (0.25, 0.6), (0.5, 0.5), (0.25, 0.4), (0.25, 0.03), (0, 0)
                ),
            ),
            False,
            True,
        ),
        Shape(
            "star",
            (_poly((0.2, 0), (0.5, 1), (0.8, 0), (0, 0.62), (1, 0.62), (0.2, 0)),),
            True,
            True,
        ),
        Shape("pigtail", (_pigtail(),)),
        Shape(
            "zigzag",  # down or up first, four or five strokes
            (
                _poly((0, 0.5), (0.2, 0), (0.4, 0.5), (0.6, 0), (0.8, 0.5), (1, 0)),
                _poly((0, 0.5), (0.25, 0), (0.5, 0.5), (0.75, 0), (1, 0.5)),
                _poly((0, 0), (0.2, 0.5), (0.4, 0), (0.6, 0.5), (0.8, 0), (1, 0.5)),
                _poly((0, 0), (0.25, 0.5), (0.5, 0), (0.75, 0.5), (1, 0)),
            ),
            False,
            True,
        ),
        Shape("line", tuple(_line(a) for a in (0.0, 45.0, 90.0, 135.0)), False, True),
    )
}


def normalised(points: np.ndarray, size: float) -> np.ndarray:
    """The path centred on its bounding box and scaled so the larger side is ``size``."""
    p = np.asarray(points, dtype=float)
    lo, hi = p.min(axis=0), p.max(axis=0)
    return (p - (lo + hi) / 2) * (size / max(float(np.max(hi - lo)), 1e-12))


def template_document(shape: Shape) -> dict[str, object]:
    """The JSON document of a shipped template."""
    return {
        "shape": shape.name,
        "closed": shape.closed,
        "reversible": shape.reversible,
        "source": "hapticdesk.gestures.strokes.shapes (own drawing of the $1 gesture set's shape)",
        "strokes": [
            np.round(normalised(resample(v, TEMPLATE_POINTS), TEMPLATE_SIZE_M), 5).tolist()
            for v in shape.variants
        ],
    }


def write_templates(folder: Path) -> list[Path]:
    """Write one ``<shape>.json`` per built-in shape into ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for shape in SHAPES.values():
        path = folder / f"{shape.name}.json"
        path.write_text(json.dumps(template_document(shape)) + "\n", encoding="utf-8")
        paths.append(path)
    return paths


def hand_drawn(
    name: str,
    rng: np.random.Generator,
    size_m: float = 0.08,
    wobble: float = 0.03,
    slant_deg: float = 12.0,
    style: int | None = None,
) -> np.ndarray:
    """A differently drawn instance of a built-in shape, as a dense path in metres.

    Unlike the template it has other proportions (each axis scaled 0.75–1.33), a slant and a
    turn (up to ``slant_deg``), wobble (smooth sideways drift of up to ``wobble`` of its size
    along the path), rounded or overshot corners, a random start point when the shape is
    closed, and a random direction when it is reversible. Centred at (0, 0).

    ``style`` makes one person: the same ``style`` always picks the same variant, start
    point, direction and corners for a shape (people draw a shape the same way each time);
    size, proportions, slant and wobble still vary with ``rng``.
    """
    shape = SHAPES[name]
    how = rng if style is None else np.random.default_rng([style, *name.encode()])
    path = shape.variants[int(how.integers(len(shape.variants)))].copy()
    if shape.closed:
        ring = resample(path, 257)[:-1]
        ring = np.roll(ring, int(how.integers(256)), axis=0)
        path = np.vstack([ring, ring[:1]])
    if shape.reversible and how.random() < 0.5:
        path = path[::-1]
    if how.random() < 0.5:  # rounded corners
        path = resample(_chaikin(resample(path, 24 + int(how.integers(16))), 2), 256)
    path = normalised(path, 1.0)
    aspect = np.exp(rng.uniform(np.log(0.75), np.log(1.33), size=2))
    shear = math.tan(math.radians(rng.uniform(-slant_deg, slant_deg)))
    turn = math.radians(rng.uniform(-slant_deg, slant_deg))
    c, s = math.cos(turn), math.sin(turn)
    affine = np.array([[c, -s], [s, c]]) @ np.array([[1.0, shear], [0.0, 1.0]]) @ np.diag(aspect)
    path = path @ affine.T
    # wobble: a few slow random sinusoids across the path, in both axes
    u = np.linspace(0.0, 1.0, len(path))[:, None]
    freq = rng.uniform(0.5, 3.0, size=(1, 3))
    phase = rng.uniform(0, 2 * math.pi, size=(2, 3))
    amp = rng.uniform(0, wobble, size=(2, 3)) / 3
    path = path + np.column_stack(
        [np.sum(amp[k] * np.sin(2 * math.pi * freq * u + phase[k]), axis=1) for k in range(2)]
    )
    return normalised(path, size_m * rng.uniform(0.75, 1.33))


if __name__ == "__main__":  # pragma: no cover - regenerates package data
    target = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).parent / "templates"
    for written in write_templates(target):
        print(written)
