#!/usr/bin/env python3
"""Swipes at human speeds and swipes one after another, on the simulated paper desk.

The nine 5 cm buttons of examples/layouts/buttons.yaml (``tap``) and ``swipe`` bound anywhere
(4 directions, default options). Two scenes, each judged per true touch: ``right`` (a swipe
in the direction made), ``wrong`` (another direction), ``missed`` (no swipe) and ``tap``
(a tap fired by the swipe: a gesture nobody made).

1. Speeds: 12 cm swipes in the four directions at 0.2–0.4, 0.4–0.7 and 0.7–1.0 m/s, 3 s of
   rest after each (so the zero is followed between them).
2. In a row: the simulator's own swipes (16–20 cm, its human speed), 0.7–1.2 s apart (a person
   swiping through a list), judged in groups of ten; the zero's age at each.

Both with and without ``estimation.sway_compensation`` (the legs as the accelerometer): the
desk's sway, which a dragging finger excites, moves the located point against the finger
and rings on after the swipe, so the idle desk is not still and its zero not followed.

    python scripts/swipe_accuracy.py [--swipes 60] [--seeds 1,2,3] [--desk PROFILE]

``--desk``: another desk's profile (a name or a path, e.g. examples/desks/eight-legs.yaml)
in place of the paper's; its buttons are the same 5 cm grid at the top's centre.
"""

from __future__ import annotations

import argparse
import collections
import tempfile
import time
from pathlib import Path

import numpy as np
from tap_accuracy import BUTTONS, true_touches  # (scripts beside this one)

from hapticdesk.estimator import ContactEstimator
from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.profile_reader import load_profile
from hapticdesk.gestures.engine import GestureEngine
from hapticdesk.gestures.event import GestureEvent
from hapticdesk.gestures.layout_reader import load_layout
from hapticdesk.sim import Idle, Scene, Swipe, simulate

DIRECTIONS = {"right": (1.0, 0.0), "up": (0.0, 1.0), "left": (-1.0, 0.0), "down": (0.0, -1.0)}
BANDS = ((0.2, 0.4), (0.4, 0.7), (0.7, 1.0))
SWIPE_BINDING = "  - {gesture: swipe, direction: [right, up, left, down], do: log}\n"


def _engine(desk: DeskProfile) -> GestureEngine:
    """examples/layouts/buttons.yaml with ``swipe`` bound anywhere too."""
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / BUTTONS.name
        path.write_text(BUTTONS.read_text() + SWIPE_BINDING)
        layout = load_layout(path, profile=desk)
    return GestureEngine(layout, position_delay_s=ContactEstimator(desk).position_delay_s)


def judge(
    desk: DeskProfile, scene: Scene, seed: int, want: list[str | None]
) -> tuple[list[collections.Counter], list[float]]:
    """Simulate, estimate in 0.5 s blocks (as a run does) and recognise; per swipe action a
    Counter of right/wrong/missed/tap, and the zero's age when it started."""
    rec = simulate(desk, scene, seed=seed)
    est = ContactEstimator(desk)
    engine = _engine(desk)
    step = int(0.5 * desk.sample_rate_hz)
    events: list[GestureEvent] = []
    ages: list[tuple[float, float]] = []
    for a in range(0, len(rec.t), step):
        events += engine.feed(est.push(rec.t[a : a + step], rec.wrench[a : a + step]))
        ages.append((float(rec.t[a]), float(rec.t[a]) - est.zeroing.state.zero_t))
    events += engine.flush(float(rec.t[-1]))
    out, age_at = [], []
    for start, end, action, _ in true_touches(rec):
        if want[action] is None:
            continue
        mine = [e for e in events if start - 0.02 <= e.t <= end + 0.3]
        swipes = [e for e in mine if e.gesture == "swipe"]
        tally: collections.Counter = collections.Counter()
        if not swipes:
            tally["missed"] += 1
        else:
            tally["right" if swipes[0].direction == want[action] else "wrong"] += 1
        tally["tap"] += any(e.gesture == "tap" for e in mine)
        out.append(tally)
        age_at.append(next((age for t, age in reversed(ages) if t <= start), 0.0))
    return out, age_at


