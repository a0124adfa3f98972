#!/usr/bin/env python3
"""Leave-one-writer-out: the stroke recognizer's choices made on four writers of the $1 logs
and measured on the fifth, all five ways, per speed, with a plain Protractor beside.

The choices (``stroke_similarity.ScoreChoices``) and how each is made on the four training writers:

- ``direction_weight`` (the warped directions' share of the score, the rest Protractor's
  cosine) and ``form_weight`` (whether and how much a difference in form costs): the pair
  of the grid with the best top-1 accuracy, averaged over three protocols on the four
  (a writer's own 3 templates; writer-independent, templates from three of them tested on
  the fourth; the built-in templates), rejection left out;
- ``margin`` (how far below its own templates' agreement a shape still takes a stroke): the
  largest of the grid that accepts at most a target share of unknown shapes the built-in
  catalogue has not either, pooled over the four (with a writer's own 3 templates a shape, a
  shape left out, leave-one-shape-out, and left out of the catalogue: what the margin alone
  must reject); the target is the largest (5 % down to 1 %) at which a margin made on three
  of the four accepts at most 5 % of the fourth's, on their mean (nested: a margin made on
  some writers accepts more of a new writer's unknown shapes);
- ``confirmed_margin`` (the margin for a stroke the built-in catalogue takes for the same
  shape): made the same way, at least ``margin``, on the same unknown shapes, those the
  catalogue lacks too (on the shapes it has, its rival rule already rejects the strokes, so
  the looser margin's cost would not be seen there); on the $1 logs every fold makes it
  equal to ``margin``;
- ``least_size`` (with ``margin_share``: a stroke gets more than ``margin`` only when at least
  this share of its shape's least template): the least, rounded down to SIZE_STEP, over the
  four writers' own strokes (own 3 templates) taken for their shape, of that ratio;
- ``margin_share`` (the share of the set's separation, ``stroke_verdict.separation``, a stroke
  may fall short of its shape's agreement where that is more than ``margin``, the catalogue's
  nearest shape is the taken one and the stroke is not below ``least_size``): made as
  ``margin`` is, on the same unknown shapes, with ``margin`` and ``least_size`` made first;
  ``confirmed_margin`` is then not used (nor made);
- ``builtin_extra`` (what a stroke nearest a built-in template asks beyond ``min_score``):
  the smallest of the grid that accepts at most 1 % of strokes that are none of the shapes
  (S, Z, spiral, figure eight, scribble; ``stroke_accuracy.others``, drawn differently each
  time): chosen on no writer at all.

The nearest shape is the one whose ⌊√n⌋ best templates of the n people drew score highest
on average (``stroke_verdict.neighbourhood``): a fixed rule, not a choice.

Each held-out writer is then measured with the choices its four made: writer-independent
(the four writers' 1,920 strokes as templates), the writer's own 3 templates a shape
(rotated over the 10 repetitions, the 7 others tested), the built-in templates, and unknown
shapes accepted (own 3 templates, each shape left out in turn; "none built-in": left out of
the rival catalogue too). A writer's templates are judged as a layout's own are with
``builtin_templates`` off: the built-in templates their rival catalogue
(``stroke_verdict.catalogue_says``). A plain Protractor (Li 2010:
n = 16, uniform scale, rotation within ``max_rotation_deg``, top-1, no rejection) has the
same templates. The shipped choices are the same procedure on all five writers; they are
shipped when every fold chose the same. Under the table, what each held-out writer's own 3
templates lose, by cause (``own_losses``: the margin, another shape, below ``min_score``,
the catalogue's rival), each stroke with the rotations it was lost in.

    python scripts/stroke_lowo.py $DOLLAR1            # 4-20 min (the machine's load)
    python scripts/stroke_lowo.py $DOLLAR1 --json lowo.json
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import sys
import time
from collections import Counter
from collections.abc import Iterator
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))  # (stroke_accuracy beside this one)

from stroke_accuracy import others, trace_synthetic  # noqa: E402

from hapticdesk.gestures.options import GESTURE_OPTIONS  # noqa: E402
from hapticdesk.gestures.strokes.dollar_logs import SPEEDS, read_logs  # noqa: E402
from hapticdesk.gestures.strokes.shapes import normalised, resample  # noqa: E402
from hapticdesk.gestures.strokes.stroke_similarity import (  # noqa: E402
    DEFAULT_CHOICES,
    ScoreChoices,
    Similarity,
    similarity,
    stroke_features,
)
from hapticdesk.gestures.strokes.stroke_verdict import (  # noqa: E402
    Catalogue,
    Medians,
    Nearest,
    agreement,
    catalogue_twins,
    medians,
    nearest,
    separation,
)
from hapticdesk.gestures.strokes.unistroke import builtin_templates  # noqa: E402

MIN_SCORE = GESTURE_OPTIONS["stroke"]["min_score"].default
MAX_ROTATION = GESTURE_OPTIONS["stroke"]["max_rotation_deg"].default
PROTRACTOR_POINTS = 16
DIRECTION_WEIGHTS = (0.15, 0.3, 0.5, 0.7, 0.85)
FORM_WEIGHTS = (0.0, 0.3)
MARGINS = tuple(round(0.02 + 0.005 * k, 3) for k in range(21))  # 0.02 .. 0.12
SIZE_STEP = 0.05  # least_size is rounded down to this
SHARES = tuple(round(0.1 + 0.01 * k, 2) for k in range(31))  # 0.1 .. 0.4 of the separation
BUILTIN_EXTRAS = tuple(round(0.01 * k, 2) for k in range(13))  # 0 .. 0.12
#: the strokes that are none of the shapes, of stroke_accuracy.others (its partial strokes
#: and dragged taps are measured on the desk, not chosen on: half a circle is a rounded
#: bracket, a dragged tap's few turns a v or a zigzag)
NON_SHAPES = ("S", "Z", "spiral", "figure_eight", "scribble")
UNKNOWN_TARGET = 0.05  # unknown shapes accepted, at most
TARGETS = tuple(round(UNKNOWN_TARGET - 0.0025 * k, 4) for k in range(17))  # 5 % .. 1 %
#: strokes that are none of the shapes accepted, at most: about none (a gesture nobody made
#: is worse than a missed one; a person's unknown shape is at least a shape they meant)
NON_SHAPE_TARGET = 0.01
OWN_TEMPLATES = 3


@dataclass
class Logs:
    """The logs: each stroke's shape, writer, speed and repetition (arrays), and the parts of
    the score of every stroke against every other (and against the built-in templates)."""

    shape: np.ndarray
    writer: np.ndarray
    speed: np.ndarray
    repetition: np.ndarray
    parts: Similarity  # (N, N)
    builtin_parts: Similarity  # (N, B)
    builtin_names: np.ndarray
    builtin_ideal: np.ndarray
    protractor: np.ndarray  # (N, N) plain Protractor's cosine
    builtin_protractor: np.ndarray  # (N, B)
    size: np.ndarray  # (N,) each stroke's bounding diagonal (the logs' pixels)

    @property
    def writers(self) -> list[str]:
        return sorted(set(self.writer.tolist()))


def protractor_vectors(paths: list[np.ndarray]) -> np.ndarray:
    """Plain Protractor vectors (k, n, 2): resampled, centred, of unit length."""
    out = []
    for p in paths:
        q = resample(p, PROTRACTOR_POINTS)
        q = q - q.mean(axis=0)
        out.append(q / max(float(np.linalg.norm(q)), 1e-12))
    return np.asarray(out)


def protractor_cosine(strokes: np.ndarray, templates: np.ndarray) -> np.ndarray:
    """Li 2010 eq. 5 at the best rotation within ±MAX_ROTATION: (k, T)."""
    a = np.einsum("tnd,knd->kt", templates, strokes)
    b = np.einsum("tn,kn->kt", templates[:, :, 1], strokes[:, :, 0]) - np.einsum(
        "tn,kn->kt", templates[:, :, 0], strokes[:, :, 1]
    )
    limit = math.radians(MAX_ROTATION)
    theta = np.clip(np.arctan2(b, a), -limit, limit)
    return a * np.cos(theta) + b * np.sin(theta)


def load(folder: str) -> tuple[Logs, dict[str, float]]:
    """The logs and the seconds each part of the work took."""
    strokes = list(read_logs(folder))
    if not strokes:
        raise SystemExit(f"no $1 logs (*.xml) under {folder}")
    paths = [s.points for s in strokes]
    cost: dict[str, float] = {}
    started = time.perf_counter()
    features, ok = stroke_features(paths)
    if len(ok) != len(paths):
        raise SystemExit("a logged stroke has no extent")
    parts = similarity(features, features, MAX_ROTATION)
    cost["ours"] = time.perf_counter() - started
    builtin = builtin_templates()
    builtin_parts = similarity(features, builtin.features(), MAX_ROTATION, builtin.ideal)
    started = time.perf_counter()
    vectors = protractor_vectors(paths)
    protractor = protractor_cosine(vectors, vectors)
    cost["protractor"] = time.perf_counter() - started
    logs = Logs(
        shape=np.asarray([s.shape for s in strokes], dtype=object),
        writer=np.asarray([s.subject for s in strokes], dtype=object),
        speed=np.asarray([s.speed for s in strokes], dtype=object),
        repetition=np.asarray([s.repetition for s in strokes]),
        parts=parts,
        builtin_parts=builtin_parts,
        builtin_names=builtin.names,
        builtin_ideal=builtin.ideal,
        protractor=protractor,
        builtin_protractor=protractor_cosine(vectors, protractor_vectors(builtin.paths)),
        size=features.sizes,
    )
    cost["pairs"] = float(len(paths) ** 2)
    return logs, cost


# --- protocols: (test strokes, template strokes) -----------------------------------------------


def own_splits(logs: Logs, writers: list[str]) -> Iterator[tuple[str, str, np.ndarray, np.ndarray]]:
    """A writer's own OWN_TEMPLATES templates a shape at one speed (repetitions r … r+2,
    rotated over the 10), the others of that writer and speed tested."""
    for w, speed in itertools.product(writers, SPEEDS):
        members = np.flatnonzero((logs.writer == w) & (logs.speed == speed))
        for r in range(10):
            reps = [(r + j) % 10 + 1 for j in range(OWN_TEMPLATES)]
            chosen = np.isin(logs.repetition[members], reps)
            yield w, speed, members[~chosen], members[chosen]


def top1(scores: np.ndarray, names: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """Whether each stroke's nearest template is of its shape (k,) bool."""
    return names[np.argmax(scores, axis=1)] == truth


