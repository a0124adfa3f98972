"""How alike a stroke and a template are: $1 preprocessing, Protractor's rotation and cosine,
an elastic match of the directions of motion, and the difference in form.

References:
- J. O. Wobbrock, A. D. Wilson, Y. Li, "Gestures without libraries, toolkits or training:
  a $1 recognizer for user interface prototypes", UIST 2007 — resampling to N equidistant
  points, translation to the centroid, a uniform scale.
- Y. Li, "Protractor: a fast and accurate gesture recognizer", CHI 2010 — the stroke as a
  unit vector, and the closed-form best rotation θ* = atan(b / a) with similarity
  a·cos θ + b·sin θ (Li 2010, eqs. 3–5).
- H. Sakoe, S. Chiba, "Dynamic programming algorithm optimization for spoken word
  recognition", IEEE TASSP 1978 — dynamic time warping within a band |i − j| ≤ r.

Changes for a desk: the stroke keeps its orientation (the desk has an up, away from the
user), and the rotation allowed between a stroke and a template is limited to
``max_rotation_deg`` (θ* clipped to the range; a·cos θ + b·sin θ = R·cos(θ − θ*) is largest
at the clipped angle), so ``caret`` is not a turned ``v``.

The score of a stroke against a template (:class:`Similarity`): Protractor's cosine at the
clipped rotation (where the path goes) mixed with the agreement of its directions of motion
at ``N_DIRECTIONS`` steps of equal arc length, turned the same way and aligned by dynamic
time warping within ``BAND`` steps (1 − the least total cost of 1 − cos of the angle
between matched directions, over ``N_DIRECTIONS``: it forgives timing), 0.3 and 0.7. Against a
template a person drew, a difference in form costs too: in total turning (a brace turns
about twice as much as a bracket) and in the share of the turning in the sharpest few
turns (corners against curves: rectangle against circle); the built-in templates, drawn by
program with exact corners, are not compared by form. The score is clipped to 0..1.

Every choice in :class:`ScoreChoices` (the mix, whether form counts, the margins, what a
built-in template asks) was made by leave-one-writer-out on the $1 logs of five people:
made on four, measured on the fifth, all five ways; every fold made the same weights and
``builtin_extra``, the margins differ (``margin`` 0.055-0.08, ``margin_share`` 0.18-0.28,
``least_size`` 0.65-0.7), and the shipped ones are the same procedure on all five
(``python scripts/stroke_lowo.py DIR``; docs/strokes.md). Matching is a few array operations
over all templates; the warping loops over the band's cells, not over templates or samples.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from hapticdesk.gestures.strokes.shapes import resample

N_POINTS = 64  # points of Protractor's vector (the rotation and the cosine)
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
    #: a margin of this share of the set's separation (stroke_verdict.separation: how far
    #: apart its writer keeps their shapes, on medians over pairs of templates) where that
    #: is more than ``margin``, for a stroke the catalogue takes for the same shape and not
    #: smaller than ``least_size`` (stroke_verdict.Nearest.margin); ``confirmed_margin`` is
    #: then not used. None: ``margin`` and ``confirmed_margin`` only
    margin_share: float | None = 0.22
    #: with ``margin_share``: a stroke gets more than ``margin`` only where its size is at
    #: least this share of the least of its shape's drawn templates' (a tap dragged 5 cm
    #: against triangles drawn 15 cm: $1 is scale-invariant); the least share, rounded down
    #: to 0.05, of the training writers' own strokes taken for their shape
    least_size: float = 0.65
    #: the margin instead, for a stroke the built-in catalogue takes for the same shape
    #: (stroke_verdict.catalogue_says), at least ``margin``. Chosen as ``margin`` is, on
    #: unknown shapes the catalogue lacks too: on those it has, the catalogue's rival rule
    #: already rejects them, so a looser margin there costs nothing seen and would pass
    #: unknown shapes the catalogue cannot rival. So chosen, every fold makes it equal to
    #: ``margin`` (a looser one, 0.12, took 23 % of a writer's such shapes)
    confirmed_margin: float = 0.065
    #: a stroke whose nearest template is a built-in one (drawn by program, so not compared
    #: by form) needs ``min_score`` plus this: the least that takes at most 1 % of strokes
    #: that are none of the shapes (S, Z, spiral, figure eight, scribble:
    #: ``stroke_accuracy.others``), chosen on no person
    builtin_extra: float = 0.03


DEFAULT_CHOICES = ScoreChoices()


class StrokeFeatures(NamedTuple):
    """What the recognizer compares, for k paths: Protractor's vectors (k, N_POINTS, 2),
    the directions of motion (k, N_DIRECTIONS), the form (k, 2: total turning, corner
    share) and the size (k,: the diagonal of the bounding box, in the path's units)."""

    vectors: np.ndarray
    angles: np.ndarray
    forms: np.ndarray
    sizes: np.ndarray

    def take(self, index: np.ndarray | slice) -> StrokeFeatures:
        return StrokeFeatures(*(a[index] for a in self))


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


def path_size(points: np.ndarray) -> float:
    """The diagonal of a path's bounding box (its units)."""
    return float(np.hypot(*np.ptp(np.asarray(points, dtype=float), axis=0)))


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
        np.asarray([path_size(paths[i]) for i in ok], dtype=float).reshape(len(ok)),
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