def speeds(desk: DeskProfile, n: int, seed: int) -> dict[tuple[float, float], collections.Counter]:
    rng = np.random.default_rng(seed)
    actions: list = []
    want: list[str | None] = []
    band_of = []
    for i in range(n):
        name = list(DIRECTIONS)[i % 4]
        lo, hi = BANDS[(i // 4) % len(BANDS)]
        v = np.array(DIRECTIONS[name])
        start = -v * 0.06 + rng.uniform(-0.05, 0.05, 2) * v[::-1]
        actions.append(
            Swipe(
                from_point=(float(start[0]), float(start[1])),
                to_point=(float(start[0] + 0.12 * v[0]), float(start[1] + 0.12 * v[1])),
                speed=float(rng.uniform(lo, hi)),
                wait_s=1.0,
            )
        )
        actions.append(Idle(duration_s=3.0))
        want += [name, None]
        band_of.append((lo, hi))
    tallies, _ = judge(desk, Scene(actions=actions, seed=seed), seed, want)
    result: dict[tuple[float, float], collections.Counter] = {}
    for band, tally in zip(band_of, tallies, strict=True):
        result.setdefault(band, collections.Counter()).update(tally)
    return result


def in_a_row(desk: DeskProfile, n: int, seed: int) -> list[tuple[collections.Counter, float]]:
    rng = np.random.default_rng(seed)
    actions, want = [], []
    for _ in range(n):
        name = list(DIRECTIONS)[rng.integers(4)]
        v = np.array(DIRECTIONS[name])
        length = 0.20 if v[0] else 0.16
        start = -v * length / 2 + rng.uniform(-0.04, 0.04, 2) * v[::-1]
        end = start + v * length
        actions.append(
            Swipe(
                from_point=(float(start[0]), float(start[1])),
                to_point=(float(end[0]), float(end[1])),
                wait_s=float(rng.uniform(0.7, 1.2)),
            )
        )
        want.append(name)
    tallies, ages = judge(desk, Scene(actions=actions, seed=seed), seed, list(want))
    return list(zip(tallies, ages, strict=True))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--swipes", type=int, default=60, help="swipes in a row, per seed")
    parser.add_argument("--speed-swipes", type=int, default=84, help="12 cm swipes, per seed")
    parser.add_argument("--seeds", default="1,2,3")
    parser.add_argument("--desk", default="kitamura2017", help="desk profile: name or path")
    args = parser.parse_args()
    seeds = [int(s) for s in args.seeds.split(",")]
    shipped = load_profile(args.desk)
    for label, desk in (
        ("sway_compensation: false", shipped.with_estimation(sway_compensation=False)),
        ("the profile as shipped (sway compensation on for `fused`)", shipped),
    ):
        started = time.monotonic()
        print(f"## {shipped.name}, {label}")
        bands: dict[tuple[float, float], collections.Counter] = {}
        for seed in seeds:
            for band, tally in speeds(desk, args.speed_swipes, seed).items():
                bands.setdefault(band, collections.Counter()).update(tally)
        print("| 12 cm swipes at | right | wrong | missed | a tap fired |")
        print("|---|---|---|---|---|")
        for (lo, hi), t in sorted(bands.items()):
            total = t["right"] + t["wrong"] + t["missed"]
            print(f"| {lo:g}–{hi:g} m/s | {t['right']}/{total} | {t['wrong']} | {t['missed']} "
                  f"| {t['tap']} |")  # fmt: skip
        groups: dict[int, collections.Counter] = {}
        age: dict[int, list[float]] = {}
        for seed in seeds:
            for i, (tally, zero_age) in enumerate(in_a_row(desk, args.swipes, seed)):
                groups.setdefault(i // 10, collections.Counter()).update(tally)
                age.setdefault(i // 10, []).append(zero_age)
        print("\n| swipes in a row | right | missed | the zero's age (median) |")
        print("|---|---|---|---|")
        for g, t in sorted(groups.items()):
            total = t["right"] + t["wrong"] + t["missed"]
            print(f"| {10 * g + 1}–{10 * g + 10} | {t['right']}/{total} | {t['missed']} "
                  f"| {max(0.0, float(np.median(age[g]))):.0f} s |")  # fmt: skip
        print(f"<!-- {time.monotonic() - started:.0f} s -->\n")


if __name__ == "__main__":
    main()