@dataclass
class Found:
    """Nearest shapes of many strokes gathered over splits (only what the verdict reads),
    with the true shapes (k,)."""

    nearest: Nearest
    truth: np.ndarray

    @classmethod
    def gather(cls, parts: list[tuple[Nearest, np.ndarray]]) -> Found:
        def joined(field: str) -> np.ndarray:
            return np.concatenate([getattr(n, field) for n, _ in parts])

        shape = joined("shape")
        empty = np.zeros((len(shape), 0))
        fields = ("score", "own", "built_in", "rival", "confirmed", "floor", "separation", "size")
        fields = (shape, *(joined(f) for f in fields))
        truth = np.concatenate([t for _, t in parts])
        return cls(Nearest([], empty, *fields), truth)

    def accepted(self, choices: ScoreChoices) -> np.ndarray:
        """:meth:`Nearest.accepted`: the recognizer's own rule."""
        return self.nearest.accepted(MIN_SCORE, choices)

    def right(self, choices: ScoreChoices) -> np.ndarray:
        return self.accepted(choices) & (self.nearest.shape == self.truth)


def drawn_by_people(
    logs: Logs,
    scores: np.ndarray,
    catalogue: np.ndarray,
    test: np.ndarray,
    templates: np.ndarray,
    loso: str = "",
    apart: Medians | None = None,
) -> list[tuple[Nearest, np.ndarray]]:
    """The nearest shapes of strokes ``test`` among the strokes ``templates`` as templates
    (as ``TemplateSet.classify_many`` finds them, the built-in templates the rival catalogue:
    every stroke's ``catalogue`` scores (N, B)), with the true shapes. With ``loso``, each
    shape's strokes among the other shapes' templates only (leave-one-shape-out): "built-in"
    a shape the catalogue has, "new" one it has not either (its built-in templates left out).
    ``apart``: the templates' :class:`Medians`, when already found."""
    names = logs.shape[templates]
    people = np.zeros(len(templates), bool)
    own = agreement(scores[np.ix_(templates, templates)], names, ~people)
    twins = catalogue_twins(catalogue[templates], names, logs.builtin_names)
    if apart is None:
        apart = medians(
            scores[np.ix_(templates, templates)], names, catalogue[templates], logs.builtin_names
        )

    def found(strokes: np.ndarray, left_out: str = "") -> tuple[Nearest, np.ndarray]:
        keep = names != left_out
        unknown = left_out if loso == "new" else ""
        known = logs.builtin_names != unknown
        rival = Catalogue(catalogue[np.ix_(strokes, known)], logs.builtin_names[known], twins)
        near = nearest(
            scores[np.ix_(strokes, templates[keep])],
            names[keep],
            people[keep],
            own,
            rival,
            separation(apart, left_out, unknown),
            (logs.size[strokes], logs.size[templates[keep]]),
        )
        return near, logs.shape[strokes]

    if not loso:
        return [found(test)]
    return [
        found(test[logs.shape[test] == shape], shape)
        for shape in dict.fromkeys(logs.shape[test].tolist())
    ]


