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
- shapes that are not in the set (S, Z, spiral, figure eight, scribbles, partial strokes:
  half a circle and a pigtail given up before its loop, and taps dragged just over a stroke's
  least size) show how often something else is taken for a shape.

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
from functools import partial

import numpy as np
from tap_accuracy import add_sway_compensation_option, with_sway_compensation  # (beside this)

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
    # partial strokes: a shape given up part way (half a circle, a pigtail before its loop
    # closes, from where its $1 drawing starts)
    start = math.radians(rng.uniform(60.0, 120.0))
    a = start + np.linspace(0.0, math.pi, 100)
    half_circle = np.column_stack([np.cos(a), np.sin(a)])
    pigtail = SHAPES["pigtail"].variants[0]
    part_pigtail = pigtail[: int(len(pigtail) * rng.uniform(0.45, 0.6))]
    out = {
        "S": s_curve,
        "Z": zed,
        "spiral": spiral,
        "figure_eight": eight,
        "scribble": walk,
        "half_circle": half_circle,
        "part_pigtail": part_pigtail,
    }
    drawn = {k: normalised(resample(v, 200), size_m) for k, v in out.items()}
    # a tap whose finger wandered just over a stroke's least size (min_size 4 cm) as it slid
    drag = np.cumsum(rng.normal(size=(5, 2)), axis=0)
    drawn["dragged_tap"] = normalised(resample(drag, 200), float(rng.uniform(0.04, 0.055)))
    return drawn


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


STROKES_A_SESSION = 200  # strokes a simulated session: bounds the memory of one recording


def simulate_strokes(items, seed: int, desk_name: str = "kitamura2017", sway: str = "auto"):
    """Simulate the strokes (label, path, speed[, times]) one after the other on the paper's
    desk (or ``desk_name``: kitamura2017-accel compensates its sway with an accelerometer;
    ``sway``: ``--sway-compensation``'s choice, on, off or auto, the profile's) and estimate:
    (desk, recording, contacts)."""

    from hapticdesk.estimator import estimate
    from hapticdesk.files.profile_reader import load_profile
    from hapticdesk.sim import Idle, Scene, Stroke, simulate

    desk = with_sway_compensation(load_profile(desk_name), sway)
    rng = np.random.default_rng(seed)
    actions: list = []
    for i, (_, path, speed, *timed) in enumerate(items):
        if i and i % 20 == 0:
            actions.append(Idle(duration_s=6.0))  # people pause; the zero follows the drift
        centre = rng.uniform([-0.15, -0.08], [0.15, 0.08])
        times = tuple(timed[0]) if timed and timed[0] is not None else None
        actions.append(
            Stroke(path=tuple(map(tuple, path + centre)), speed=speed, wait_s=0.8, times=times)
        )
    rec = simulate(desk, Scene(actions=actions, seed=seed))
    return desk, rec, estimate(desk, rec)


def capture_strokes(desk, rec, contacts, count: int) -> list[np.ndarray | None]:
    """The captured path of each of ``count`` simulated strokes (None: not captured)."""
    from hapticdesk.gestures.strokes.capture import StrokeCapture

    capture = StrokeCapture(desk, min_size=0.02)
    strokes = capture.feed(contacts) + capture.flush(float(rec.t[-1]))
    # each captured stroke belongs to the drawn stroke whose true contact holds its middle;
    # a drawn stroke the desk did not capture counts as rejected (None)
    touching = np.nan_to_num(rec.extra["true_fn"]) > 0
    edges = np.diff(touching.astype(np.int8), prepend=0, append=0)
    starts = np.flatnonzero(edges == 1)
    if len(starts) != count:
        raise SystemExit(f"the simulator drew {len(starts)} strokes for {count} asked")
    paths: list[np.ndarray | None] = [None] * count
    for s in strokes:
        i = int(np.searchsorted(rec.t[starts], float(np.median(s.t)))) - 1
        if 0 <= i < count and paths[i] is None:
            paths[i] = s.points
    return paths


