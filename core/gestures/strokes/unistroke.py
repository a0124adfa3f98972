"""Unistroke shape recognition: $1 preprocessing, Protractor's rotation and cosine, an elastic
match of the directions of motion.

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
at the clipped angle), so ``caret`` is not a turned ``v``. Built-in shapes marked closed
are also matched from 32 start points, and those marked reversible (closed ones too) the
other way round.

The score of a stroke against a template (:class:`Similarity`): Protractor's cosine at the
clipped rotation (where the path goes) mixed with the agreement of its directions of motion
at ``N_DIRECTIONS`` steps of equal arc length, turned the same way and aligned by dynamic
time warping within ``BAND`` steps (1 − the least total cost of 1 − cos of the angle
between matched directions, over ``N_DIRECTIONS``: it forgives timing), 0.3 and 0.7. Against a
template a person drew, a difference in form costs too: in total turning (a brace turns
about twice as much as a bracket) and in the share of the turning in the sharpest few
turns (corners against curves: rectangle against circle); the built-in templates, drawn by
program with exact corners, are not compared by form. The score is clipped to 0..1.

The verdict (:func:`judge`): the nearest shape is the one whose ⌊√n⌋ best of its n templates
as people drew them score highest on average, or whose built-in template scores higher
(:func:`neighbourhood`: k-nearest neighbours, the best one for a person's three templates);
it is accepted when its best score reaches ``min_score`` (plus ``builtin_extra`` when that
template is a built-in one, not compared by form) and, for a shape with two or more
templates as drawn, their own agreement (the lowest, over them, of the best score of each
against another) less the ``margin``: a shape its writer draws the same way each time asks
more of a stroke than one drawn loosely, so a stroke of another shape near it is rejected.

Every choice in :class:`ScoreChoices` (the mix, whether form counts, the margin, what a
built-in template asks) was made by leave-one-writer-out on the $1 logs of five people:
made on four, measured on the fifth, all five ways; every fold made the same but for the
margin (0.055-0.08), and the shipped ones are the same procedure on all five
(``python scripts/stroke_lowo.py DIR``; docs/strokes.md). The built-in templates are our own
drawings (shapes.py), taken from nobody's strokes. Matching is a few array operations over
all templates; the warping loops over the band's cells, not over templates or samples.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from importlib import resources
from typing import NamedTuple

import numpy as np

from hapticdesk.gestures.strokes.shapes import resample

N_POINTS = 64  # points of Protractor's vector (the rotation and the cosine)
START_POINTS = 32  # start points tried for closed templates
N_DIRECTIONS = 32  # directions of motion compared by the elastic match
BAND = 3  # the warping's band (Sakoe & Chiba's r), in steps: about a tenth of a stroke
TURNING_STEPS = 12  # directions over which the total turning of a path is summed
#: a stroke's total turning may differ from a template's by this much (log ratio, about
#: ±22 %) at no cost; beyond it every unit of log ratio costs the form weight
TURNING_SLACK = 0.2
MIN_TURNING = math.pi / 2  # a quarter turn: less is an about straight path
#: corners against curves: the share of a path's turning in its CORNER_TURNS sharpest turns
#: (of N_DIRECTIONS) is about 1 for a rectangle or a bracket, well below for a circle or a
#: brace; a difference beyond CORNER_SLACK costs the form weight per unit
CORNER_TURNS = 4
CORNER_SLACK = 0.1
_PAIRS_PER_CHUNK = 1 << 16  # bounds the memory of a batch: strokes × templates a chunk


@dataclass(frozen=True)
class ScoreChoices:
    """The recognizer's choices, each made by leave-one-writer-out (docs/strokes.md)."""

    #: share of the warped directions in the score; the rest is Protractor's cosine
    direction_weight: float = 0.7
    #: what a unit of difference in form (total turning, corner share) beyond its slack
    #: costs, against a template a person drew
    form_weight: float = 0.3
    #: a shape with two or more drawn templates needs a score of its templates' own
    #: agreement less this
    margin: float = 0.065
    #: a stroke whose nearest template is a built-in one (drawn by program, so not compared
    #: by form) needs ``min_score`` plus this: the least that takes at most 1 % of strokes
    #: that are none of the shapes (S, Z, spiral, figure eight, scribble:
    #: ``stroke_accuracy.others``), chosen on no person
    builtin_extra: float = 0.03


