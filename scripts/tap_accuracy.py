#!/usr/bin/env python3
"""Taps near a button's edge, on the simulated paper desk and on a desk the project never saw.

Nine 5 cm buttons 8 cm apart (examples/layouts/buttons.yaml). Every tap lands uniformly 2 to
10 mm inside a random edge of a random button (anywhere along that edge), with a random peak
force of 2 to 8 N (half of them light, 2 to 3 N) and a short duration (60 to 160 ms). The
simulator's human adds its own aim scatter, sideways push and pad roll; the sensors have the
paper's noise. Each simulated touch is estimated, run through the gesture engine and judged:

- right: one tap event, in the button aimed at;
- wrong: a tap event in another button;
- missed: no tap event for the touch;
- phantom: a tap event no touch made (none paired with a touch).

    python scripts/tap_accuracy.py                  # 1,000 taps on each desk, about 40 s
    python scripts/tap_accuracy.py --taps 200 --desk unseen
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hapticdesk.estimator import ContactEstimator, estimate
from hapticdesk.files.profile import DeskProfile, load_profile, profile_from_mapping
from hapticdesk.files.yamlfile import load_marked_yaml
from hapticdesk.gestures.engine import GestureEngine
from hapticdesk.gestures.layout import Layout, load_layout
from hapticdesk.sim import Idle, Scene, Tap, simulate

ROOT = Path(__file__).resolve().parents[1]
BUTTONS = ROOT / "examples" / "layouts" / "buttons.yaml"
CENTRES = np.array([(x, y) for y in (0.08, 0.0, -0.08) for x in (-0.08, 0.0, 0.08)])  # b1..b9
HALF = 0.025  # half the button's side

#: a desk nothing was tuned on: 1.2 m × 0.7 m on six sensors, some turned, two upside down,
#: two reporting the load instead of the reaction
UNSEEN_DESK = """
name: unseen-six
sample_rate_hz: 1000
desk: {mass_kg: 24.0, natural_frequency_hz: 7.0}
sensors:
  - {name: a, position: [-0.55, -0.30, 0.0], rotation_rpy_deg: [0, 0, 90]}
  - {name: b, position: [0.0, -0.30, 0.0], rotation_rpy_deg: [180, 0, 0], reports: load}
  - {name: c, position: [0.55, -0.30, 0.0], rotation_rpy_deg: [0, 0, -45]}
  - {name: d, position: [-0.55, 0.30, 0.0], rotation_rpy_deg: [180, 0, 120]}
  - {name: e, position: [0.0, 0.30, 0.0], reports: load}
  - {name: f, position: [0.55, 0.30, 0.0], rotation_rpy_deg: [0, 0, 200]}
surfaces:
  - name: top
    origin: [0.0, 0.0, 0.70]
    normal: [0, 0, 1]
    polygon: [[-0.6, -0.35], [0.6, -0.35], [0.6, 0.35], [-0.6, 0.35]]
"""


@dataclass
class Tally:
    """How the taps of one run were judged."""

    taps: int = 0
    right: int = 0
    wrong: int = 0
    missed: int = 0
    phantom: int = 0
    light: int = 0  # taps of 2–3 N
    light_right: int = 0
    unfelt: int = 0  # missed taps the estimator never saw in contact (peak near its 2 N)
    unlocated: int = 0  # missed taps it saw in contact but never placed on the desk

    def add(self, other: Tally) -> None:
        for name in self.__dataclass_fields__:
            setattr(self, name, getattr(self, name) + getattr(other, name))

    def line(self, label: str) -> str:
        share = 100.0 * self.right / max(self.taps, 1)
        light = 100.0 * self.light_right / max(self.light, 1)
        return (
            f"| {label} | {self.taps} | {self.right} ({share:.1f} %) | {self.wrong} | "
            f"{self.missed} ({self.unfelt} not felt, {self.unlocated} not located) | "
            f"{self.phantom} | {self.light_right}/{self.light} ({light:.1f} %) |"
        )


def unseen_desk(method: str = "fused") -> DeskProfile:
    """The desk of :data:`UNSEEN_DESK`, estimated by ``method``."""
    path = Path("unseen-six.yaml")
    text = UNSEEN_DESK + f"estimation: {{method: {method}}}\n"
    return profile_from_mapping(load_marked_yaml(path, text), path)


def edge_taps(rng: np.random.Generator, n: int) -> tuple[Scene, np.ndarray, np.ndarray]:
    """``n`` taps 2–10 mm inside a random edge of a random button. Returns the scene, the
    button aimed at (0..8) and each tap's peak force."""
    which = rng.integers(9, size=n)
    inset = rng.uniform(0.002, 0.010, size=n)  # from the edge aimed at
    along = rng.uniform(-HALF + 0.002, HALF - 0.002, size=n)  # 2 mm inside the others too
    side = rng.integers(4, size=n)
    normal = np.array([(1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0)])[side]
    tangent = normal[:, ::-1]
    points = CENTRES[which] + normal * (HALF - inset)[:, None] + tangent * along[:, None]
    light = rng.random(n) < 0.5
    peak = np.where(light, rng.uniform(2.0, 3.0, size=n), rng.uniform(3.0, 8.0, size=n))
    duration = rng.uniform(0.06, 0.16, size=n)
    actions: list = []
    for i, (x, y) in enumerate(points):
        if i and i % 40 == 0:
            actions.append(Idle(duration_s=5.0))  # the estimator follows the drift at rest
        actions.append(
            Tap(
                point=(float(x), float(y)),
                peak_n=float(peak[i]),
                duration_s=float(duration[i]),
                wait_s=float(rng.uniform(0.4, 0.8)),
            )
        )
    return Scene(actions=actions, seed=int(rng.integers(1 << 30))), which, peak


