"""The verdict on strokes from their scores against templates: the nearest shape, and whether
it is near enough to be taken.

The nearest shape (:func:`nearest`) is the one whose ⌊√n⌋ best of its n templates as people
drew them score highest on average, or whose built-in template scores higher
(:func:`neighbourhood`: k-nearest neighbours, the best one for a person's three templates);
it is accepted (:meth:`Nearest.accepted`) when its best score reaches ``min_score`` (plus
``builtin_extra`` when that template is a built-in one, not compared by form) and, for a shape
with two or more templates as drawn, their own agreement (:func:`agreement`: the lowest, over
them, of the best score of each against another) less the margin (:meth:`Nearest.margin`:
``margin``, or a share of the set's :func:`separation` where that is more, for a stroke the
catalogue takes for the same shape and not much smaller than the person's templates of it):
a shape its writer draws the same way each time asks more of a stroke than one drawn
loosely, so a stroke of another shape near it is rejected. The choices are :class:`ScoreChoices`
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


class Medians(NamedTuple):
    """How a set's drawn templates stand to each other, on medians over pairs (so not on how
    many templates a shape has): ``shapes`` (S,); ``within`` (S,), the median score of a
    shape's templates against each other (nan with fewer than two); ``between`` (S, S), at
    [o, s] the median score of shape o's templates against shape s's; ``catalogue`` (S, C),
    the median over a shape's templates of their best score against each catalogue shape of
    ``catalogue_shapes`` (C,)."""

    shapes: list[str]
    within: np.ndarray
    between: np.ndarray
    catalogue: np.ndarray
    catalogue_shapes: list[str]


def medians(
    scores: np.ndarray,
    names: np.ndarray,
    catalogue: np.ndarray | None = None,
    catalogue_names: np.ndarray | None = None,
) -> Medians:
    """The :class:`Medians` of templates of shapes ``names`` (T,) from their ``scores``
    (T, T) against each other and ``catalogue`` (T, B) against built-in templates of shapes
    ``catalogue_names`` (B,) (none: no catalogue)."""
    shapes = list(dict.fromkeys(names.tolist()))
    rows = [np.flatnonzero(names == s) for s in shapes]
    scores = np.asarray(scores, dtype=float)
    count = len(shapes)
    within, between = _pair_medians(scores, rows)
    c_shapes: list[str] = []
    against = np.zeros((count, 0))
    if catalogue is not None and catalogue_names is not None and len(catalogue_names):
        c_shapes = list(dict.fromkeys(catalogue_names.tolist()))
        per = _per_shape(np.asarray(catalogue, dtype=float), catalogue_names, c_shapes)
        against = np.asarray([np.median(per[r], axis=0) for r in rows]).reshape(count, -1)
    return Medians(shapes, within, between, against, c_shapes)


def _pair_medians(scores: np.ndarray, rows: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """:class:`Medians` ``within`` and ``between`` from the templates' ``scores`` (T, T) and
    each shape's rows: in one call when every shape has as many templates (a person's
    three, other writers' 120), else block by block."""
    count, size = len(rows), {len(r) for r in rows}
    within = np.full(count, np.nan)
    if len(size) == 1:
        n = size.pop()
        order = np.concatenate(rows)
        blocks = scores[np.ix_(order, order)].reshape(count, n, count, n).transpose(0, 2, 1, 3)
        between = np.median(blocks.reshape(count, count, n * n), axis=2)
        if n >= 2:
            own = blocks[np.arange(count), np.arange(count)].reshape(count, n * n)
            within = np.median(own[:, ~np.eye(n, dtype=bool).ravel()], axis=1)
        np.fill_diagonal(between, 0.0)
        return within, between
    between = np.zeros((count, count))
    for j, mine in enumerate(rows):
        for i, theirs in enumerate(rows):
            block = scores[np.ix_(theirs, mine)]
            if i != j:
                between[i, j] = np.median(block)
            elif len(mine) >= 2:
                within[j] = np.median(block[~np.eye(len(mine), dtype=bool)])
    return within, between


def separation(found: Medians, without: str = "", catalogue_without: str = "") -> float:
    """How far apart a set keeps its shapes: the mean, over its shapes with two or more
    templates, of their :class:`Medians` ``within`` less the highest median score against
    them of another shape, another of the set's or a catalogue shape the set has none of
    (so two shapes far apart are still judged against the shapes a person might draw; with
    neither, 0: a set with no catalogue passes nan, unmeasured, to :meth:`Nearest.margin`).
    ``without``: the set without that shape (a layout that lacks it: the catalogue's shape
    of that name then counts); ``catalogue_without``: the catalogue without that shape. nan
    when no shape has two templates (unmeasured)."""
    keep = np.asarray([s != without for s in found.shapes], dtype=bool)
    drawn = set(np.asarray(found.shapes, dtype=object)[keep].tolist())
    columns = np.asarray(
        [s not in drawn and s != catalogue_without for s in found.catalogue_shapes], dtype=bool
    )
    others = keep[:, None] & ~np.eye(len(keep), dtype=bool)
    near = np.maximum(
        np.where(others, found.between, 0.0).max(axis=0, initial=0.0),
        found.catalogue[:, columns].max(axis=1, initial=0.0),
    )
    gaps = (found.within - near)[keep & ~np.isnan(found.within)]
    return float(gaps.mean()) if len(gaps) else math.nan


