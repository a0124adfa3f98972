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
1 − cos of the angle between the two directions, and the warped score
1 − (least total cost) / N_DIRECTIONS (the mean cosine of the angle between matched
directions when the warping path is the diagonal) is mixed with Protractor's cosine
(``PROTRACTOR_WEIGHT``). Against a template drawn by a person, a difference in form costs
too: in total turning (a brace turns about twice as much as a bracket) and in the share of
the turning in the sharpest few turns (corners against curves: rectangle against circle).
The score is clipped to 0..1. The nearest shape is the one of highest score; it is accepted
when its score reaches ``min_score`` and, for a shape with two or more templates as drawn,
the templates' own agreement less ``TIGHTNESS_MARGIN``: a shape its writer draws the same
way each time asks more of a stroke than one drawn loosely. A stroke nearest a built-in
template asks ``BUILTIN_EXTRA_SCORE`` more (form is not compared against those). Measured
on real people (the $1 logs, scripts/stroke_accuracy.py --dollar; figures in the README):
one global threshold on the warped score could not keep both writer-independent strokes at
Protractor's top-1 and unknown shapes at ≤ 5 % accepted, nine of ten unknowns accepted
being a brace taken for the same person's bracket or caret ↔ question mark. Matching is a
few array operations over all templates; the warping loops over the band's cells, not over
templates or samples.
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
#: share of Protractor's cosine (Li 2010, eq. 5, at the clipped rotation) in the score: the
#: warped directions forgive timing, the cosine keeps where the path goes
PROTRACTOR_WEIGHT = 0.15
TURNING_STEPS = 12  # directions over which the total turning of a path is summed
#: a stroke's total turning may differ from a template's by this much (log ratio, about
#: ±22 %) at no cost; beyond it every unit of log ratio costs TURNING_WEIGHT of the score:
#: a brace turns about twice as much as a bracket of the same person
TURNING_SLACK = 0.2
TURNING_WEIGHT = 0.3
MIN_TURNING = math.pi / 2  # a quarter turn: less is an about straight path
#: corners against curves: the share of a path's turning in its CORNER_TURNS sharpest turns
#: (of N_DIRECTIONS) is about 1 for a rectangle or a bracket, well below for a circle or a
#: brace; a difference beyond CORNER_SLACK costs CORNER_WEIGHT per unit
CORNER_TURNS = 4
CORNER_SLACK = 0.1
CORNER_WEIGHT = 0.3
#: a shape with two or more drawn templates needs a score of its templates' own agreement
#: (mean best score of each against the others) less this margin, if above ``min_score``
TIGHTNESS_MARGIN = 0.12
#: a stroke whose nearest template is a built-in one (drawn by program, so not compared by
#: form) needs ``min_score`` plus this: measured at min_score 0.8 on strokes that are none of
#: the shapes (S, Z, spiral, figure eight, scribble) traced on the simulated desk, +0 / +0.04 /
#: +0.08 / +0.1 accept 18 / 12 / 5 / 3 % of them while real people's strokes (the $1 logs,
#: built-in templates) stay 98.0 / 96.8 / 94.4 / 92.4 % right
BUILTIN_EXTRA_SCORE = 0.08
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


def total_turning(points: np.ndarray, n: int = TURNING_STEPS) -> float:
    """Sum of the absolute turns (radians) between ``n`` directions of motion, at least
    MIN_TURNING: below it a path is about straight and the ratio of two turnings is noise."""
    turns = np.angle(np.exp(1j * np.diff(direction_angles(points, n))))
    return max(float(np.abs(turns).sum()), MIN_TURNING)


def corner_share(points: np.ndarray) -> float:
    """Share of the turning (over N_DIRECTIONS directions) in the CORNER_TURNS sharpest turns,
    of at least MIN_TURNING: near 0 for an about straight path."""
    turns = np.abs(np.angle(np.exp(1j * np.diff(direction_angles(points)))))
    top = float(np.sort(turns)[-CORNER_TURNS:].sum())
    return top / max(float(turns.sum()), MIN_TURNING)