@dataclass
class Protocols:
    """The nearest shapes of some writers' strokes in each protocol, for one ScoreChoices'
    scores: own 3 templates, the same with a shape left out, writer-independent, built-in."""

    own: Found
    unknown: Found
    new: Found  # unknown shapes the catalogue has not either
    independent: Found
    builtin: Found
    unknown_writer: np.ndarray  # (the writer of each stroke of ``unknown``)

    @classmethod
    def on(
        cls, logs: Logs, choices: ScoreChoices, test_writers: list[str], template_writers: list[str]
    ) -> Protocols:
        """``test_writers``' strokes; writer-independent templates: the strokes of those of
        ``template_writers`` that are not the tested writer."""
        scores = logs.parts.score(choices)
        catalogue = logs.builtin_parts.score(choices)
        own, unknown, new, independent = [], [], [], []
        unknown_writer = []
        for w, _, te, tm in own_splits(logs, test_writers):
            apart = medians(
                scores[np.ix_(tm, tm)], logs.shape[tm], catalogue[tm], logs.builtin_names
            )
            own += drawn_by_people(logs, scores, catalogue, te, tm, "", apart)
            new += drawn_by_people(logs, scores, catalogue, te, tm, "new", apart)
            left_out = drawn_by_people(logs, scores, catalogue, te, tm, "built-in", apart)
            unknown += left_out
            unknown_writer += [np.full(len(truth), w, dtype=object) for _, truth in left_out]
        for w in test_writers:
            te = np.flatnonzero(logs.writer == w)
            tm = np.flatnonzero(np.isin(logs.writer, template_writers) & (logs.writer != w))
            independent += drawn_by_people(logs, scores, catalogue, te, tm)
        tested = np.flatnonzero(np.isin(logs.writer, test_writers))
        builtin = nearest(catalogue[tested], logs.builtin_names, logs.builtin_ideal, {})
        return cls(
            Found.gather(own),
            Found.gather(unknown),
            Found.gather(new),
            Found.gather(independent),
            Found.gather([(builtin, logs.shape[tested])]),
            np.concatenate(unknown_writer),
        )