def trace_on_desk(
    items, seed: int, desk_name: str = "kitamura2017", sway: str = "auto"
) -> list[np.ndarray | None]:
    """Simulate the strokes one after the other, estimate, capture: one path per stroke. In
    sessions of STROKES_A_SESSION (seeds ``seed`` + the first stroke's index): a simulated
    recording is bounded (``simulate`` refuses one over 2 million samples)."""
    paths: list[np.ndarray | None] = []
    for lo in range(0, len(items), STROKES_A_SESSION):
        part = items[lo : lo + STROKES_A_SESSION]
        paths += capture_strokes(*simulate_strokes(part, seed + lo, desk_name, sway), len(part))
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
    other_labels = [lab for lab in labels if lab.startswith("other:")]
    taken_as = [
        None if p is None else templates.classify(p, MIN_SCORE, MAX_ROTATION).shape for p in others_
    ]
    accepted_other = sum(v is not None for v in taken_as)
    taken = Counter(
        (lab.removeprefix("other:"), v)
        for lab, v in zip(other_labels, taken_as, strict=True)
        if v is not None
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
        "others_taken": ", ".join(f"{a}→{b} {n}" for (a, b), n in taken.most_common()),
    }


# --- real people: the $1 logs at their real speed on the simulated desk ------------------------
# (the logs as drawn, leave-one-writer-out with Protractor beside: scripts/stroke_lowo.py)

SPEEDS = ("slow", "medium", "fast")
HUMAN_SIZE_M = (0.07, 0.10)  # a logged stroke is scaled so its larger side is this long


def human_speed_items(folder: str, test_reps: int, seed: int):
    """The $1 logs as desk strokes at their real timing: (enrolment items, test items), each
    (label, path in metres centred on 0, None, times) with the label "subject/speed/shape/rep";
    repetitions 1-3 of each person, speed and shape are enrolled (`strokes record`), the next
    ``test_reps`` are tested."""
    from hapticdesk.gestures.strokes.dollar_logs import read_logs

    rng = np.random.default_rng(seed)
    enrol, test = [], []
    for s in read_logs(folder):
        if s.repetition > 3 + test_reps:
            continue
        p = s.points - (s.points.min(axis=0) + s.points.max(axis=0)) / 2
        p = p * (rng.uniform(*HUMAN_SIZE_M) / max(float(np.ptp(p, axis=0).max()), 1e-9))
        item = (f"{s.subject}/{s.speed}/{s.shape}/{s.repetition}", p, None, s.t)
        (enrol if s.repetition <= 3 else test).append(item)
    return enrol, test


def _path_speed(path: np.ndarray, t: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum() / max(t[-1], 1e-9))