def separation_margin(choices: ScoreChoices, apart: np.ndarray | float) -> np.ndarray:
    """The margin a set's :func:`separation` ``apart`` allows a stroke the catalogue agrees
    with: ``choices.margin_share`` of it where that is more than ``choices.margin``, else
    ``choices.margin`` (also without a share, or with the separation unmeasured: nan)."""
    apart = np.asarray(apart, dtype=float)
    if choices.margin_share is None:
        return np.full(apart.shape, choices.margin)
    wider = np.maximum(choices.margin_share * apart, choices.margin)
    return np.where(np.isnan(apart), choices.margin, wider)


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
    ``floor`` (k,), the least it gives the person's templates of that shape; ``separation``
    (k,), the :func:`separation` of the set each stroke was judged against; ``size`` (k,),
    the stroke's size over the least of its shape's drawn templates' (nan: not measured)."""

    shapes: list[str]
    per_shape: np.ndarray
    shape: np.ndarray
    score: np.ndarray
    own: np.ndarray
    built_in: np.ndarray
    rival: np.ndarray
    confirmed: np.ndarray
    floor: np.ndarray
    separation: np.ndarray
    size: np.ndarray

    def margin(self, choices: ScoreChoices = DEFAULT_CHOICES) -> np.ndarray:
        """The margin below its shape's agreement each stroke may fall (k,): with
        ``choices.margin_share``, that share of its set's separation where it is more than
        ``choices.margin`` and the stroke is :meth:`trusted`, else ``choices.margin`` (also
        without a separation: nan, a set with no catalogue to measure it against). The
        separation only adds to the fixed margin, and only where the catalogue agrees and
        the stroke is not much smaller than the person's templates of its shape."""
        fixed = np.full(len(self.shape), choices.margin)
        if choices.margin_share is None:
            return fixed
        return np.where(self.trusted(choices), separation_margin(choices, self.separation), fixed)

    def trusted(self, choices: ScoreChoices = DEFAULT_CHOICES) -> np.ndarray:
        """Whether each stroke may have more than ``choices.margin`` (k,) bool: the built-in
        catalogue's nearest shape is the one it is taken for (``confirmed``) and it is at
        least ``choices.least_size`` of its shape's least drawn template (or unmeasured)."""
        big = ~(self.size < choices.least_size)
        return np.isfinite(self.confirmed) & big

    def accepted(self, min_score: float, choices: ScoreChoices = DEFAULT_CHOICES) -> np.ndarray:
        """Whether each stroke is taken for its nearest shape (k,) bool: its score reaches
        ``min_score`` (plus ``choices.builtin_extra`` when its nearest template is built-in)
        and its shape's agreement less the :meth:`margin` (without a share,
        ``choices.confirmed_margin`` where the catalogue confirms the shape: at the
        catalogue's own threshold, ``min_score`` plus ``choices.builtin_extra``, and its floor
        less the margin), and no rival shape of the catalogue reaches that threshold."""
        catalogue = min_score + choices.builtin_extra
        margin = self.margin(choices)
        if choices.margin_share is None:
            confirmed = (self.confirmed >= catalogue) & (self.confirmed >= self.floor - margin)
            margin = np.where(confirmed, choices.confirmed_margin, margin)
        needed = np.maximum(min_score, self.own - margin)
        extra = np.where(self.built_in, catalogue, -np.inf)
        return (self.score >= np.maximum(needed, extra)) & (self.rival < catalogue)


def nearest(
    scores: np.ndarray,
    names: np.ndarray,
    ideal: np.ndarray,
    own: Mapping[str, float],
    catalogue: Catalogue | None = None,
    apart: float = math.nan,
    sizes: tuple[np.ndarray, np.ndarray] | None = None,
) -> Nearest:
    """The :class:`Nearest` shapes of k strokes from their ``scores`` (k, T) against
    templates of shapes ``names`` (T,), ``ideal`` (T,) those drawn by program, ``own`` the
    :func:`agreement` of the shapes that have one; ``catalogue`` the built-in templates as a
    rival (none: no rival); ``apart`` the set's :func:`separation`; ``sizes`` those of the
    strokes (k,) and the templates (T,)."""
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
    return Nearest(
        shapes,
        per_shape,
        chosen,
        per_shape[rows, best],
        agreed[best],
        built_in,
        *says,
        np.full(len(best), apart),
        _size(sizes, names, ideal, chosen),
    )


def _size(
    sizes: tuple[np.ndarray, np.ndarray] | None,
    names: np.ndarray,
    ideal: np.ndarray,
    chosen: np.ndarray,
) -> np.ndarray:
    """Each stroke's size over the least of its chosen shape's drawn templates' (nan
    without sizes or drawn templates)."""
    if sizes is None:
        return np.full(len(chosen), np.nan)
    strokes, templates = sizes
    least = {
        shape: float(np.min(templates[(names == shape) & ~ideal], initial=np.inf))
        for shape in set(chosen.tolist())
    }
    out = np.asarray([least[c] for c in chosen], dtype=float)
    return np.where(np.isfinite(out), np.asarray(strokes, dtype=float) / out, np.nan)


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
    apart: float = math.nan,
    sizes: tuple[np.ndarray, np.ndarray] | None = None,
) -> list[Match]:
    """The verdicts on k strokes from their ``scores`` (k, T) against templates of shapes
    ``names`` (T,) (:func:`nearest`, :meth:`Nearest.accepted`)."""
    if not len(scores) or not len(names):
        return [Match(None, 0.0, None, {}) for _ in range(len(scores))]
    found = nearest(scores, names, ideal, own, catalogue, apart, sizes)
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
