"""Unistroke shape recognition: the $1 recognizer's preprocessing with Protractor's matching.

References:
- J. O. Wobbrock, A. D. Wilson, Y. Li, "Gestures without libraries, toolkits or training:
  a $1 recognizer for user interface prototypes", UIST 2007 — resampling to N equidistant
  points, translation to the centroid, templates per shape.
- Y. Li, "Protractor: a fast and accurate gesture recognizer", CHI 2010 — the stroke as a
  unit vector, and the closed-form best rotation θ* = atan(b / a) with similarity
  a·cos θ + b·sin θ (Li 2010, eqs. 3–5).
- L. Anthony, J. O. Wobbrock, "A lightweight multistroke recognizer for user interface
  prototypes" ($N), GI 2010 — both axes scaled to the unit box unless the stroke is nearly
  one-dimensional (the shorter side under ``ONE_D_RATIO`` of the longer), so an oval circle
  or a tall rectangle still matches its template while a ``line`` keeps its proportions.

Changes for a desk: the stroke keeps its orientation (the desk has an up, away from the
user), and the rotation allowed between a stroke and a template is limited to
``max_rotation_deg`` (θ* clipped to the range; a·cos θ + b·sin θ = R·cos(θ − θ*) is largest
at the clipped angle), so ``caret`` is not a turned ``v``. Shapes marked closed are also
matched from 32 start points, reversible ones in both directions. The nearest template is
Protractor's; its score is the mean of Protractor's cosine similarity and the agreement of
the directions of motion along the two paths (mean cosine of the angle between them, at the
same rotation). Position alone scores smooth scribbles high against simple shapes; the
direction term halves what scribbles get accepted at the same loss of true shapes
(measured by scripts/stroke_accuracy.py). A stroke whose nearest shape scores below
``min_score`` is rejected (shape None). Matching is a few matrix products over all templates.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from importlib import resources

import numpy as np

from hapticdesk.gestures.strokes.shapes import resample

N_POINTS = 64
START_POINTS = 32  # start points tried for closed templates


def stroke_vector(points: np.ndarray, n: int = N_POINTS) -> np.ndarray | None:
    """Protractor's vector: resampled, centred, flattened to (2n,) and of unit length (a
    uniform scale: proportions are kept). None when the stroke has no extent."""
    p = resample(np.asarray(points, dtype=float), n)
    p = p - p.mean(axis=0)
    v = p.ravel()
    norm = float(np.linalg.norm(v))
    return v / norm if norm > 1e-12 else None


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

    def add_all(self, templates: Mapping[str, Iterable[np.ndarray]]) -> None:
        """Add user templates: shape -> strokes, each used as drawn."""
        for shape, strokes in templates.items():
            for points in strokes:
                self.add(shape, points)

    def classify(
        self, points: np.ndarray, min_score: float, max_rotation_deg: float = 30.0
    ) -> Match:
        """Best shape for a stroke; ``shape`` None when its score is below ``min_score``.

        The nearest template is the one of highest Protractor similarity; the score that
        decides acceptance adds how well the directions of motion agree at that rotation.
        """
        g = stroke_vector(points)
        if g is None or not self._vectors:
            return Match(None, 0.0, None, {})
        t = np.asarray(self._vectors).reshape(len(self._vectors), -1, 2)
        gp = g.reshape(-1, 2)
        a, b = _rotation_terms(t, gp)  # Li 2010, eq. 3-4
        limit = math.radians(max_rotation_deg)
        theta = np.clip(np.arctan2(b, a), -limit, limit)
        position = a * np.cos(theta) + b * np.sin(theta)  # Li 2010, eq. 5, at the clipped angle
        ta, tb = _rotation_terms(_directions(t), _directions(gp))
        direction = (ta * np.cos(theta) + tb * np.sin(theta)) / (gp.shape[0] - 1)
        combined = np.clip((position + direction) / 2, 0.0, 1.0)
        nearest: dict[str, int] = {}
        for i, name in enumerate(self._names):
            if name not in nearest or combined[i] > combined[nearest[name]]:
                nearest[name] = i
        scores = {name: float(combined[i]) for name, i in nearest.items()}
        best = max(scores, key=scores.__getitem__)
        score = scores[best]
        return Match(best if score >= min_score else None, score, best, scores)


def _rotation_terms(t: np.ndarray, g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """a = Σ t·g and b = Σ t × g over points, for templates t (T, n, 2) and a stroke g (n, 2):
    turning g by θ gives the dot product a·cos θ + b·sin θ."""
    a = t[:, :, 0] @ g[:, 0] + t[:, :, 1] @ g[:, 1]
    b = t[:, :, 1] @ g[:, 0] - t[:, :, 0] @ g[:, 1]
    return a, b


def _directions(points: np.ndarray) -> np.ndarray:
    """Unit vectors of motion between consecutive points (..., n - 1, 2)."""
    d = np.diff(points, axis=-2)
    return d / np.maximum(np.linalg.norm(d, axis=-1, keepdims=True), 1e-15)


def builtin_templates(expand: bool = True) -> TemplateSet:
    """The shipped templates (templates/*.json); ``expand`` False adds each as drawn, without
    the start points of closed shapes and the reversals of reversible ones."""
    out = TemplateSet()
    root = resources.files("hapticdesk.gestures.strokes").joinpath("templates")
    for entry in sorted(root.iterdir(), key=lambda p: p.name):
        if not entry.name.endswith(".json"):
            continue
        doc = json.loads(entry.read_text(encoding="utf-8"))
        for stroke in doc["strokes"]:
            out.add(
                doc["shape"],
                np.asarray(stroke),
                expand and doc.get("closed", False),
                expand and doc.get("reversible", False),
            )
    return out


def template_set(
    user: Mapping[str, Iterable[np.ndarray]] | None = None, builtin: bool = True
) -> TemplateSet:
    """Built-in templates (unless ``builtin`` is False) plus ``user`` templates."""
    out = builtin_templates() if builtin else TemplateSet()
    if user:
        out.add_all(user)
    return out
