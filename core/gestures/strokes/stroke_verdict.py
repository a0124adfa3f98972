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


class Twins(NamedTuple):
    """How a person's templates stand to the catalogue, per shape they drew: ``best``, the
    best score of its templates against each catalogue shape, and ``lowest``, the lowest of
    its templates' scores against the catalogue's same shape (absent where it has none)."""

    best: Mapping[str, Mapping[str, float]]
    lowest: Mapping[str, float]


class Catalogue(NamedTuple):
    """The built-in templates as a rival to a person's own: k strokes' ``scores`` (k, B)
    against them, their shapes ``names`` (B,), and the person's templates' ``twins``
    (:func:`catalogue_twins`)."""

    scores: np.ndarray
    names: np.ndarray
    twins: Twins


def catalogue_twins(scores: np.ndarray, names: np.ndarray, catalogue_names: np.ndarray) -> Twins:
    """The :class:`Twins` of drawn templates of shapes ``names`` (T,) from their ``scores``
    (T, B) against the catalogue of shapes ``catalogue_names`` (B,)."""
    shapes = list(dict.fromkeys(catalogue_names.tolist()))
    per = _per_shape(scores, catalogue_names, shapes)
    drawn = list(dict.fromkeys(names.tolist()))
    best = {s: dict(zip(shapes, per[names == s].max(axis=0).tolist(), strict=True)) for s in drawn}
    lowest = {s: float(per[names == s, shapes.index(s)].min()) for s in drawn if s in shapes}
    return Twins(best, lowest)


class CatalogueSays(NamedTuple):
    """What the catalogue says of k strokes taken for shapes a person drew: ``rival`` (k,),
    its best score for a shape the person drew none of that is nearer than the taken one
    (-inf where none is), ``confirmed`` (k,), its score for the taken shape where that is
    its own nearest shape (-inf where not), and ``floor`` (k,), the least it gives the
    person's templates of that shape (inf where it has none)."""

    rival: np.ndarray
    confirmed: np.ndarray
    floor: np.ndarray


def catalogue_says(chosen: np.ndarray, drawn: np.ndarray, catalogue: Catalogue) -> CatalogueSays:
    """For k strokes taken for ``chosen`` (k,), with ``drawn`` the shapes of a person's
    templates: a rival is a shape with no template in ``drawn`` whose catalogue score beats
    both the catalogue's score for the chosen shape and every one of the chosen shape's drawn
    templates against it (``catalogue.twins``: a person's shape the catalogue itself takes
    for another is not rivalled by it). Strokes taken for a shape nobody drew: neither."""
    shapes = list(dict.fromkeys(catalogue.names.tolist()))
    per = _per_shape(catalogue.scores, catalogue.names, shapes)
    column = {shape: j for j, shape in enumerate(shapes)}
    rows = np.arange(len(chosen))
    mine = np.asarray([column.get(c, -1) for c in chosen], dtype=int)
    own = np.where(mine >= 0, per[rows, mine], -np.inf)
    recorded = set(drawn.tolist())
    rival = np.full(len(chosen), -np.inf)
    for shape in shapes:
        if shape in recorded:
            continue
        twin = np.asarray([catalogue.twins.best.get(c, {}).get(shape, np.inf) for c in chosen])
        score = per[:, column[shape]]
        rival = np.where((score > own) & (score > twin), np.maximum(rival, score), rival)
    by_person = np.isin(chosen, list(recorded))
    floor = np.asarray([catalogue.twins.lowest.get(c, np.inf) for c in chosen])
    confirmed = np.where(by_person & (own >= per.max(axis=1)), own, -np.inf)
    return CatalogueSays(np.where(by_person, rival, -np.inf), confirmed, floor)


def _per_shape(scores: np.ndarray, names: np.ndarray, shapes: list[str]) -> np.ndarray:
    """The best of ``scores`` (k, T) per shape of ``names`` (T,): (k, S)."""
    return np.column_stack([scores[:, names == s].max(axis=1) for s in shapes])


