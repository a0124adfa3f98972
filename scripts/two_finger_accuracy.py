"""Two-finger detection on the simulator: detection rate and false alarms.

Simulates scenes of two-finger touches (a press held by one finger, a second finger landing
0.05–0.5 s later 4–30 cm away, as a press or a tap) and of single touches (quick light taps,
presses, swipes), runs the estimator and :func:`hapticdesk.estimator.multitouch.second_touches`,
and counts the touches flagged as two-fingered.

    python scripts/two_finger_accuracy.py [--two 200] [--single 1000] [--seed 0]
"""

from __future__ import annotations

import argparse

import numpy as np

from hapticdesk.estimator import ContactEstimator
from hapticdesk.estimator.multitouch import second_touches
from hapticdesk.files.profile import load_profile
from hapticdesk.sim import Scene, simulate
from hapticdesk.sim.actions import Press, Step, Swipe, Tap

SPACING_S = 4.0  # one touch (or pair) every this many seconds
QUIET_S = 2.0
PER_SCENE = 25


def _point(rng: np.random.Generator) -> tuple[float, float]:
    return (float(rng.uniform(-0.33, 0.33)), float(rng.uniform(-0.22, 0.22)))


def _two(rng: np.random.Generator, start: float) -> list[Step]:
    p1 = _point(rng)
    while True:
        p2 = _point(rng)
        if 0.04 <= np.hypot(p2[0] - p1[0], p2[1] - p1[1]) <= 0.3:
            break
    stagger = float(rng.uniform(0.05, 0.5))
    second: Step = (
        Tap(point=p2, start_s=start + stagger)
        if rng.random() < 0.5
        else Press(point=p2, hold_s=0.5, start_s=start + stagger)
    )
    return [Press(point=p1, hold_s=1.0, start_s=start), second]


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


def flagged(desk, steps: list[list[Step]], seed: int) -> list[bool]:
    """Simulate the touches and say for each whether a second finger was flagged in it."""
    starts = [QUIET_S + i * SPACING_S for i in range(len(steps))]
    scene = Scene([s for group in steps for s in group], quiet_s=QUIET_S, tail_s=2.0, seed=seed)
    rec = simulate(desk, scene)
    block = ContactEstimator(desk).push(rec.t, rec.wrench)
    multi = second_touches(desk, rec.t, rec.wrench, block).multi
    return [bool(multi[(rec.t >= a) & (rec.t < a + SPACING_S - 0.5)].any()) for a in starts]


def run(kind: str, count: int, seed: int) -> list[bool]:
    desk = load_profile("kitamura2017")
    rng = np.random.default_rng(seed)
    make = _two if kind == "two" else _single
    out: list[bool] = []
    for first in range(0, count, PER_SCENE):
        n = min(PER_SCENE, count - first)
        groups = [make(rng, QUIET_S + i * SPACING_S) for i in range(n)]
        out += flagged(desk, groups, seed + first)
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--two", type=int, default=200)
    parser.add_argument("--single", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    two = run("two", args.two, args.seed)
    single = run("single", args.single, args.seed + 10_000)
    print(f"two-finger touches: {sum(two)}/{len(two)} detected ({100 * np.mean(two):.1f} %)")
    print(
        f"single touches: {sum(single)}/{len(single)} flagged as two "
        f"(false alarms {100 * np.mean(single):.2f} %)"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