# --- the choices, made on some writers ------------------------------------------------------------


def non_shapes(seed: int = 5, count: int = 40) -> list[np.ndarray]:
    """Strokes that are none of the built-in shapes, each drawn differently (proportions,
    turn, noise): ``count`` of each of stroke_accuracy.others' five."""
    rng = np.random.default_rng(seed)
    items = []
    for _ in range(count):
        for name, path in others(rng, 0.1).items():
            if name not in NON_SHAPES:
                continue
            aspect = np.exp(rng.uniform(np.log(0.75), np.log(1.33), size=2))
            turn = math.radians(rng.uniform(-12.0, 12.0))
            c, s = math.cos(turn), math.sin(turn)
            affine = np.array([[c, -s], [s, c]]) @ np.diag(aspect)
            items.append((name, normalised(path @ affine.T, 0.1), 0.1))
    return trace_synthetic(items, seed)


def builtin_extra(non_shape_parts: Similarity, choices: ScoreChoices) -> float:
    """The smallest BUILTIN_EXTRAS that accepts at most NON_SHAPE_TARGET of the non-shapes."""
    best = non_shape_parts.score(choices).max(axis=1)
    for extra in BUILTIN_EXTRAS:
        if np.mean(best >= MIN_SCORE + extra) <= NON_SHAPE_TARGET:
            return extra
    return BUILTIN_EXTRAS[-1]