class Nearest(NamedTuple):
    """Each stroke's nearest shape among the templates: ``shapes`` (S,) and ``per_shape``
    (k, S), the best score against each; for the nearest, ``shape`` (k,), ``score`` (k,),
    ``own`` (k,), its templates' :func:`agreement` (-inf without), ``built_in`` (k,),
    whether its nearest template was drawn by program, and what the built-in catalogue says
    (:func:`catalogue_says`): ``rival`` (k,), its score for a nearer shape the person drew
    none of, ``confirmed`` (k,), its score for the same shape where it is its nearest, and
    ``floor`` (k,), the least it gives the person's templates of that shape."""

    shapes: list[str]
    per_shape: np.ndarray
    shape: np.ndarray
    score: np.ndarray
    own: np.ndarray
    built_in: np.ndarray
    rival: np.ndarray
    confirmed: np.ndarray
    floor: np.ndarray

    def accepted(self, min_score: float, choices: ScoreChoices = DEFAULT_CHOICES) -> np.ndarray:
        """Whether each stroke is taken for its nearest shape (k,) bool: its score reaches
        ``min_score`` (plus ``choices.builtin_extra`` when its nearest template is built-in)
        and its shape's agreement less ``choices.margin`` (``choices.confirmed_margin`` where
        the catalogue confirms the shape: at the catalogue's own threshold, ``min_score`` plus
        ``choices.builtin_extra``, and its floor less ``choices.margin``), and no rival shape
        of the catalogue reaches that threshold."""
        catalogue = min_score + choices.builtin_extra
        floor = self.floor - choices.margin
        confirmed = (self.confirmed >= catalogue) & (self.confirmed >= floor)
        margin = np.where(confirmed, choices.confirmed_margin, choices.margin)
        needed = np.maximum(min_score, self.own - margin)
        extra = np.where(self.built_in, catalogue, -np.inf)
        return (self.score >= np.maximum(needed, extra)) & (self.rival < catalogue)


def nearest(
    scores: np.ndarray,
    names: np.ndarray,
    ideal: np.ndarray,
    own: Mapping[str, float],
    catalogue: Catalogue | None = None,
) -> Nearest:
    """The :class:`Nearest` shapes of k strokes from their ``scores`` (k, T) against
    templates of shapes ``names`` (T,), ``ideal`` (T,) those drawn by program, ``own`` the
    :func:`agreement` of the shapes that have one; ``catalogue`` the built-in templates as a
    rival (none: no rival)."""
    shapes = list(dict.fromkeys(names.tolist()))
    ideal = np.asarray(ideal, dtype=bool)
    per_shape = _per_shape(scores, names, shapes)
    best = np.argmax(neighbourhood(scores, names, ideal, shapes), axis=1)
    agreed = np.asarray([own.get(s, -np.inf) for s in shapes])
    rows = np.arange(len(best))
    chosen = np.asarray(shapes, dtype=object)[best]
    mine = np.where(names[None, :] == chosen[:, None], scores, -np.inf)
    built_in = ideal[np.argmax(mine, axis=1)]
    nothing = np.full(len(best), -np.inf)
    says = CatalogueSays(nothing, nothing, -nothing)
    if catalogue is not None:
        said = catalogue_says(chosen, names[~ideal], catalogue)
        rival, confirmed = (np.where(built_in, -np.inf, a) for a in said[:2])
        says = CatalogueSays(rival, confirmed, said.floor)
    return Nearest(shapes, per_shape, chosen, per_shape[rows, best], agreed[best], built_in, *says)


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
    catalogue: Catalogue | None = None,
) -> list[Match]:
    """The verdicts on k strokes from their ``scores`` (k, T) against templates of shapes
    ``names`` (T,) (:func:`nearest`, :meth:`Nearest.accepted`)."""
    if not len(scores) or not len(names):
        return [Match(None, 0.0, None, {}) for _ in range(len(scores))]
    found = nearest(scores, names, ideal, own, catalogue)
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