def run_human_speed(
    folder: str, test_reps: int, seed: int, desk_name: str = "kitamura2017", sway: str = "auto"
) -> None:
    """Real strokes at their real speed on the simulated desk: built-in, 1 and 3 own
    templates captured on the desk the same way, per speed."""
    started = time.perf_counter()
    enrol, test = human_speed_items(folder, test_reps, seed)
    if not test:
        raise SystemExit(f"no $1 logs (*.xml) under {folder}")
    items = enrol + test
    paths = trace_on_desk(items, seed, desk_name, sway)
    captured = {lab: p for (lab, *_), p in zip(items, paths, strict=True)}
    builtin = template_set()
    own: dict[tuple[str, str, int], TemplateSet] = {}
    for lab, *_ in enrol:
        subject, speed, shape, rep = lab.split("/")
        for count in (1, 3):
            if int(rep) <= count and captured[lab] is not None:
                # a layout's own templates without the built-in ones: those are the rival
                # catalogue (unistroke.template_set(..., builtin=False))
                mine = own.setdefault((subject, speed, count), TemplateSet(catalogue=builtin))
                mine.add(shape, captured[lab])
    rows: dict[tuple[str, str], list[str]] = {}
    speeds: dict[str, list[float]] = {}
    for lab, path, _, t in test:
        subject, speed, shape, _ = lab.split("/")
        speeds.setdefault(speed, []).append(_path_speed(path, t))
        got = captured[lab]
        for name, templates in (
            ("built-in", builtin),
            ("1 own template a shape", own.get((subject, speed, 1))),
            ("3 own templates a shape", own.get((subject, speed, 3))),
        ):
            verdict = "rejected"
            if got is not None and templates is not None:
                found = templates.classify(got, MIN_SCORE, MAX_ROTATION).shape
                verdict = "rejected" if found is None else "right" if found == shape else "wrong"
            rows.setdefault((name, speed), []).append(verdict)
            rows.setdefault((name, "all"), []).append(verdict)
    print(
        f"Real strokes at their real speed on the simulated {desk_name} desk"
        f"{_sway_label(sway)}: the $1 logs "
        f"({len(test)} test strokes, {len(enrol)} enrolment strokes captured the same way), "
        f"scaled to {HUMAN_SIZE_M[0] * 100:g}–{HUMAN_SIZE_M[1] * 100:g} cm, traced with their "
        f"logged times; min_score {MIN_SCORE}, max_rotation_deg {MAX_ROTATION:g} "
        f"(`python scripts/stroke_accuracy.py --human-speed {folder} --reps {test_reps}"
        f"{f' --desk {desk_name}' if desk_name != 'kitamura2017' else ''}"
        f"{_sway_flag(sway)}`, "
        f"{time.perf_counter() - started:.0f} s)\n"
    )
    print("| templates | speed (median, 10–90 %) | right | rejected | wrong |")
    print("|---|---|---:|---:|---:|")
    order = {speed: k for k, speed in enumerate((*SPEEDS, "all"))}
    for name, speed in sorted(rows, key=lambda key: (key[0] != "built-in", key[0], order[key[1]])):
        verdicts = rows[(name, speed)]
        v = speeds.get(speed, sum(speeds.values(), []))
        lo, mid, hi = np.percentile(v, [10, 50, 90])
        n = len(verdicts)
        print(
            f"| {name} | {speed} ({mid:.2f}, {lo:.2f}–{hi:.2f} m/s) | "
            f"{100 * verdicts.count('right') / n:.1f} % | "
            f"{100 * verdicts.count('rejected') / n:.1f} % | "
            f"{100 * verdicts.count('wrong') / n:.1f} % |"
        )


def _sway_label(sway: str) -> str:
    return {"on": " with sway_compensation", "off": " without sway_compensation"}.get(sway, "")


def _sway_flag(sway: str) -> str:
    return "" if sway == "auto" else f" --sway-compensation {sway}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--per-shape", type=int, default=20, help="test strokes per shape")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--desk", default="kitamura2017", help="the simulated desk's profile")
    add_sway_compensation_option(parser, "the desk")
    parser.add_argument("--synthetic", action="store_true", help="noisy paths, no simulator")
    parser.add_argument("--quick", action="store_true", help="skip the user-template rows")
    parser.add_argument(
        "--human-speed", metavar="DIR", help="$1 logs under DIR at real speed, on the desk"
    )
    parser.add_argument("--reps", type=int, default=3, help="with --human-speed: test strokes")
    args = parser.parse_args()
    if args.human_speed:
        run_human_speed(args.human_speed, args.reps, args.seed, args.desk, args.sway_compensation)
        return
    trace = (
        trace_synthetic
        if args.synthetic
        else partial(trace_on_desk, desk_name=args.desk, sway=args.sway_compensation)
    )
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
    how = (
        "synthetic noisy paths"
        if args.synthetic
        else f"traced on the simulated {args.desk} desk" + _sway_label(args.sway_compensation)
    )
    print(
        f"Stroke accuracy, {args.per_shape} strokes per shape × {len(SHAPES)} shapes, {how}; "
        f"min_score {MIN_SCORE}, max_rotation_deg {MAX_ROTATION:g} "
        f"(`python scripts/stroke_accuracy.py --per-shape {args.per_shape} --seed {args.seed}"
        f"{' --synthetic' if args.synthetic else ''}"
        f"{f' --desk {args.desk}' if args.desk != 'kitamura2017' else ''}"
        f"{_sway_flag(args.sway_compensation)}"
        f"`, {time.perf_counter() - started:.0f} s)\n"
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
    print("\nNon-shapes taken for a shape, by kind:\n")
    for who, name, r in rows:
        print(f"- {who}, {name}: {r['others_taken'] or 'none'}")


if __name__ == "__main__":
    main()