def choose(logs: Logs, writers: list[str], non_shape_parts: Similarity) -> ScoreChoices:
    """The choices made on ``writers`` only (see the module docstring): for each weight pair
    of the grid its built-in extra and its margin, then the pair whose writers are most often
    right, averaged over the three protocols."""
    best: tuple[float, ScoreChoices] | None = None
    for dw, fw in itertools.product(DIRECTION_WEIGHTS, FORM_WEIGHTS):
        choices = replace(DEFAULT_CHOICES, direction_weight=dw, form_weight=fw)
        choices = replace(choices, builtin_extra=builtin_extra(non_shape_parts, choices))
        found = Protocols.on(logs, choices, writers, writers)
        tight = margin(found, writers, replace(choices, margin_share=None))
        choices = replace(choices, margin=tight, confirmed_margin=tight)
        if choices.margin_share is None:
            choices = replace(choices, confirmed_margin=confirmed_margin(found, writers, choices))
        else:
            choices = replace(choices, least_size=least_size(found))
            choices = replace(choices, margin_share=margin(found, writers, choices))
        right = np.mean(
            [f.right(choices).mean() for f in (found.own, found.independent, found.builtin)]
        )
        if best is None or right > best[0] + 1e-12:
            best = (float(right), choices)
    assert best is not None
    return best[1]


def margin(found: Protocols, writers: list[str], choices: ScoreChoices) -> float:
    """The margin made on ``writers`` for unknown shapes the catalogue has not either (what
    the margin alone must reject; ``confirmed_margin`` the same): the largest of MARGINS
    before the first whose unknown shapes accepted (the mean over the writers) exceed a
    target, the target the largest of TARGETS that keeps UNKNOWN_TARGET on a writer left out
    of them: with each of ``writers`` left out in turn, the margin made on the others at that
    target accepts at most UNKNOWN_TARGET of the left-out writer's unknown shapes on their
    mean (nested leave-one-writer-out: a margin made on some writers accepts more on a new
    one). With ``choices.margin_share`` set, the share of the set's separation (of SHARES)
    is made the same way."""
    if choices.margin_share is not None:
        shares = [replace(choices, margin_share=k) for k in SHARES]
        rates = _rates(found.new, found.unknown_writer, writers, shares)
        return SHARES[nested_margin(rates, writers)]

    def both(m: float) -> ScoreChoices:
        return replace(choices, margin=m, confirmed_margin=m)

    rates = _rates(found.new, found.unknown_writer, writers, [both(m) for m in MARGINS])
    return MARGINS[nested_margin(rates, writers)]


def least_size(found: Protocols) -> float:
    """The least size, over the least drawn template of its shape, of the writers' own
    strokes taken for their own shape (own 3 templates), rounded down to SIZE_STEP: a stroke
    smaller than any of them drew gets no more than ``margin`` (ScoreChoices.least_size)."""
    near = found.own.nearest
    size = near.size[(near.shape == found.own.truth) & np.isfinite(near.size)]
    return round(math.floor(float(size.min()) / SIZE_STEP) * SIZE_STEP, 2) if len(size) else 0.0