DEFAULT_CHOICES = ScoreChoices()


class StrokeFeatures(NamedTuple):
    """What the recognizer compares, for k paths: Protractor's vectors (k, N_POINTS, 2),
    the directions of motion (k, N_DIRECTIONS) and the form (k, 2: total turning, corner
    share)."""

    vectors: np.ndarray
    angles: np.ndarray
    forms: np.ndarray

    def take(self, index: np.ndarray | slice) -> StrokeFeatures:
        return StrokeFeatures(self.vectors[index], self.angles[index], self.forms[index])


class Similarity(NamedTuple):
    """The parts of the score of k strokes against T templates, each (k, T): Protractor's
    cosine and the warped agreement of directions at the clipped rotation, and the form
    differences beyond their slack (0 against a template drawn by program)."""

    cosine: np.ndarray
    warped: np.ndarray
    form: np.ndarray

    def score(self, choices: ScoreChoices = DEFAULT_CHOICES) -> np.ndarray:
        """The score (k, T), 0..1."""
        w = choices.direction_weight
        mixed = w * self.warped + (1.0 - w) * self.cosine - choices.form_weight * self.form
        return np.clip(mixed, 0.0, 1.0)

    def take(self, rows: np.ndarray | slice, columns: np.ndarray | slice) -> Similarity:
        """The parts for some strokes and some templates."""
        return Similarity(*(a[rows][:, columns] for a in self))


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


def stroke_features(paths: Sequence[np.ndarray]) -> tuple[StrokeFeatures, np.ndarray]:
    """The features of the paths that have an extent, and their indices into ``paths``."""
    vectors = [stroke_vector(p) for p in paths]
    ok = np.asarray([i for i, v in enumerate(vectors) if v is not None], dtype=int)
    features = StrokeFeatures(
        np.asarray([vectors[i] for i in ok]).reshape(len(ok), N_POINTS, 2),
        np.asarray([direction_angles(paths[i]) for i in ok]).reshape(len(ok), N_DIRECTIONS),
        np.asarray(
            [(total_turning(paths[i]), corner_share(paths[i])) for i in ok], dtype=float
        ).reshape(len(ok), 2),
    )
    return features, ok


