#!/usr/bin/env python3
"""Stroke recognition accuracy on strokes traced on the simulated paper desk.

Every built-in shape is drawn many times differently from its template (hapticdesk.gestures.
shapes.hand_drawn: other sizes and proportions, slant, wobble, rounded corners, any start
point of a closed shape, either direction of a reversible one), traced by the simulator's
human at varied speeds with the paper's sensor noise, estimated, captured and smoothed as
the stroke recognizer does it, then classified:

- with the built-in templates;
- with user templates only: 1, then 3 per shape, recorded the same way in a separate
  session (the person drawing each shape once or three times for `hapticdesk strokes record`);
- shapes that are not in the set (S, Z, spiral, figure eight, scribbles) show how often
  something else is taken for a shape.

Prints a Markdown table to paste into the README. ``--synthetic`` skips the simulator and
adds noise to the drawn paths instead (when the simulator is not available).

    python scripts/stroke_accuracy.py            # 20 strokes per shape, about a minute
    python scripts/stroke_accuracy.py --per-shape 5 --quick
"""

from __future__ import annotations

import argparse
import math
import time
from collections import Counter

import numpy as np

from hapticdesk.gestures.options import GESTURE_OPTIONS
from hapticdesk.gestures.strokes.shapes import SHAPES, hand_drawn, normalised, resample
from hapticdesk.gestures.strokes.unistroke import TemplateSet, template_set

MIN_SCORE = GESTURE_OPTIONS["stroke"]["min_score"].default
MAX_ROTATION = GESTURE_OPTIONS["stroke"]["max_rotation_deg"].default


def others(rng: np.random.Generator, size_m: float) -> dict[str, np.ndarray]:
    """Strokes that are none of the built-in shapes."""
    u = np.linspace(0, 1, 200)
    spiral = np.column_stack(
        [u * np.cos(4 * math.pi * u), u * np.sin(4 * math.pi * u)]
    )  # two turns outwards
    eight = np.column_stack([np.sin(2 * math.pi * u), np.sin(4 * math.pi * u) / 2])
    s_curve = np.vstack(
        [
            np.column_stack([np.cos(a), 0.5 + 0.5 * np.sin(a)])
            for a in [np.linspace(0.3 * math.pi, 1.5 * math.pi, 60)]
        ]
        + [
            np.column_stack([-np.cos(a), -0.5 + 0.5 * np.sin(a)])
            for a in [np.linspace(0.5 * math.pi, -0.7 * math.pi, 60)]
        ]
    )
    zed = np.array([[0, 1], [1, 1], [0, 0], [1, 0]], dtype=float)
    walk = np.cumsum(rng.normal(size=(14, 2)), axis=0)
    out = {"S": s_curve, "Z": zed, "spiral": spiral, "figure_eight": eight, "scribble": walk}
    return {k: normalised(resample(v, 200), size_m) for k, v in out.items()}


def drawings(rng: np.random.Generator, per_shape: int, with_others: bool, style: int | None = None):
    """(label, path in metres, speed m/s) for every stroke to trace. ``style`` None: each
    stroke drawn by someone else; a number: all by one person (hand_drawn's ``style``)."""
    items = []
    for name in SHAPES:
        for _ in range(per_shape):
            size = float(rng.uniform(0.06, 0.2))
            path = hand_drawn(name, rng, size_m=size, style=style)
            items.append((name, path, float(rng.uniform(0.034, 0.15))))
    if with_others:
        for _ in range(per_shape):
            for name, path in others(rng, float(rng.uniform(0.06, 0.2))).items():
                items.append((f"other:{name}", path, float(rng.uniform(0.034, 0.15))))
    order = rng.permutation(len(items))
    return [items[i] for i in order]


def trace_on_desk(items, seed: int) -> list[np.ndarray]:
    """Simulate the strokes one after the other, estimate, capture: one path per stroke."""
    from hapticdesk.estimator import estimate
    from hapticdesk.files.profile import load_profile
    from hapticdesk.gestures.strokes.capture import StrokeCapture
    from hapticdesk.sim import Idle, Scene, Stroke, simulate

    desk = load_profile("kitamura2017")
    rng = np.random.default_rng(seed)
    actions: list = []
    for i, (_, path, speed) in enumerate(items):
        if i and i % 20 == 0:
            actions.append(Idle(duration_s=6.0))  # people pause; the zero follows the drift
        centre = rng.uniform([-0.15, -0.08], [0.15, 0.08])
        actions.append(Stroke(path=tuple(map(tuple, path + centre)), speed=speed, wait_s=0.8))
    rec = simulate(desk, Scene(actions=actions, seed=seed))
    capture = StrokeCapture(desk, min_size=0.02)
    strokes = capture.feed(estimate(desk, rec)) + capture.flush(float(rec.t[-1]))
    # each captured stroke belongs to the drawn stroke whose true contact holds its middle;
    # a drawn stroke the desk did not capture counts as rejected (None)
    touching = np.nan_to_num(rec.extra["true_fn"]) > 0
    edges = np.diff(touching.astype(np.int8), prepend=0, append=0)
    starts = np.flatnonzero(edges == 1)
    if len(starts) != len(items):
        raise SystemExit(f"the simulator drew {len(starts)} strokes for {len(items)} asked")
    paths: list[np.ndarray | None] = [None] * len(items)
    for s in strokes:
        i = int(np.searchsorted(rec.t[starts], float(np.median(s.t)))) - 1
        if 0 <= i < len(items) and paths[i] is None:
            paths[i] = s.points
    return paths