def _form(points: np.ndarray) -> tuple[float, float]:
    return total_turning(points), corner_share(points)


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
        self._forms: list[tuple[float, float]] = []  # total turning, corner share
        self._ideal: list[bool] = []  # drawn by program: its form is not compared
        self._drawn: list[bool] = []  # as drawn, not a start point or direction variant
        self._thresholds: dict[str, float] | None = None  # own agreement less the margin

    @property
    def shapes(self) -> list[str]:
        return list(dict.fromkeys(self._names))

    def __len__(self) -> int:
        return len(self._vectors)

    def add(
        self,
        shape: str,
        points: np.ndarray,
        closed: bool = False,
        reversible: bool = False,
        ideal: bool = False,
    ) -> None:
        """Add one template (any units; only its form counts). ``ideal``: drawn by program
        (the built-in shapes), whose sharp corners and exact turns people do not draw, so a
        stroke's turning and corners are not compared with it."""
        paths = _start_points(points, START_POINTS) if closed else [np.asarray(points, dtype=float)]
        if reversible:
            paths += [p[::-1] for p in paths]
        for k, p in enumerate(paths):
            self._add_path(shape, p, drawn=k == 0, ideal=ideal)

    def _add_path(self, shape: str, points: np.ndarray, drawn: bool, ideal: bool) -> None:
        v = stroke_vector(points)
        if v is None:
            raise ValueError(f"a template of {shape!r} has no extent")
        self._names.append(shape)
        self._vectors.append(v)
        self._angles.append(direction_angles(points))
        self._forms.append(_form(points))
        self._ideal.append(ideal)
        self._drawn.append(drawn)
        self._thresholds = None

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
        form = np.asarray([_form(strokes[i]) for i in ok])
        limit = math.radians(max_rotation_deg)
        score = self._scores(g, angles, form, limit)  # (k, T)
        names = np.asarray(self._names)
        shapes = self.shapes
        per_shape = np.column_stack([score[:, names == s].max(axis=1) for s in shapes])
        own = self.thresholds(limit)
        nearest_ideal = np.asarray(self._ideal)[np.argmax(score, axis=1)]
        for row, i in enumerate(ok):
            scores = {s: float(per_shape[row, c]) for c, s in enumerate(shapes)}
            best = shapes[int(np.argmax(per_shape[row]))]
            needed = max(min_score, own.get(best, 0.0))
            if nearest_ideal[row]:
                needed = max(needed, min_score + BUILTIN_EXTRA_SCORE)
            out[i] = Match(best if scores[best] >= needed else None, scores[best], best, scores)
        return out

    def thresholds(self, limit: float = math.radians(30.0)) -> dict[str, float]:
        """Per shape with two or more drawn templates: the mean, over those templates, of the
        best score against another of them, less ``TIGHTNESS_MARGIN``. A shape its writer
        draws the same way each time asks more of a stroke than one drawn loosely, so a
        near miss of a tight shape (one's brace taken for one's bracket) is rejected."""
        if self._thresholds is None:
            self._thresholds = {}
            names = np.asarray(self._names)
            drawn = np.flatnonzero(self._drawn)
            g = np.asarray(self._vectors)[drawn].reshape(len(drawn), -1, 2)
            scores = (
                self._scores(g, np.asarray(self._angles)[drawn], self._form()[drawn], limit)
                if len(drawn)
                else np.zeros((0, len(names)))
            )
            for shape in self.shapes:
                rows = np.flatnonzero(names[drawn] == shape)
                if len(rows) < 2:
                    continue
                own = scores[np.ix_(rows, drawn[rows])]
                np.fill_diagonal(own, -np.inf)
                agreement = float(own.max(axis=1).mean())
                self._thresholds[shape] = agreement - TIGHTNESS_MARGIN
        return self._thresholds

    def _form(self) -> np.ndarray:
        return np.asarray(self._forms, dtype=float).reshape(-1, 2)

    def _scores(
        self, g: np.ndarray, angles: np.ndarray, form: np.ndarray, limit: float
    ) -> np.ndarray:
        """Scores (k, T) of strokes (k, n, 2) with direction ``angles`` (k, N_DIRECTIONS)
        and ``form`` (k, 2: total turning, corner share) against every template, in chunks
        that bound the memory."""
        t = np.asarray(self._vectors).reshape(len(self._vectors), -1, 2)
        ta = np.asarray(self._angles)
        step = max(1, _CELLS_PER_CHUNK // (len(t) * N_DIRECTIONS**2))
        own = self._form()
        turning = np.abs(np.log(form[:, None, 0] / own[None, :, 0]))
        corners = np.abs(form[:, None, 1] - own[None, :, 1])
        form_cost = TURNING_WEIGHT * np.maximum(turning - TURNING_SLACK, 0.0)
        form_cost += CORNER_WEIGHT * np.maximum(corners - CORNER_SLACK, 0.0)
        form_cost[:, np.asarray(self._ideal, dtype=bool)] = 0.0  # (k, T)
        out = []
        for lo in range(0, len(g), step):
            a, b = _rotation_terms(t, g[lo : lo + step])  # Li 2010, eqs. 3-4
            theta = np.clip(np.arctan2(b, a), -limit, limit)  # (k, T)
            cosine = a * np.cos(theta) + b * np.sin(theta)  # Li 2010, eq. 5
            turned = angles[lo : lo + step, None, :, None] + theta[:, :, None, None]
            cost = 1.0 - np.cos(ta[None, :, None, :] - turned)  # (k, T, stroke i, template j)
            warped = 1.0 - _warped_cost(cost, BAND) / N_DIRECTIONS
            mixed = (1.0 - PROTRACTOR_WEIGHT) * warped + PROTRACTOR_WEIGHT * cosine
            out.append(np.clip(mixed - form_cost[lo : lo + step], 0.0, 1.0))
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
            base.add(doc["shape"], points, ideal=True)
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
            base._add_path(shape, points, drawn=False, ideal=True)
    return base


def template_set(
    user: Mapping[str, Iterable[np.ndarray]] | None = None, builtin: bool = True
) -> TemplateSet:
    """Built-in templates (unless ``builtin`` is False) plus ``user`` templates."""
    out = builtin_templates() if builtin else TemplateSet()
    if user:
        out.add_all(user)
    return out