def confirmed_margin(found: Protocols, writers: list[str], choices: ScoreChoices) -> float:
    """The margin for strokes the catalogue confirms, made on ``writers`` as :func:`margin`
    is, on the same unknown shapes (left out of a writer's templates and of the catalogue:
    on those the catalogue has, its rival rule rejects them whatever this margin is, so
    they cannot show what a looser one lets through), at least ``choices.margin``."""
    grid = [m for m in MARGINS if m >= choices.margin]
    candidates = [replace(choices, confirmed_margin=m) for m in grid]
    rates = _rates(found.new, found.unknown_writer, writers, candidates)
    return grid[nested_margin(rates, writers)]


def _rates(
    unknown: Found, writer: np.ndarray, writers: list[str], candidates: list[ScoreChoices]
) -> dict[str, np.ndarray]:
    """Each writer's unknown shapes accepted with each of the ``candidates``."""
    taken = np.asarray([unknown.accepted(c) for c in candidates])  # (candidates, strokes)
    return {w: taken[:, writer == w].mean(axis=1) for w in writers}


def nested_margin(rates: dict[str, np.ndarray], writers: list[str]) -> int:
    """The index into MARGINS that :func:`margin` makes on ``writers`` from each writer's
    unknown shapes accepted at each of MARGINS (``rates``, increasing with the margin)."""

    def made_on(some: list[str], target: float) -> int:
        over = np.flatnonzero(np.mean([rates[w] for w in some], axis=0) > target)
        return max(int(over[0]) - 1, 0) if len(over) else len(rates[some[0]]) - 1

    chosen = TARGETS[-1]
    for target in TARGETS:
        left_out = [rates[w][made_on([v for v in writers if v != w], target)] for w in writers]
        if np.mean(left_out) <= UNKNOWN_TARGET:
            chosen = target
            break
    return made_on(writers, chosen)


# --- measuring a held-out writer ---------------------------------------------------------------


def measure(logs: Logs, held_out: str, choices: ScoreChoices) -> dict[str, dict[str, float]]:
    """Per speed: the held-out writer's figures with ``choices`` (% right, % accepted), and
    a plain Protractor's top-1 with the same templates."""
    train = [w for w in logs.writers if w != held_out]
    found = Protocols.on(logs, choices, [held_out], train)
    mine = np.flatnonzero(logs.writer == held_out)
    own_protractor = np.concatenate(
        [
            top1(logs.protractor[np.ix_(te, tm)], logs.shape[tm], logs.shape[te])
            for _, _, te, tm in own_splits(logs, [held_out])
        ]
    )
    own_speed = np.concatenate([logs.speed[te] for _, _, te, _ in own_splits(logs, [held_out])])
    others_ = np.flatnonzero(logs.writer != held_out)
    wi_protractor = top1(
        logs.protractor[np.ix_(mine, others_)], logs.shape[others_], logs.shape[mine]
    )
    builtin_protractor = top1(logs.builtin_protractor[mine], logs.builtin_names, logs.shape[mine])
    unknown_speed = np.concatenate(
        [
            logs.speed[te[logs.shape[te] == shape]]
            for _, _, te, _ in own_splits(logs, [held_out])
            for shape in dict.fromkeys(logs.shape[te].tolist())
        ]
    )
    out: dict[str, dict[str, float]] = {}
    for speed in SPEEDS:
        at = logs.speed[mine] == speed
        own_at = own_speed == speed
        out[speed] = {
            "wi": 100 * found.independent.right(choices)[at].mean(),
            "wi_protractor": 100 * wi_protractor[at].mean(),
            "own": 100 * found.own.right(choices)[own_at].mean(),
            "own_protractor": 100 * own_protractor[own_at].mean(),
            "builtin": 100 * found.builtin.right(choices)[at].mean(),
            "builtin_protractor": 100 * builtin_protractor[at].mean(),
            "unknown": 100 * found.unknown.accepted(choices)[unknown_speed == speed].mean(),
            "new": 100 * found.new.accepted(choices)[unknown_speed == speed].mean(),
        }
    return out


