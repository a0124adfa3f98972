"""Unistroke templates by shape, matched all at once: the built-in ones (templates/*.json, our
own drawings made by program in shapes.py, taken from nobody's strokes) and a person's own.

A built-in shape marked closed is also matched from ``START_POINTS`` start points, and one
marked reversible (closed ones too) the other way round. How alike a stroke and a template
are is stroke_similarity.py; which shape, if any, a stroke is taken for is stroke_verdict.py
(the recognizer as a whole: docs/strokes.md). A person's templates are rivalled by the built-in
ones (stroke_verdict.catalogue_says): those in the set, or with ``builtin_templates`` off, a
``catalogue`` that is not matched, only asked whether a stroke is a shape the person drew none
of.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping, Sequence
from importlib import resources

import numpy as np

from hapticdesk.gestures.strokes.shapes import resample
from hapticdesk.gestures.strokes.stroke_similarity import (
    DEFAULT_CHOICES,
    N_POINTS,
    ScoreChoices,
    StrokeFeatures,
    similarity,
    stroke_features,
    stroke_vector,
)
from hapticdesk.gestures.strokes.stroke_verdict import (
    Catalogue,
    Match,
    Twins,
    agreement,
    catalogue_twins,
    judge,
    medians,
    separation,
    separation_margin,
)

START_POINTS = 32  # start points tried for closed templates


def _start_points(points: np.ndarray, count: int) -> list[np.ndarray]:
    """A closed path started at ``count`` points spread along it."""
    ring = resample(np.vstack([points, points[:1]]), N_POINTS * 4 + 1)[:-1]
    out = []
    for k in range(count):
        rolled = np.roll(ring, -k * len(ring) // count, axis=0)
        out.append(np.vstack([rolled, rolled[:1]]))
    return out


class TemplateSet:
    """Templates by shape name, matched all at once."""

    def __init__(
        self, choices: ScoreChoices = DEFAULT_CHOICES, catalogue: TemplateSet | None = None
    ) -> None:
        """``catalogue``: built-in templates not matched, only a rival to the drawn ones
        where the set has no built-in templates of its own."""
        self.choices = choices
        self.catalogue = catalogue
        self._names: list[str] = []
        self._paths: list[np.ndarray] = []
        self._ideal: list[bool] = []  # drawn by program: its form is not compared
        self._drawn: list[bool] = []  # as drawn, not a start point or direction variant
        self._features: StrokeFeatures | None = None
        self._own: dict[float, dict[str, float]] = {}  # rotation limit -> agreement by shape
        self._twins: dict[float, Twins] = {}  # rotation limit -> catalogue_twins
        self._apart: dict[float, float] = {}  # rotation limit -> separation

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
        self._twins = {}
        self._apart = {}

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
        catalogue = self._catalogue(features, scores, max_rotation_deg)
        apart = self._separation(max_rotation_deg)
        sizes = (features.sizes, self.features().sizes)
        verdicts = judge(
            scores, self.names, self.ideal, min_score, own, self.choices, catalogue, apart, sizes
        )
        for i, verdict in zip(ok.tolist(), verdicts, strict=True):
            out[i] = verdict
        return out

    def thresholds(self, max_rotation_deg: float = 30.0) -> dict[str, float]:
        """Per shape with two or more drawn templates, the score a stroke needs besides
        ``min_score``: their own agreement (:func:`agreement`) less the :meth:`margin`. A shape its
        writer draws the same way each time asks more of a stroke than one drawn loosely,
        so a near miss of a tight shape (one's brace taken for one's bracket) is rejected."""
        own = self._agreement(max_rotation_deg)
        return {shape: v - self.margin(max_rotation_deg) for shape, v in own.items()}

    def margin(self, max_rotation_deg: float = 30.0) -> float:
        """The most a stroke may fall below its shape's agreement: ``choices.margin_share``
        of the set's :func:`separation` where that is more than ``choices.margin`` (and only
        for a stroke the catalogue takes for the same shape, of at least
        ``choices.least_size``: stroke_verdict.Nearest.margin), else ``choices.margin``."""
        return float(separation_margin(self.choices, self._separation(max_rotation_deg)))

    def _catalogue(
        self, strokes: StrokeFeatures, scores: np.ndarray, max_rotation_deg: float
    ) -> Catalogue | None:
        """The built-in templates as a rival to the drawn ones (stroke_verdict.Catalogue):
        the set's own, else ``catalogue``'s; None without drawn templates or a catalogue."""
        ideal, drawn = self.ideal, np.asarray(self._drawn) & ~self.ideal
        source = self._catalogue_source()
        if not drawn.any() or source is None:
            return None
        if source is self:
            names, against = self.names[ideal], scores[:, ideal]
        else:
            names = source.names
            parts = similarity(strokes, source.features(), max_rotation_deg, source.ideal)
            against = parts.score(self.choices)
        twins = self._twins.get(max_rotation_deg)
        if twins is None:
            mine = self._against_catalogue(source, drawn, max_rotation_deg)
            twins = catalogue_twins(mine, self.names[drawn], names)
            self._twins[max_rotation_deg] = twins
        return Catalogue(against, names, twins)

    def _catalogue_source(self) -> TemplateSet | None:
        """Where the rival built-in templates are: the set itself when it has any, else
        ``catalogue`` (None without one)."""
        if self.ideal.any():
            return self
        if self.catalogue is not None and len(self.catalogue):
            return self.catalogue
        return None

    def _against_catalogue(
        self, source: TemplateSet, drawn: np.ndarray, max_rotation_deg: float
    ) -> np.ndarray:
        """The scores of the ``drawn`` templates against ``source``'s built-in ones."""
        mine = self.features().take(drawn)
        ideal_of = np.asarray(source.ideal)[source.ideal]
        parts = similarity(mine, source.features().take(source.ideal), max_rotation_deg, ideal_of)
        return parts.score(self.choices)

    def _separation(self, max_rotation_deg: float) -> float:
        """:func:`separation` of the templates people drew (against each other and the
        catalogue's shapes they drew none of; computed once per rotation limit); nan
        without a catalogue (nothing to measure it against: ``choices.margin`` then) or when
        the margin is not a share of it."""
        apart = self._apart.get(max_rotation_deg)
        if apart is None:
            apart = math.nan
            drawn = np.asarray(self._drawn, dtype=bool) & ~self.ideal
            source = self._catalogue_source()
            if self.choices.margin_share is not None and source is not None and drawn.sum() > 1:
                mine = self.features().take(drawn)
                parts = similarity(mine, mine, max_rotation_deg, self.ideal[drawn])
                against = self._against_catalogue(source, drawn, max_rotation_deg)
                names = source.names[source.ideal]
                found = medians(parts.score(self.choices), self.names[drawn], against, names)
                apart = separation(found)
            self._apart[max_rotation_deg] = apart
        return apart

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
    """Built-in templates (unless ``builtin`` is False: then they are only the ``catalogue``
    that rivals the ``user`` templates, made only where there is one to rival: 291
    templates read and expanded, 20-30 ms) plus ``user`` templates."""
    drawn = {shape: list(paths) for shape, paths in (user or {}).items()}
    if builtin:
        out = builtin_templates()
    else:
        rivalled = any(drawn.values())
        out = TemplateSet(catalogue=builtin_templates() if rivalled else None)
    if drawn:
        out.add_all(drawn)
    return out