def similarity(
    strokes: StrokeFeatures,
    templates: StrokeFeatures,
    max_rotation_deg: float,
    ideal: np.ndarray | None = None,
) -> Similarity:
    """The parts of the score of every stroke against every template, in chunks that bound
    the memory. ``ideal`` (T,) bool: templates drawn by program, not compared by form."""
    limit = math.radians(max_rotation_deg)
    k, count = len(strokes.vectors), len(templates.vectors)
    turning = np.abs(np.log(strokes.forms[:, None, 0] / templates.forms[None, :, 0]))
    corners = np.abs(strokes.forms[:, None, 1] - templates.forms[None, :, 1])
    form = np.maximum(turning - TURNING_SLACK, 0.0) + np.maximum(corners - CORNER_SLACK, 0.0)
    if ideal is not None:
        form[:, np.asarray(ideal, dtype=bool)] = 0.0
    cosine = np.zeros((k, count))
    warped = np.zeros((k, count))
    t_cos, t_sin = np.cos(templates.angles), np.sin(templates.angles)  # (T, n)
    step = max(1, _PAIRS_PER_CHUNK // max(count, 1))
    for lo in range(0, k, step):
        part = slice(lo, min(k, lo + step))
        a, b = _rotation_terms(templates.vectors, strokes.vectors[part])  # Li 2010, eqs. 3-4
        theta = np.clip(np.arctan2(b, a), -limit, limit)  # (k, T)
        cosine[part] = a * np.cos(theta) + b * np.sin(theta)  # Li 2010, eq. 5
        turned = strokes.angles[part, None, :] + theta[:, :, None]  # (k, T, n)
        cost = _warped_cost(np.cos(turned), np.sin(turned), t_cos, t_sin, BAND)
        warped[part] = 1.0 - cost / N_DIRECTIONS
    return Similarity(cosine, warped, form)


def agreement(scores: np.ndarray, names: np.ndarray, drawn: np.ndarray) -> dict[str, float]:
    """Per shape with two or more templates as drawn: the lowest, over those templates, of
    the best score against another of them (a stroke of the shape as new to the set as each
    template was to the others scores about that). ``scores`` (T, T): the templates against
    each other; ``names`` (T,) their shapes; ``drawn`` (T,) bool: as drawn, not a start
    point or a direction added."""
    out: dict[str, float] = {}
    for shape in dict.fromkeys(names.tolist()):
        rows = np.flatnonzero((names == shape) & drawn)
        if len(rows) < 2:
            continue
        own = scores[np.ix_(rows, rows)].astype(float)
        np.fill_diagonal(own, -np.inf)
        out[shape] = float(own.max(axis=1).min())
    return out


class Nearest(NamedTuple):
    """Each stroke's nearest shape among the templates: ``shapes`` (S,) and ``per_shape``
    (k, S), the best score against each; for the nearest, ``shape`` (k,), ``score`` (k,),
    ``own`` (k,), its templates' :func:`agreement` (-inf without), and ``built_in`` (k,),
    whether its nearest template was drawn by program."""

    shapes: list[str]
    per_shape: np.ndarray
    shape: np.ndarray
    score: np.ndarray
    own: np.ndarray
    built_in: np.ndarray

    def accepted(self, min_score: float, choices: ScoreChoices = DEFAULT_CHOICES) -> np.ndarray:
        """Whether each stroke is taken for its nearest shape (k,) bool: its score reaches
        ``min_score`` (plus ``choices.builtin_extra`` when its nearest template is built-in)
        and its shape's agreement less ``choices.margin``."""
        needed = np.maximum(min_score, self.own - choices.margin)
        extra = np.where(self.built_in, min_score + choices.builtin_extra, -np.inf)
        return self.score >= np.maximum(needed, extra)


def nearest(
    scores: np.ndarray, names: np.ndarray, ideal: np.ndarray, own: Mapping[str, float]
) -> Nearest:
    """The :class:`Nearest` shapes of k strokes from their ``scores`` (k, T) against
    templates of shapes ``names`` (T,), ``ideal`` (T,) those drawn by program, ``own`` the
    :func:`agreement` of the shapes that have one."""
    shapes = list(dict.fromkeys(names.tolist()))
    ideal = np.asarray(ideal, dtype=bool)
    per_shape = np.column_stack([scores[:, names == s].max(axis=1) for s in shapes])
    best = np.argmax(neighbourhood(scores, names, ideal, shapes), axis=1)
    agreed = np.asarray([own.get(s, -np.inf) for s in shapes])
    rows = np.arange(len(best))
    chosen = np.asarray(shapes, dtype=object)[best]
    mine = np.where(names[None, :] == chosen[:, None], scores, -np.inf)
    return Nearest(
        shapes,
        per_shape,
        chosen,
        per_shape[rows, best],
        agreed[best],
        ideal[np.argmax(mine, axis=1)],
    )


def neighbourhood(
    scores: np.ndarray, names: np.ndarray, ideal: np.ndarray, shapes: list[str]
) -> np.ndarray:
    """How near each of k strokes is to each shape (k, S), what :func:`nearest` ranks by: the
    mean of the stroke's k_s best scores against the shape's templates as people drew them,
    k_s = ⌊√n_s⌋ of its n_s such templates (k-nearest neighbours with k growing as √n, the
    usual consistent choice: 1 for the three a person records, so their best; 10 for 120
    strokes of other writers, so one of them drawn like another shape does not decide), or
    its best built-in template's score where that is higher."""
    out = np.empty((len(scores), len(shapes)))
    for j, shape in enumerate(shapes):
        of_shape = names == shape
        out[:, j] = scores[:, of_shape & ideal].max(axis=1, initial=-np.inf)
        drawn = scores[:, of_shape & ~ideal]
        k = math.isqrt(drawn.shape[1])
        if k >= 1:
            top = -np.partition(-drawn, k - 1, axis=1)[:, :k]
            out[:, j] = np.maximum(out[:, j], top.mean(axis=1))
    return out


def judge(
    scores: np.ndarray,
    names: np.ndarray,
    ideal: np.ndarray,
    min_score: float,
    own: Mapping[str, float],
    choices: ScoreChoices = DEFAULT_CHOICES,
) -> list[Match]:
    """The verdicts on k strokes from their ``scores`` (k, T) against templates of shapes
    ``names`` (T,) (:func:`nearest`, :meth:`Nearest.accepted`)."""
    if not len(scores) or not len(names):
        return [Match(None, 0.0, None, {}) for _ in range(len(scores))]
    found = nearest(scores, names, ideal, own)
    taken = found.accepted(min_score, choices)
    return [
        Match(
            str(found.shape[i]) if taken[i] else None,
            float(found.score[i]),
            str(found.shape[i]),
            dict(zip(found.shapes, found.per_shape[i].tolist(), strict=True)),
        )
        for i in range(len(scores))
    ]


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

    def __init__(self, choices: ScoreChoices = DEFAULT_CHOICES) -> None:
        self.choices = choices
        self._names: list[str] = []
        self._paths: list[np.ndarray] = []
        self._ideal: list[bool] = []  # drawn by program: its form is not compared
        self._drawn: list[bool] = []  # as drawn, not a start point or direction variant
        self._features: StrokeFeatures | None = None
        self._own: dict[float, dict[str, float]] = {}  # rotation limit -> agreement by shape

    @property
    def shapes(self) -> list[str]:
        return list(dict.fromkeys(self._names))

    def __len__(self) -> int:
        return len(self._paths)

    @property
    def names(self) -> np.ndarray:
        """Each template's shape (T,), start point and direction variants included."""
        return np.asarray(self._names, dtype=object)

    @property
    def ideal(self) -> np.ndarray:
        """Whether each template was drawn by program (T,) bool."""
        return np.asarray(self._ideal, dtype=bool)

    @property
    def paths(self) -> list[np.ndarray]:
        """Each template's path (T,), as added."""
        return list(self._paths)

    def add(
        self,
        shape: str,
        points: np.ndarray,
        closed: bool = False,
        reversible: bool = False,
        ideal: bool = False,
    ) -> None:
        """Add one template (any units; only its form counts). ``closed``: also from
        START_POINTS start points; ``reversible``: also the other way round. ``ideal``: drawn
        by program (the built-in shapes), whose sharp corners and exact turns people do not
        draw, so a stroke's turning and corners are not compared with it."""
        paths = _start_points(points, START_POINTS) if closed else [np.asarray(points, dtype=float)]
        if reversible:
            paths += [p[::-1] for p in paths]
        for k, p in enumerate(paths):
            if stroke_vector(p) is None:
                raise ValueError(f"a template of {shape!r} has no extent")
            self._names.append(shape)
            self._paths.append(p)
            self._ideal.append(ideal)
            self._drawn.append(k == 0)
        self._features = None
        self._own = {}

    def add_all(self, templates: Mapping[str, Iterable[np.ndarray]]) -> None:
        """Add user templates: shape -> strokes, each used as drawn."""
        for shape, strokes in templates.items():
            for points in strokes:
                self.add(shape, points)

    def features(self) -> StrokeFeatures:
        """The templates' features (computed once)."""
        if self._features is None:
            self._features = stroke_features(self._paths)[0]
        return self._features

    def classify(
        self, points: np.ndarray, min_score: float, max_rotation_deg: float = 30.0
    ) -> Match:
        """Best shape for a stroke; ``shape`` None when its score is below ``min_score``."""
        return self.classify_many([points], min_score, max_rotation_deg)[0]

    def classify_many(
        self, strokes: Sequence[np.ndarray], min_score: float, max_rotation_deg: float = 30.0
    ) -> list[Match]:
        """:meth:`classify` for many strokes at once (the same verdicts, in batches)."""
        out = [Match(None, 0.0, None, {})] * len(strokes)
        if not self._paths:
            return out
        features, ok = stroke_features(strokes)
        if not len(ok):
            return out
        parts = similarity(features, self.features(), max_rotation_deg, np.asarray(self._ideal))
        own = self._agreement(max_rotation_deg)
        scores = parts.score(self.choices)
        verdicts = judge(scores, self.names, self.ideal, min_score, own, self.choices)
        for i, verdict in zip(ok.tolist(), verdicts, strict=True):
            out[i] = verdict
        return out

    def thresholds(self, max_rotation_deg: float = 30.0) -> dict[str, float]:
        """Per shape with two or more drawn templates, the score a stroke needs besides
        ``min_score``: their own agreement (:func:`agreement`) less the margin. A shape its
        writer draws the same way each time asks more of a stroke than one drawn loosely,
        so a near miss of a tight shape (one's brace taken for one's bracket) is rejected."""
        own = self._agreement(max_rotation_deg)
        return {shape: v - self.choices.margin for shape, v in own.items()}

    def _agreement(self, max_rotation_deg: float) -> dict[str, float]:
        """:func:`agreement` of the drawn templates (computed once per rotation limit)."""
        own = self._own.get(max_rotation_deg)
        if own is None:
            features = self.features()
            drawn = np.asarray(self._drawn, dtype=bool)
            if drawn.sum() >= 2:
                mine = features.take(drawn)
                scores = similarity(mine, mine, max_rotation_deg, self.ideal[drawn])
                names = self.names[drawn]
                own = agreement(scores.score(self.choices), names, np.ones(len(names), bool))
            else:
                own = {}
            self._own[max_rotation_deg] = own
        return own


def _rotation_terms(t: np.ndarray, g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """a = Σ t·g and b = Σ t × g over points, for templates t (T, n, 2) and strokes g
    (k, n, 2), each (k, T): turning g by θ gives the dot product a·cos θ + b·sin θ."""
    a = np.einsum("tnd,knd->kt", t, g)
    b = np.einsum("tn,kn->kt", t[:, :, 1], g[:, :, 0]) - np.einsum(
        "tn,kn->kt", t[:, :, 0], g[:, :, 1]
    )
    return a, b


def _warped_cost(
    s_cos: np.ndarray, s_sin: np.ndarray, t_cos: np.ndarray, t_sin: np.ndarray, band: int
) -> np.ndarray:
    """Least total cost of a monotone path from (0, 0) to (n-1, n-1) with steps right, down
    or diagonal and |i − j| ≤ ``band`` (Sakoe & Chiba 1978), where cell (i, j) costs 1 − the
    cosine between the stroke's direction i, (cos, sin) ``s_cos``/``s_sin`` (k, T, n), and
    the template's direction j, ``t_cos``/``t_sin`` (T, n): (k, T). Only the band's cells
    are computed."""
    n = s_cos.shape[-1]
    previous = np.full(s_cos.shape[:-1] + (n + 1,), np.inf)
    previous[..., 0] = 0.0
    for i in range(1, n + 1):
        row = np.full_like(previous, np.inf)
        si_cos, si_sin = s_cos[..., i - 1], s_sin[..., i - 1]
        for j in range(max(1, i - band), min(n, i + band) + 1):
            cost = 1.0 - (si_cos * t_cos[:, j - 1] + si_sin * t_sin[:, j - 1])
            best = np.minimum(np.minimum(previous[..., j], previous[..., j - 1]), row[..., j - 1])
            row[..., j] = cost + best
        previous = row
    return previous[..., n]


def builtin_templates(expand: bool = True, choices: ScoreChoices = DEFAULT_CHOICES) -> TemplateSet:
    """The shipped templates (templates/*.json): our own drawings of the shapes, made by
    program (shapes.py), not taken from anyone's strokes. ``expand``: a closed shape is also
    added from ``START_POINTS`` start points and a reversible one the other way round."""
    out = TemplateSet(choices)
    root = resources.files("hapticdesk.gestures.strokes").joinpath("templates")
    for entry in sorted(root.iterdir(), key=lambda p: p.name):
        if not entry.name.endswith(".json"):
            continue
        doc = json.loads(entry.read_text(encoding="utf-8"))
        closed = expand and bool(doc.get("closed", False))
        reversible = expand and bool(doc.get("reversible", False))
        for stroke in doc["strokes"]:
            out.add(doc["shape"], np.asarray(stroke, dtype=float), closed, reversible, ideal=True)
    return out


def template_set(
    user: Mapping[str, Iterable[np.ndarray]] | None = None, builtin: bool = True
) -> TemplateSet:
    """Built-in templates (unless ``builtin`` is False) plus ``user`` templates."""
    out = builtin_templates() if builtin else TemplateSet()
    if user:
        out.add_all(user)
    return out