LOSSES = ("margin", "another shape", "below min_score", "catalogue rival")


def own_losses(
    logs: Logs, held_out: str, choices: ScoreChoices
) -> tuple[dict[str, Counter[str]], int]:
    """What the held-out writer's own 3 templates lose with ``choices``, and of how many
    strokes tested (a stroke once per rotation it is tested in), per cause (LOSSES: in
    the order :meth:`Nearest.accepted` is read; "another shape" whether taken or not), each a
    count per stroke ("shape speed rREP", "→ taken" for another shape): a stroke is tested in
    up to seven of the ten rotations, so one odd stroke can be lost seven times."""
    scores = logs.parts.score(choices)
    catalogue = logs.builtin_parts.score(choices)
    threshold = MIN_SCORE + choices.builtin_extra
    out: dict[str, Counter[str]] = {cause: Counter() for cause in LOSSES}
    tested = 0
    for _, speed, te, tm in own_splits(logs, [held_out]):
        tested += len(te)
        ((near, truth),) = drawn_by_people(logs, scores, catalogue, te, tm)
        right = near.accepted(MIN_SCORE, choices) & (near.shape == truth)
        for i in np.flatnonzero(~right):
            stroke = f"{truth[i]} {speed} r{logs.repetition[te[i]]}"
            if near.shape[i] != truth[i]:
                out["another shape"][f"{stroke} → {near.shape[i]}"] += 1
            elif near.score[i] < MIN_SCORE:
                out["below min_score"][stroke] += 1
            elif near.rival[i] >= threshold:
                out["catalogue rival"][stroke] += 1
            else:
                out["margin"][stroke] += 1
    return out, tested


def losses_text(writer: str, lost: dict[str, Counter[str]], tested: int) -> str:
    """One line: the writer's own-3 losses per cause, each stroke with its count."""
    total = sum(sum(c.values()) for c in lost.values())
    parts = [
        f"{cause} {sum(c.values())}"
        + (f" ({', '.join(f'{k} ×{v}' for k, v in sorted(c.items()))})" if c else "")
        for cause, c in lost.items()
    ]
    return f"- {writer}: {total} of {tested} lost: " + "; ".join(parts)


COLUMNS = (
    ("wi", "writer-independent"),
    ("wi_protractor", "Protractor"),
    ("own", "own 3 templates"),
    ("own_protractor", "Protractor"),
    ("builtin", "built-in"),
    ("builtin_protractor", "Protractor"),
    ("unknown", "unknown accepted"),
    ("new", "none built-in"),
)


