"""Two-finger detection on the simulator: detection rate and false alarms.

Simulates scenes of two-finger touches (a press held by one finger, a second finger landing
0.05–0.5 s later 4–30 cm away, as a press or a tap) and of single touches (quick light taps,
presses, swipes), runs the estimator (its stage :mod:`hapticdesk.estimator.multitouch`) and
counts the touches flagged as two-fingered, how far the second finger is placed from where it
landed, and how many fire a ``two_finger_tap``.

    python scripts/two_finger_accuracy.py [--two 200] [--single 1000] [--seed 0] [--desk unseen-six]
"""

from __future__ import annotations

import argparse
import tempfile
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from tap_accuracy import UNSEEN_DESKS, unseen_desk  # (a script beside this one)

from hapticdesk.estimator import ContactEstimator
from hapticdesk.estimator.contacts import FLAG_MULTI
from hapticdesk.files.profile_reader import load_profile
from hapticdesk.gestures.engine import GestureEngine
from hapticdesk.gestures.layout_reader import load_layout
from hapticdesk.sim import Scene, simulate
from hapticdesk.sim.actions import Press, Step, Swipe, Tap

#: a layout binding only the two-finger tap, on the whole top, long enough for the pairs' press
LAYOUT = """desk: kitamura2017
units: cm
regions:
  top: {rect: [-35, -25, 35, 25]}
bindings:
  - {gesture: two_finger_tap, region: top, max_duration_s: 5.0, do: log}
"""
SPACING_S = 6.0  # one touch (or pair) every this many seconds (a press may take 4 s)
HOLDING_S = 0.6  # a second finger this long after the first lands on a held press
QUIET_S = 2.0
PER_SCENE = 48  # touches a session (one fresh estimator)


def _point(rng: np.random.Generator) -> tuple[float, float]:
    return (float(rng.uniform(-0.33, 0.33)), float(rng.uniform(-0.22, 0.22)))


def _two(rng: np.random.Generator, start: float) -> list[Step]:
    p1 = _point(rng)
    while True:
        p2 = _point(rng)
        if 0.04 <= np.hypot(p2[0] - p1[0], p2[1] - p1[1]) <= 0.3:
            break
    stagger = float(rng.uniform(0.05, 1.0))
    second: Step = (
        Tap(point=p2, start_s=start + stagger)
        if rng.random() < 0.5
        else Press(point=p2, hold_s=0.5, start_s=start + stagger)
    )
    return [Press(point=p1, hold_s=1.2, start_s=start), second]


def _single(rng: np.random.Generator, start: float) -> list[Step]:
    kind = rng.integers(3)
    p = _point(rng)
    if kind == 0:
        return [Tap(point=p, start_s=start)]
    if kind == 1:
        return [Press(point=p, start_s=start, hold_s=float(rng.uniform(0.2, 1.0)))]
    q = (float(np.clip(p[0] + rng.uniform(-0.2, 0.2), -0.34, 0.34)), p[1])
    if abs(q[0] - p[0]) < 0.05:
        q = (p[0] + (0.1 if p[0] < 0 else -0.1), p[1])
    return [Swipe(from_point=p, to_point=q, start_s=start)]


@dataclass
class Outcome:
    """Per touch (or pair): flagged as two-fingered, a two_finger_tap fired, and how far the
    second finger was placed from where it landed (NaN: not placed, or no second finger)."""

    flagged: list[bool] = field(default_factory=list)
    gesture: list[bool] = field(default_factory=list)
    second_error_m: list[float] = field(default_factory=list)
    kind: list[str] = field(default_factory=list)  # the single touch's kind, or the pair's
    carried: int = 0  # groups left out: begun while the group before was still in contact


def _kind(group: list[Step]) -> str:
    """A single touch's kind; a pair: whether the first finger was holding (its press's rise,
    at most 25 N at ≈45 N/s, over) when the second landed."""
    if len(group) == 1:
        return type(group[0]).__name__.lower()
    return "holding" if group[1].start_s - group[0].start_s >= HOLDING_S else "rising"  # type: ignore[operator]