def true_touches(true_fn: np.ndarray, t: np.ndarray) -> list[tuple[float, float]]:
    """(start, end) of every simulated touch (where the true normal force is positive)."""
    touching = np.flatnonzero(true_fn > 0)
    gaps = np.diff(touching) > 1
    starts = touching[np.concatenate([[True], gaps])]
    ends = touching[np.concatenate([gaps, [True]])]
    return list(zip(t[starts], t[np.minimum(ends + 1, len(t) - 1)], strict=True))


def run(desk: DeskProfile, layout: Layout, n: int, seed: int) -> Tally:
    """Simulate ``n`` edge taps on ``desk`` and judge the engine's tap events."""
    rng = np.random.default_rng(seed)
    scene, which, peak = edge_taps(rng, n)
    rec = simulate(desk, scene, seed=seed)
    contacts = estimate(desk, rec)
    engine = GestureEngine(layout, position_delay_s=ContactEstimator(desk).position_delay_s)
    events = [
        e for e in engine.feed(contacts) + engine.flush(float(contacts.t[-1])) if e.gesture == "tap"
    ]
    touches = true_touches(rec.extra["true_fn"], rec.t)
    if len(touches) != n:
        raise RuntimeError(f"the simulation made {len(touches)} touches for {n} taps")
    times = np.array([e.t for e in events])
    used = np.zeros(len(events), bool)
    tally = Tally(taps=n)
    for i, (start, end) in enumerate(touches):
        # a tap fires at the release the estimator sees, within a few samples of the true one
        hit = np.flatnonzero((times >= start) & (times <= end + 0.2) & ~used)
        light = peak[i] < 3.0
        tally.light += int(light)
        if len(hit) == 0:
            tally.missed += 1
            during = (contacts.t >= start) & (contacts.t <= end + 0.1)
            tally.unfelt += int(not contacts.in_contact[during].any())
            tally.unlocated += int(
                contacts.in_contact[during].any() and not contacts.located[during].any()
            )
            continue
        used[hit[0]] = True
        if events[hit[0]].region == f"b{which[i] + 1}":
            tally.right += 1
            tally.light_right += int(light)
        else:
            tally.wrong += 1
    tally.phantom = int((~used).sum())
    return tally


def measure(desk: DeskProfile, layout: Layout, n: int, seed: int, chunk: int = 250) -> Tally:
    """``n`` taps in scenes of at most ``chunk`` (bounded memory), seeds ``seed``, ``seed+1``…"""
    total = Tally()
    for k, start in enumerate(range(0, n, chunk)):
        total.add(run(desk, layout, min(chunk, n - start), seed + k))
    return total


def desks(which: str) -> dict[str, DeskProfile]:
    out = {}
    if which in ("paper", "both"):
        out["paper desk (kitamura2017)"] = load_profile("kitamura2017")
    if which in ("unseen", "both"):
        out["unseen desk (1.2 × 0.7 m, 6 sensors), fused"] = unseen_desk()
    if which in ("unseen-switched", "both"):
        # without `estimation: {method: ...}` a profile gets the paper's `switched`, which
        # places few 2–3 N taps (its differentiated candidate is too uncertain below F_tth)
        out["same desk, switched (a profile's default)"] = unseen_desk("switched")
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--taps", type=int, default=1000, help="taps per desk (default 1000)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument(
        "--desk", choices=("paper", "unseen", "unseen-switched", "both"), default="both"
    )
    args = parser.parse_args()
    print("| desk | taps | right | wrong | missed | phantom | light 2–3 N right |")
    print("|---|---|---|---|---|---|---|")
    for label, desk in desks(args.desk).items():
        started = time.monotonic()
        layout = load_layout(BUTTONS, profile=desk)
        tally = measure(desk, layout, args.taps, args.seed)
        print(tally.line(label) + f"  <!-- {time.monotonic() - started:.0f} s -->")


if __name__ == "__main__":
    main()
