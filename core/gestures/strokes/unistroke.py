"""Unistroke shape recognition: $1 preprocessing, Protractor's rotation, an elastic match of
the directions of motion.

References:
- J. O. Wobbrock, A. D. Wilson, Y. Li, "Gestures without libraries, toolkits or training:
  a $1 recognizer for user interface prototypes", UIST 2007 — resampling to N equidistant
  points, translation to the centroid, a uniform scale, templates per shape.
- Y. Li, "Protractor: a fast and accurate gesture recognizer", CHI 2010 — the stroke as a
  unit vector, and the closed-form best rotation θ* = atan(b / a) with similarity
  a·cos θ + b·sin θ (Li 2010, eqs. 3–5).
- H. Sakoe, S. Chiba, "Dynamic programming algorithm optimization for spoken word
  recognition", IEEE TASSP 1978 — dynamic time warping within a band |i − j| ≤ r.

Changes for a desk: the stroke keeps its orientation (the desk has an up, away from the
user), and the rotation allowed between a stroke and a template is limited to
``max_rotation_deg`` (θ* clipped to the range; a·cos θ + b·sin θ = R·cos(θ − θ*) is largest
at the clipped angle), so ``caret`` is not a turned ``v``. Shapes marked closed are also
matched from 32 start points and in both directions, leaving out the variants that are
like another shape (a reversed triangle is a delete mark).

The score: the stroke's direction of motion at ``N_DIRECTIONS`` steps of equal arc length
(which fixes a path up to position and size), turned by the clipped θ*, is aligned with
each template's by dynamic time warping within ``BAND`` steps; the cost of a step is
1 − cos of the angle between the two directions and the score is
1 − (least total cost) / N_DIRECTIONS, clipped to 0..1 (the mean cosine of the angle between
matched directions when the warping path is the diagonal). The nearest shape is the one
of highest score, and a stroke whose nearest shape scores below ``min_score`` is rejected
(shape None). Measured on real people (the $1 logs, scripts/stroke_accuracy.py --dollar):
Protractor's cosine, alone or with a rigid direction term, scores a brace drawn by one person
against that person's bracket higher than another person's bracket, so no threshold kept
both writer-independent strokes (≤ 73 % right) and unknown shapes (≤ 5 % accepted); warping
the directions absorbs how people differ in timing along a shape while a missing or extra
corner still costs (see the README for the figures). Matching is a few array operations over
all templates; the warping loops over the band's cells, not over templates or samples.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from importlib import resources

import numpy as np

from hapticdesk.gestures.strokes.shapes import resample

N_POINTS = 64  # points of Protractor's vector (the rotation)
START_POINTS = 32  # start points tried for closed templates
N_DIRECTIONS = 32  # directions of motion compared by the elastic match
BAND = 3  # the warping's band (Sakoe & Chiba's r), in steps: about a tenth of a stroke
#: a start point or direction of a closed shape this like another shape is not added
MAX_VARIANT_LIKENESS = 0.9
_CELLS_PER_CHUNK = 1 << 22  # bounds the memory of a batch: strokes × templates × n²


def stroke_vector(points: np.ndarray, n: int = N_POINTS) -> np.ndarray | None:
    """Protractor's vector: resampled, centred, flattened to (2n,) and of unit length (a
    uniform scale: proportions are kept). None when the stroke has no extent."""
    p = resample(np.asarray(points, dtype=float), n)
    p = p - p.mean(axis=0)
    v = p.ravel()
    norm = float(np.linalg.norm(v))
    return v / norm if norm > 1e-12 else None


def direction_angles(points: np.ndarray, n: int = N_DIRECTIONS) -> np.ndarray:
    """The direction of motion (radians) along ``n`` steps of equal arc length (n,)."""
    d = np.diff(resample(np.asarray(points, dtype=float), n + 1), axis=0)
    return np.arctan2(d[:, 1], d[:, 0])


def _start_points(points: np.ndarray, count: int) -> list[np.ndarray]:
    """A closed path started at ``count`` points spread along it."""
    ring = resample(np.vstack([points, points[:1]]), N_POINTS * 4 + 1)[:-1]
    out = []
    for k in range(count):
        rolled = np.roll(ring, -k * len(ring) // count, axis=0)
        out.append(np.vstack([rolled, rolled[:1]]))
    return out


@dataclass(frozen=True)
class Match:
    """The verdict on a stroke: ``shape`` None when nothing matched well enough."""

    shape: str | None
    score: float
    best_shape: str | None  # the nearest shape even when rejected
    scores: dict[str, float]  # best score per shape


class TemplateSet:
    """Templates by shape name, matched all at once."""

    def __init__(self) -> None:
        self._names: list[str] = []
        self._vectors: list[np.ndarray] = []
        self._angles: list[np.ndarray] = []

    @property
    def shapes(self) -> list[str]:
        return list(dict.fromkeys(self._names))

    def __len__(self) -> int:
        return len(self._vectors)

    def add(
        self, shape: str, points: np.ndarray, closed: bool = False, reversible: bool = False
    ) -> None:
        """Add one template (any units; only its form counts)."""
        paths = _start_points(points, START_POINTS) if closed else [np.asarray(points, dtype=float)]
        if reversible:
            paths += [p[::-1] for p in paths]
        for p in paths:
            v = stroke_vector(p)
            if v is None:
                raise ValueError(f"a template of {shape!r} has no extent")
            self._names.append(shape)
            self._vectors.append(v)
            self._angles.append(direction_angles(p))

    def add_all(self, templates: Mapping[str, Iterable[np.ndarray]]) -> None:
        """Add user templates: shape -> strokes, each used as drawn."""
        for shape, strokes in templates.items():
            for points in strokes:
                self.add(shape, points)

    def classify(
        self, points: np.ndarray, min_score: float, max_rotation_deg: float = 30.0
    ) -> Match:
        """Best shape for a stroke; ``shape`` None when its score is below ``min_score``."""
        return self.classify_many([points], min_score, max_rotation_deg)[0]

    def classify_many(
        self, strokes: Sequence[np.ndarray], min_score: float, max_rotation_deg: float = 30.0
    ) -> list[Match]:
        """:meth:`classify` for many strokes at once (the same verdicts, in batches)."""
        vectors = [stroke_vector(p) for p in strokes]
        ok = [i for i, v in enumerate(vectors) if v is not None]
        out = [Match(None, 0.0, None, {})] * len(strokes)
        if not ok or not self._vectors:
            return out
        g = np.asarray([vectors[i] for i in ok]).reshape(len(ok), -1, 2)
        angles = np.asarray([direction_angles(strokes[i]) for i in ok])
        score = self._scores(g, angles, math.radians(max_rotation_deg))  # (k, T)
        names = np.asarray(self._names)
        shapes = self.shapes
        per_shape = np.column_stack([score[:, names == s].max(axis=1) for s in shapes])
        for row, i in enumerate(ok):
            scores = {s: float(per_shape[row, c]) for c, s in enumerate(shapes)}
            best = shapes[int(np.argmax(per_shape[row]))]
            out[i] = Match(best if scores[best] >= min_score else None, scores[best], best, scores)
        return out

    def _scores(self, g: np.ndarray, angles: np.ndarray, limit: float) -> np.ndarray:
        """Scores (k, T) of strokes (k, n, 2) with direction ``angles`` (k, N_DIRECTIONS)
        against every template, in chunks that bound the memory."""
        t = np.asarray(self._vectors).reshape(len(self._vectors), -1, 2)
        ta = np.asarray(self._angles)
        step = max(1, _CELLS_PER_CHUNK // (len(t) * N_DIRECTIONS**2))
        out = []
        for lo in range(0, len(g), step):
            a, b = _rotation_terms(t, g[lo : lo + step])  # Li 2010, eqs. 3-4
            theta = np.clip(np.arctan2(b, a), -limit, limit)  # (k, T)
            turned = angles[lo : lo + step, None, :, None] + theta[:, :, None, None]
            cost = 1.0 - np.cos(ta[None, :, None, :] - turned)  # (k, T, stroke i, template j)
            out.append(np.clip(1.0 - _warped_cost(cost, BAND) / N_DIRECTIONS, 0.0, 1.0))
        return np.concatenate(out)


def _rotation_terms(t: np.ndarray, g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """a = Σ t·g and b = Σ t × g over points, for templates t (T, n, 2) and strokes g
    (k, n, 2), each (k, T): turning g by θ gives the dot product a·cos θ + b·sin θ."""
    a = np.einsum("tnd,knd->kt", t, g)
    b = np.einsum("tn,kn->kt", t[:, :, 1], g[:, :, 0]) - np.einsum(
        "tn,kn->kt", t[:, :, 0], g[:, :, 1]
    )
    return a, b


def _warped_cost(cost: np.ndarray, band: int) -> np.ndarray:
    """Least total cost of a monotone path from (0, 0) to (n-1, n-1) through ``cost``
    (..., n, n) with steps right, down or diagonal and |i − j| ≤ ``band`` (Sakoe & Chiba
    1978), for all leading indices at once."""
    n = cost.shape[-1]
    previous = np.full(cost.shape[:-2] + (n + 1,), np.inf)
    previous[..., 0] = 0.0
    for i in range(1, n + 1):
        row = np.full_like(previous, np.inf)
        for j in range(max(1, i - band), min(n, i + band) + 1):
            best = np.minimum(np.minimum(previous[..., j], previous[..., j - 1]), row[..., j - 1])
            row[..., j] = cost[..., i - 1, j - 1] + best
        previous = row
    return previous[..., n]


def builtin_templates(expand: bool = True) -> TemplateSet:
    """The shipped templates (templates/*.json). ``expand``: a closed shape is also added
    from ``START_POINTS`` start points, and a reversible one the other way round, but only
    the variants that are not like another shape: a variant whose score against another
    shape's template as drawn reaches ``MAX_VARIANT_LIKENESS`` is left out. Measured on the
    $1 logs: added blindly, the reversed triangle took 47 of 150 delete marks."""
    base = TemplateSet()
    variants: list[tuple[str, np.ndarray]] = []
    root = resources.files("hapticdesk.gestures.strokes").joinpath("templates")
    for entry in sorted(root.iterdir(), key=lambda p: p.name):
        if not entry.name.endswith(".json"):
            continue
        doc = json.loads(entry.read_text(encoding="utf-8"))
        for stroke in doc["strokes"]:
            points = np.asarray(stroke, dtype=float)
            base.add(doc["shape"], points)
            if not expand:
                continue
            closed = bool(doc.get("closed", False))
            turns = _start_points(points, START_POINTS) if closed else [points]
            if doc.get("reversible", False):
                turns += [p[::-1] for p in turns]
            variants += [(doc["shape"], p) for p in turns[1:]]
    matches = base.classify_many([p for _, p in variants], 0.0)  # against the shapes as drawn
    for (shape, points), match in zip(variants, matches, strict=True):
        like_another = max((v for k, v in match.scores.items() if k != shape), default=0.0)
        if like_another < MAX_VARIANT_LIKENESS:
            base.add(shape, points)
    return base


def template_set(
    user: Mapping[str, Iterable[np.ndarray]] | None = None, builtin: bool = True
) -> TemplateSet:
    """Built-in templates (unless ``builtin`` is False) plus ``user`` templates."""
    out = builtin_templates() if builtin else TemplateSet()
    if user:
        out.add_all(user)
    return out
