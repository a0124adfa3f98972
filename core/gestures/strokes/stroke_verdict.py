"""The verdict on strokes from their scores against templates: the nearest shape, and whether
it is near enough to be taken.

The nearest shape (:func:`nearest`) is the one whose ⌊√n⌋ best of its n templates as people
drew them score highest on average, or whose built-in template scores higher
(:func:`neighbourhood`: k-nearest neighbours, the best one for a person's three templates);
it is accepted (:meth:`Nearest.accepted`) when its best score reaches ``min_score`` (plus
``builtin_extra`` when that template is a built-in one, not compared by form) and, for a shape
with two or more templates as drawn, their own agreement (:func:`agreement`: the lowest, over
them, of the best score of each against another) less the ``margin``: a shape its writer
draws the same way each time asks more of a stroke than one drawn loosely, so a stroke of
another shape near it is rejected. The choices are :class:`ScoreChoices`
(stroke_similarity.py), made by leave-one-writer-out (docs/strokes.md).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from hapticdesk.gestures.strokes.stroke_similarity import DEFAULT_CHOICES, ScoreChoices


@dataclass(frozen=True)
class Match:
    """The verdict on a stroke: ``shape`` None when nothing matched well enough."""

    shape: str | None
    score: float
    best_shape: str | None  # the nearest shape even when rejected
    scores: dict[str, float]  # best score per shape


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