def trace_synthetic(items, seed: int) -> list[np.ndarray]:
    """Noisy copies of the paths (σ 1.5 mm, smoothed a little), without the simulator."""
    rng = np.random.default_rng(seed)
    out = []
    for _, path, _ in items:
        p = resample(path, 200)
        noise = rng.normal(scale=0.0015, size=p.shape)
        kernel = np.ones(5) / 5
        noise = np.column_stack([np.convolve(noise[:, k], kernel, mode="same") for k in (0, 1)])
        out.append(p + noise)
    return out


def score(templates: TemplateSet, labels: list[str], paths: list[np.ndarray]) -> dict[str, float]:
    shapes = [
        (lab, p) for lab, p in zip(labels, paths, strict=True) if not lab.startswith("other:")
    ]
    others_ = [p for lab, p in zip(labels, paths, strict=True) if lab.startswith("other:")]
    verdicts = [
        None if p is None else templates.classify(p, MIN_SCORE, MAX_ROTATION).shape
        for _, p in shapes
    ]
    right = sum(v == lab for v, (lab, _) in zip(verdicts, shapes, strict=True))
    rejected = sum(v is None for v in verdicts)
    accepted_other = sum(
        p is not None and templates.classify(p, MIN_SCORE, MAX_ROTATION).shape is not None
        for p in others_
    )
    wrong = Counter(
        (lab, v) for v, (lab, _) in zip(verdicts, shapes, strict=True) if v not in (None, lab)
    )
    return {
        "n": len(shapes),
        "right": 100 * right / len(shapes),
        "rejected": 100 * rejected / len(shapes),
        "wrong": 100 * (len(shapes) - right - rejected) / len(shapes),
        "others": len(others_),
        "others_accepted": 100 * accepted_other / max(1, len(others_)),
        "confusions": ", ".join(f"{a}→{b} {n}" for (a, b), n in wrong.most_common(4)),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--per-shape", type=int, default=20, help="test strokes per shape")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--synthetic", action="store_true", help="noisy paths, no simulator")
    parser.add_argument("--quick", action="store_true", help="skip the user-template rows")
    args = parser.parse_args()
    trace = trace_synthetic if args.synthetic else trace_on_desk
    rng = np.random.default_rng(args.seed)
    started = time.perf_counter()

    # many people, each stroke drawn in its own way
    test_items = drawings(rng, args.per_shape, with_others=True)
    test_paths = trace(test_items, args.seed)
    labels = [lab for lab, _, _ in test_items]
    rows = [("anyone", "built-in", score(template_set(), labels, test_paths))]
    if not args.quick:
        # one person: an enrolment session (each shape three times, as `hapticdesk strokes
        # record` would capture it), then the test strokes, drawn the same way but not alike
        person = args.seed + 7
        enrol_items = drawings(np.random.default_rng(args.seed + 1000), 3, False, style=person)
        enrol_paths = trace(enrol_items, args.seed + 1000)
        by_shape: dict[str, list[np.ndarray]] = {}
        for (lab, _, _), path in zip(enrol_items, enrol_paths, strict=True):
            if path is not None:  # an enrolment stroke the desk missed is drawn again
                by_shape.setdefault(lab, []).append(path)
        own_items = drawings(np.random.default_rng(args.seed + 2000), args.per_shape, True, person)
        own_paths = trace(own_items, args.seed + 2000)
        own_labels = [lab for lab, _, _ in own_items]
        rows.append(("one person", "built-in", score(template_set(), own_labels, own_paths)))
        for count in (1, 3):
            user = {k: v[:count] for k, v in by_shape.items()}
            for builtin in (False, True):
                name = ("built-in + " if builtin else "") + f"{count} user template(s) per shape"
                templates = template_set(user, builtin=builtin)
                rows.append(("one person", name, score(templates, own_labels, own_paths)))
    how = "synthetic noisy paths" if args.synthetic else "traced on the simulated kitamura2017 desk"
    print(
        f"Stroke accuracy, {args.per_shape} strokes per shape × {len(SHAPES)} shapes, {how}; "
        f"min_score {MIN_SCORE}, max_rotation_deg {MAX_ROTATION:g} "
        f"(`python scripts/stroke_accuracy.py --per-shape {args.per_shape} --seed {args.seed}"
        f"{' --synthetic' if args.synthetic else ''}`, {time.perf_counter() - started:.0f} s)\n"
    )
    print(
        "| strokes by | templates | right | rejected | wrong | non-shapes taken for a shape "
        "| most confused |"
    )
    print("|---|---|---:|---:|---:|---:|---|")
    for who, name, r in rows:
        print(
            f"| {who} | {name} | {r['right']:.1f} % | {r['rejected']:.1f} % | {r['wrong']:.1f} % | "
            f"{r['others_accepted']:.0f} % of {r['others']} | {r['confusions'] or '—'} |"
        )


if __name__ == "__main__":
    main()