def table(folds: dict[str, dict[str, dict[str, float]]]) -> list[str]:
    """Markdown: writer × speed, then the mean and the worst writer per speed."""
    lines = [
        "| writer | speed | " + " | ".join(label for _, label in COLUMNS) + " |",
        "|---|---|" + "---:|" * len(COLUMNS),
    ]
    for writer, per_speed in folds.items():
        for speed, row in per_speed.items():
            cells = " | ".join(f"{row[key]:.1f} %" for key, _ in COLUMNS)
            lines.append(f"| {writer} | {speed} | {cells} |")
    for speed in (*SPEEDS, "all"):
        speeds = SPEEDS if speed == "all" else (speed,)
        rows = [
            {k: float(np.mean([folds[w][s][k] for s in speeds])) for k, _ in COLUMNS} for w in folds
        ]
        mean = " | ".join(f"{np.mean([r[k] for r in rows]):.1f} %" for k, _ in COLUMNS)
        lines.append(f"| **mean** | {speed} | {mean} |")
        worst = []
        for key, _ in COLUMNS:
            pick = max if key in ("unknown", "new") else min
            value = pick(r[key] for r in rows)
            who = next(w for w, r in zip(folds, rows, strict=True) if r[key] == value)
            worst.append(f"{value:.1f} % ({who})")
        lines.append(f"| **worst writer** | {speed} | {' | '.join(worst)} |")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", help="the $1 logs (one folder per writer)")
    parser.add_argument("--json", metavar="FILE", help="also write every figure as JSON")
    args = parser.parse_args()
    started = time.perf_counter()
    logs, cost = load(args.folder)
    non_shape = stroke_features(non_shapes())[0]
    builtin = builtin_templates()
    non_shape_parts = similarity(non_shape, builtin.features(), MAX_ROTATION, builtin.ideal)
    folds: dict[str, dict[str, dict[str, float]]] = {}
    chosen: dict[str, ScoreChoices] = {}
    for held_out in logs.writers:
        train = [w for w in logs.writers if w != held_out]
        chosen[held_out] = choose(logs, train, non_shape_parts)
        folds[held_out] = measure(logs, held_out, chosen[held_out])
    shipped = choose(logs, logs.writers, non_shape_parts)
    n = len(logs.shape)
    print(
        f"Leave-one-writer-out on the $1 logs ({n} strokes, {len(logs.writers)} writers × "
        f"{len(SPEEDS)} speeds × 16 shapes × 10), as logged; min_score {MIN_SCORE}, "
        f"max_rotation_deg {MAX_ROTATION:g}; every choice made on the other four writers "
        f"(`python scripts/stroke_lowo.py {args.folder}`, {time.perf_counter() - started:.0f} s)\n"
    )
    print("\n".join(table(folds)))
    print(
        "\nWhat each held-out writer's own 3 templates lose, with the choices its four made "
        "(stroke, speed, repetition; × the rotations it was lost in):\n"
    )
    for writer, c in chosen.items():
        print(losses_text(writer, *own_losses(logs, writer, c)))
    print("\nChoices made by each fold (on the four other writers):\n")
    for writer, c in chosen.items():
        print(f"- without {writer}: {_choices_text(c)}")
    fields = [
        f for f in asdict(DEFAULT_CHOICES) if len({getattr(c, f) for c in chosen.values()}) == 1
    ]
    print(f"- on all five: {_choices_text(shipped)}")
    print(f"- shipped (stroke_similarity.DEFAULT_CHOICES): {_choices_text(DEFAULT_CHOICES)}")
    same = "are" if shipped == DEFAULT_CHOICES else "are NOT"
    print(
        f"\nThe folds agree on: {', '.join(fields) or 'nothing'}; the shipped choices {same} "
        "what the procedure makes on all five."
    )
    per_pair = {k: 1e6 * cost[k] / cost["pairs"] for k in ("ours", "protractor")}
    print(
        f"\nCost, the same way for both (every stroke against every other, {cost['pairs']:,.0f} "
        f"pairs): ours {per_pair['ours']:.1f} µs a pair, plain Protractor "
        f"{per_pair['protractor']:.2f} µs a pair; a stroke against the {len(builtin)} built-in "
        f"templates: ours {per_pair['ours'] * len(builtin) / 1e3:.1f} ms, Protractor "
        f"{per_pair['protractor'] * len(builtin) / 1e3:.2f} ms."
    )
    if args.json:
        Path(args.json).write_text(
            json.dumps(
                {
                    "folds": folds,
                    "choices": {w: asdict(c) for w, c in chosen.items()},
                    "all_five": asdict(shipped),
                    "cost_s": cost,
                },
                indent=1,
            )
        )


def _choices_text(c: ScoreChoices) -> str:
    margins = (
        f"margin {c.margin:g}, confirmed_margin {c.confirmed_margin:g}"
        if c.margin_share is None
        else f"margin_share {c.margin_share:g} of the separation, beyond margin {c.margin:g} "
        f"only where the catalogue agrees and at least {c.least_size:g} of the least template"
    )
    return (
        f"direction_weight {c.direction_weight:g}, form_weight {c.form_weight:g}, "
        f"{margins}, builtin_extra {c.builtin_extra:g}"
    )


if __name__ == "__main__":
    main()