def judge(
    desk, layout, groups: list[list[Step]], seed: int, two: Outcome, single: Outcome
) -> float:
    """Simulate the touches in one session, estimate (second-finger stage on) and recognise
    ``layout``; each group's outcome goes to ``two`` or ``single``. Returns the minimum
    distance the stage had learnt by the session's end (its desk's measured stray)."""
    starts = [QUIET_S + i * SPACING_S for i in range(len(groups))]
    steps = []
    for a, group in zip(starts, groups, strict=True):
        offset = a - group[0].start_s  # type: ignore[operator]
        steps += [replace(step, start_s=step.start_s + offset) for step in group]  # type: ignore[operator]
    scene = Scene(steps, quiet_s=QUIET_S, tail_s=2.0, seed=seed)
    rec = simulate(desk, scene)
    estimator = ContactEstimator(desk)
    block = estimator.push(rec.t, rec.wrench)  # it flags second fingers itself
    engine = GestureEngine(layout, position_delay_s=estimator.position_delay_s)
    events = engine.feed(block) + engine.flush(float(block.t[-1]))
    multi = (block.flags & FLAG_MULTI) != 0
    for a, group in zip(starts, groups, strict=True):
        out = two if len(group) == 2 else single
        during = (rec.t >= a) & (rec.t < a + SPACING_S - 0.5)
        # a press before still down when this group lands (a slow release takes seconds):
        # the two merge into one contact, which is neither group's; left out of the rates
        first = int(np.searchsorted(rec.t, a))
        if block.in_contact[first]:
            out.carried += 1
            continue
        out.flagged.append(bool(multi[during].any()))
        out.gesture.append(any(a <= e.t < a + SPACING_S - 0.5 for e in events))
        out.kind.append(_kind(group))
        placed = np.flatnonzero(during & block.located2)
        if len(group) == 2 and len(placed):
            true = np.array(group[1].point)  # type: ignore[attr-defined]
            got = np.array([block.x2[placed[0]], block.y2[placed[0]]])
            out.second_error_m.append(float(np.linalg.norm(got - true)))
        else:
            out.second_error_m.append(float("nan"))
    assert estimator.second_finger is not None
    return estimator.second_finger.min_apart_m


def run(
    count_two: int, count_single: int, seed: int, desk, layout
) -> tuple[Outcome, Outcome, list[float]]:
    """Sessions that mix the pairs and single touches as a person would use a desk (one pair
    to five single touches, shuffled, PER_SCENE touches a session, each session a fresh
    estimator that learns the desk's stray from its presses). The pairs and the single
    touches are drawn from their own streams, so the same touches whatever the mix."""
    rng_two, rng_one = np.random.default_rng(seed), np.random.default_rng(seed + 10_000)
    pairs = [_two(rng_two, 0.0) for _ in range(count_two)]
    singles = [_single(rng_one, 0.0) for _ in range(count_single)]
    sessions = max(1, -(-(count_two + count_single) // PER_SCENE))
    two, single, minima = Outcome(), Outcome(), []
    shuffle = np.random.default_rng(seed + 20_000)
    for i in range(sessions):
        groups = pairs[i::sessions] + singles[i::sessions]
        order = shuffle.permutation(len(groups))
        minima.append(judge(desk, layout, [groups[j] for j in order], seed + i, two, single))
    return two, single, minima


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--two", type=int, default=200)
    parser.add_argument("--single", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--desk",
        default="kitamura2017",
        help="a profile, or a desk nothing was tuned on (unseen-six, unseen-four of "
        "scripts/tap_accuracy.py)",
    )
    args = parser.parse_args()
    desk = (
        unseen_desk(args.desk) if args.desk in UNSEEN_DESKS else load_profile(args.desk)
    ).with_estimation(second_finger=True)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "two_finger.yaml"
        path.write_text(LAYOUT, encoding="utf-8")
        layout = load_layout(path, profile=desk)
    two, single, minima = run(args.two, args.single, args.seed, desk, layout)
    n2, n1 = len(two.flagged), len(single.flagged)
    print(
        f"{len(minima)} sessions of {PER_SCENE} touches; minimum distance learnt by a "
        f"session's end (the desk's stray): {1e2 * min(minima):.1f}-{1e2 * max(minima):.1f} cm"
    )
    print(
        f"two-finger touches: {sum(two.flagged)}/{n2} detected ({100 * np.mean(two.flagged):.1f} %)"
    )
    if two.carried or single.carried:
        print(
            f"(left out, begun while the touch before was still down: {two.carried} pairs, "
            f"{single.carried} single touches)"
        )
    print(
        f"single touches: {sum(single.flagged)}/{n1} flagged as two "
        f"(false alarms {100 * np.mean(single.flagged):.2f} %)"
    )
    errors = np.array(two.second_error_m)
    kinds = np.array(two.kind)
    for name, which in (("all", kinds != ""), ("first finger holding", kinds == "holding"),
                        ("first finger still pressing in", kinds == "rising")):  # fmt: skip
        got = errors[which & np.isfinite(errors)]
        if len(got):
            print(
                f"second finger placed ({name}): {len(got)}/{which.sum()}, median "
                f"{1e3 * np.median(got):.0f} mm, p95 {1e3 * np.percentile(got, 95):.0f} mm off"
            )
    print(
        f"two_finger_tap (bound on the whole top, max_duration_s 5): {sum(two.gesture)}/{n2} pairs "
        f"({100 * np.mean(two.gesture):.1f} %), {sum(single.gesture)}/{n1} single touches "
        f"({100 * np.mean(single.gesture):.2f} %)"
    )
    fired = np.array(two.gesture)
    for name in ("holding", "rising"):
        which = kinds == name
        print(f"  pairs, first finger {name}: {fired[which].sum()}/{which.sum()}")
    singles = np.array(single.kind)
    for name, plural in (("tap", "taps"), ("press", "presses"), ("swipe", "swipes")):
        which = singles == name
        print(
            f"  single {plural}: {np.sum(np.array(single.flagged)[which])}/{which.sum()} flagged, "
            f"{np.sum(np.array(single.gesture)[which])} two_finger_tap"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
