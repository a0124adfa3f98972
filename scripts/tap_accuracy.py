#!/usr/bin/env python3
"""Taps near a button's edge, on the simulated paper desk and on desks the project never saw.

Nine 5 cm buttons 8 cm apart (examples/layouts/buttons.yaml). Every tap lands uniformly 2 to
10 mm inside a random edge of a random button (anywhere along that edge), with a random peak
force of 2 to 8 N (half of them light, 2 to 3 N) and a human tap's duration (60 to 200 ms).
The simulator's human adds its own aim scatter, sideways push, pad roll and tremor; the sensors
have the paper's noise. Every 40 taps the desk rests 5 s and gets touches that are not taps
(a swipe over the buttons, a 1.5 s press on one, a mug put on one and taken away). Each
simulated touch is estimated, run through the gesture engine and judged:

- right: one tap event, in the button aimed at;
- wrong: a tap event in another button;
- missed: no tap event for the tap;
- phantom: a tap event no tap made (during a swipe, a press, a mug, or no touch at all).

The tremor can keep a tap aimed at 2.0–2.1 N from ever reaching 2 N, the paper's contact force
(``contact_force_n``): such a tap is not a touch, so the share right is over the taps whose
true force reached it; the others are counted apart ("under 2 N").

    python scripts/tap_accuracy.py                  # 1,000 taps on each desk, about 1 min
    python scripts/tap_accuracy.py --taps 200 --desk unseen-four
    python scripts/tap_accuracy.py --desk paper --noise 0.1   # a quieter sensor
    python scripts/tap_accuracy.py --desk loadcells           # the load-cell desks

The load-cell desks (profiles kitamura2017-loadcells-80hz, -1khz and balance-board) are
simulated with their converters' own noise (hapticdesk.sim.loadcells: HX711s at 80 Hz, an
ADS1256 at 1 kHz); ``--noise`` sets the same amplitude on their total F_z, shared by the
cells, ``--resolution`` the six-axis sensors only.
scripts/loadcell_accuracy.py varies them (clocks, gains, mounting, other desks).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from hapticdesk.estimator import ContactEstimator, estimate
from hapticdesk.estimator.contacts import ContactBlock
from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.profile_reader import load_profile, profile_from_mapping
from hapticdesk.files.yamlfile import load_marked_yaml
from hapticdesk.gestures.engine import GestureEngine
from hapticdesk.gestures.layout import Layout
from hapticdesk.gestures.layout_reader import load_layout
from hapticdesk.sim import (
    Idle,
    LiftObject,
    LongPress,
    PutObject,
    Scene,
    SimulationRun,
    Swipe,
    Tap,
    simulate,
)
from hapticdesk.sim.loadcells import LoadCellParameters, with_total_amplitude
from hapticdesk.sim.sensors import SensorParameters

ROOT = Path(__file__).resolve().parents[1]
BUTTONS = ROOT / "examples" / "layouts" / "buttons.yaml"
CENTRES = np.array([(x, y) for y in (0.08, 0.0, -0.08) for x in (-0.08, 0.0, 0.08)])  # b1..b9
HALF = 0.025  # half the button's side

#: desks nothing was tuned on. Six sensors under 1.2 m × 0.7 m, some turned, two upside down,
#: two reporting the load instead of the reaction; four under a 1.6 m × 0.8 m standing desk
#: (taller, heavier, softer), sampled at 500 Hz, every one turned, one upside down.
UNSEEN_DESKS = {
    "unseen-six": """
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
""",
    "unseen-four": """
name: unseen-four
sample_rate_hz: 500
desk: {mass_kg: 32.0, natural_frequency_hz: 4.5}
sensors:
  - {name: fl, position: [-0.72, -0.33, 0.0], rotation_rpy_deg: [0, 0, 30]}
  - {name: fr, position: [0.72, -0.33, 0.0], rotation_rpy_deg: [180, 0, -90], reports: load}
  - {name: bl, position: [-0.72, 0.33, 0.0], rotation_rpy_deg: [0, 0, 180]}
  - {name: br, position: [0.72, 0.33, 0.0], rotation_rpy_deg: [0, 0, -150]}
surfaces:
  - name: top
    origin: [0.0, 0.0, 1.05]
    normal: [0, 0, 1]
    polygon: [[-0.8, -0.4], [0.8, -0.4], [0.8, 0.4], [-0.8, 0.4]]
""",
}


@dataclass
class Tally:
    """How the taps of one run were judged."""

    taps: int = 0
    under: int = 0  # taps whose true force never reached the contact force (not judged)
    right: int = 0
    wrong: int = 0
    missed: int = 0
    phantom: int = 0
    light: int = 0  # judged taps of 2–3 N
    light_right: int = 0
    unfelt: int = 0  # missed taps the estimator never saw in contact
    unlocated: int = 0  # missed taps it saw in contact but never placed on the desk

    def add(self, other: Tally) -> None:
        for name in self.__dataclass_fields__:
            setattr(self, name, getattr(self, name) + getattr(other, name))

    def line(self, label: str) -> str:
        judged = self.taps - self.under
        share = 100.0 * self.right / max(judged, 1)
        light = 100.0 * self.light_right / max(self.light, 1)
        return (
            f"| {label} | {self.taps} | {self.under} | {self.right}/{judged} ({share:.1f} %) | "
            f"{self.wrong} | {self.missed} ({self.unfelt} not felt, {self.unlocated} not located)"
            f" | {self.phantom} | {self.light_right}/{self.light} ({light:.1f} %) |"
        )


def unseen_desk(name: str = "unseen-six", method: str = "fused") -> DeskProfile:
    """The desk ``name`` of :data:`UNSEEN_DESKS`, estimated by ``method``."""
    path = Path(f"{name}.yaml")
    text = UNSEEN_DESKS[name] + f"estimation: {{method: {method}}}\n"
    return profile_from_mapping(load_marked_yaml(path, text), path)


def not_taps(rng: np.random.Generator) -> list:
    """Touches near the buttons that are not taps: none may fire one."""
    row = float(rng.choice([-0.08, 0.0, 0.08]))
    at = CENTRES[rng.integers(9)]
    mug = (float(at[0]), float(at[1]))
    return [
        Swipe(from_point=(-0.11, row), to_point=(0.11, row), wait_s=0.6),
        LongPress(point=tuple(CENTRES[rng.integers(9)]), hold_s=1.5, wait_s=0.6),
        PutObject(name="mug", mass_kg=0.35, point=mug, duration_s=0.15, wait_s=2.0),
        LiftObject(name="mug", duration_s=0.15, wait_s=2.0),
    ]


def edge_taps(rng: np.random.Generator, n: int) -> tuple[Scene, np.ndarray, np.ndarray]:
    """``n`` taps 2–10 mm inside a random edge of a random button, with touches that are not
    taps every 40 taps. Returns the scene, the button each tap aimed at (0..8) and each
    tap's peak force as asked of the simulated human."""
    which = rng.integers(9, size=n)
    inset = rng.uniform(0.002, 0.010, size=n)  # from the edge aimed at
    along = rng.uniform(-HALF + 0.002, HALF - 0.002, size=n)  # 2 mm inside the others too
    side = rng.integers(4, size=n)
    normal = np.array([(1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0)])[side]
    tangent = normal[:, ::-1]
    points = CENTRES[which] + normal * (HALF - inset)[:, None] + tangent * along[:, None]
    light = rng.random(n) < 0.5
    peak = np.where(light, rng.uniform(2.0, 3.0, size=n), rng.uniform(3.0, 8.0, size=n))
    duration = rng.uniform(0.06, 0.20, size=n)  # human taps
    actions: list = []
    for i, (x, y) in enumerate(points):
        if i and i % 40 == 0:
            actions.append(Idle(duration_s=5.0))  # the estimator follows the drift at rest
            actions += not_taps(rng)
        actions.append(
            Tap(
                point=(float(x), float(y)),
                peak_n=float(peak[i]),
                duration_s=float(duration[i]),
                wait_s=float(rng.uniform(0.4, 0.8)),
            )
        )
    return Scene(actions=actions, seed=int(rng.integers(1 << 30))), which, peak


def true_touches(rec: SimulationRun) -> list[tuple[float, float, int, float]]:
    """(start, end, action index, true peak force) of every simulated touch (where the true
    normal force is positive)."""
    true_fn, t = rec.extra["true_fn"], rec.t
    touching = np.flatnonzero(true_fn > 0)
    gaps = np.diff(touching) > 1
    starts = touching[np.concatenate([[True], gaps])]
    ends = touching[np.concatenate([gaps, [True]])]
    action = rec.extra["true_action"]
    return [
        (
            float(t[a]),
            float(t[min(b + 1, len(t) - 1)]),
            int(action[a]),
            float(true_fn[a : b + 1].max()),
        )
        for a, b in zip(starts, ends, strict=True)
    ]


@dataclass
class TapRun:
    """``n`` edge taps simulated on a desk and estimated (:func:`simulate_taps`)."""

    scene: Scene
    which: np.ndarray  # the button each tap aimed at (0..8)
    peak: np.ndarray  # each tap's peak force as asked
    rec: SimulationRun
    contacts: ContactBlock
    touches: list[tuple[float, float, int, float]]  # the taps' true touches, in order


def simulate_taps(
    desk: DeskProfile,
    n: int,
    seed: int,
    sensors: SensorParameters | None = None,
    *,
    cells: LoadCellParameters | None = None,
    built: DeskProfile | None = None,
) -> TapRun:
    """Simulate ``n`` edge taps on ``desk`` with ``seed`` and estimate them; ``sensors``: the
    simulated sensors' noise and resolution (default: the paper's); ``cells``: a load-cell
    desk's (default: its rate's converter); ``built``: the desk as it really is, where the
    profile ``desk`` is not quite it (cells elsewhere: scripts/loadcell_accuracy.py)."""
    rng = np.random.default_rng(seed)
    scene, which, peak = edge_taps(rng, n)
    rec = simulate(built or desk, scene, seed=seed, sensors=sensors, cells=cells)
    contacts = estimate(desk, rec)
    tap_actions = [k for k, a in enumerate(scene.actions) if isinstance(a, Tap)]
    touches = [touch for touch in true_touches(rec) if touch[2] in tap_actions]
    if [touch[2] for touch in touches] != tap_actions:
        raise RuntimeError(f"the simulation made {len(touches)} tap touches for {n} taps")
    return TapRun(scene, which, peak, rec, contacts, touches)


def gesture_events(desk: DeskProfile, layout: Layout, contacts: ContactBlock) -> list:
    """The events the gesture engine fires for ``contacts`` on ``layout``, to the end."""
    engine = GestureEngine(layout, position_delay_s=ContactEstimator(desk).position_delay_s)
    return engine.feed(contacts) + engine.flush(float(contacts.t[-1]))


def run(
    desk: DeskProfile,
    layout: Layout,
    n: int,
    seed: int,
    sensors: SensorParameters | None = None,
    **simulation: Any,
) -> Tally:
    """Simulate ``n`` edge taps on ``desk`` and judge the engine's tap events
    (``simulation``: :func:`simulate_taps`'s ``cells`` and ``built``)."""
    taps = simulate_taps(desk, n, seed, sensors, **simulation)
    events = [e for e in gesture_events(desk, layout, taps.contacts) if e.gesture == "tap"]
    return judge_taps(desk, taps.contacts, taps.touches, taps.which, taps.peak, events).tally


@dataclass
class TapVerdicts:
    """One run's taps judged: the tally, the taps fired in a wrong button (the tap's index,
    the event's) and the tap events no tap made (their indices)."""

    tally: Tally
    wrong: list[tuple[int, int]]
    phantom: list[int]


def judge_taps(
    desk: DeskProfile,
    contacts: ContactBlock,
    touches: list[tuple[float, float, int, float]],
    which: np.ndarray,
    peak: np.ndarray,
    events: list,
) -> TapVerdicts:
    """Judge the tap ``events`` against the true tap ``touches`` (:func:`true_touches`, in
    order; ``which`` button each aimed at, ``peak`` the force asked for)."""
    times = np.array([e.t for e in events])
    used = np.zeros(len(events), bool)
    tally = Tally(taps=len(touches))
    wrong: list[tuple[int, int]] = []
    contact_force = desk.estimation.contact_force_n
    for i, (start, end, _, true_peak) in enumerate(touches):
        # a tap fires at the release the estimator sees, within a few samples of the true one
        hit = np.flatnonzero((times >= start) & (times <= end + 0.2) & ~used)
        under = true_peak < contact_force
        light = not under and peak[i] < 3.0
        tally.light += int(light)
        if len(hit) == 0:
            if under:
                tally.under += 1
                continue
            tally.missed += 1
            during = (contacts.t >= start) & (contacts.t <= end + 0.1)
            tally.unfelt += int(not contacts.in_contact[during].any())
            tally.unlocated += int(
                contacts.in_contact[during].any() and not contacts.located[during].any()
            )
            continue
        used[hit[0]] = True
        right = events[hit[0]].region == f"b{which[i] + 1}"
        if under and right:
            tally.under += 1  # felt anyway (the noise lifted it): not judged either way
            continue
        if right:
            tally.right += 1
            tally.light_right += int(light)
        else:
            tally.wrong += 1
            wrong.append((i, int(hit[0])))
    tally.phantom = int((~used).sum())
    return TapVerdicts(tally, wrong, np.flatnonzero(~used).tolist())


def buttons(desk: DeskProfile, snap_mm: float | None = None) -> Layout:
    """examples/layouts/buttons.yaml on ``desk``; with ``snap_mm``, every tap's ``snap``."""
    if snap_mm is None:
        return load_layout(BUTTONS, profile=desk)
    text = BUTTONS.read_text().replace(
        "bindings:", f"settings: {{tap: {{snap: {snap_mm / 10}}}}}\nbindings:"
    )
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / BUTTONS.name
        path.write_text(text)
        return load_layout(path, profile=desk)


def measure(
    desk: DeskProfile,
    layout: Layout,
    n: int,
    seed: int,
    chunk: int = 250,
    sensors: SensorParameters | None = None,
    **simulation: Any,
) -> Tally:
    """``n`` taps in scenes of at most ``chunk`` (bounded memory), seeds ``seed``, ``seed+1``…"""
    total = Tally()
    for k, start in enumerate(range(0, n, chunk)):
        total.add(run(desk, layout, min(chunk, n - start), seed + k, sensors, **simulation))
    return total


#: the shipped load-cell desks (``--desk loadcells``)
LOADCELL_DESKS = ("kitamura2017-loadcells-80hz", "kitamura2017-loadcells-1khz", "balance-board")


def desks(which: str) -> dict[str, DeskProfile]:
    """The desks ``which`` names: paper, unseen (both unseen desks), unseen-six, unseen-four,
    unseen-switched (the six-sensor desk with the paper's `switched` method), loadcells (the
    load-cell profiles), all."""
    out = {}
    if which in ("paper", "all"):
        out["paper desk (kitamura2017)"] = load_profile("kitamura2017")
    if which in ("unseen", "unseen-six", "all"):
        out["unseen desk: 1.2 × 0.7 m, 6 sensors, fused"] = unseen_desk("unseen-six")
    if which in ("unseen", "unseen-four", "all"):
        out["unseen desk: 1.6 × 0.8 m, 4 sensors, 500 Hz, fused"] = unseen_desk("unseen-four")
    if which == "unseen-switched":
        # without `estimation: {method: ...}` a profile gets the paper's `switched`, which
        # places few 2–3 N taps (its differentiated candidate is too uncertain below F_tth)
        out["unseen 6-sensor desk, switched (a profile's default)"] = unseen_desk(
            "unseen-six", "switched"
        )
    if which in ("loadcells", "all"):
        for name in LOADCELL_DESKS:
            out[f"load cells ({name})"] = load_profile(name)
    return out


#: ``--sway-compensation``'s choices: the estimation setting ``sway_compensation`` each sets
SWAY_CHOICES = {"on": True, "off": False, "auto": None}


def add_sway_compensation_option(parser: argparse.ArgumentParser, where: str) -> None:
    """``--sway-compensation [on|off|auto]`` (bare: on; default auto, the profile's) for the
    desks ``where`` names; :func:`with_sway_compensation` applies it. (Shared by the scripts
    that measure with and without it.)"""
    parser.add_argument(
        "--sway-compensation",
        choices=tuple(SWAY_CHOICES),
        nargs="?",
        const="on",
        default="auto",
        help=f"estimation.sway_compensation (the legs as the accelerometer) on {where}; auto: "
        "the profile's (on for `fused` without an accelerometer)",
    )


def with_sway_compensation(desk: DeskProfile, choice: str) -> DeskProfile:
    """``desk`` with ``--sway-compensation``'s ``choice``; ``auto`` leaves the profile's."""
    return (
        desk if choice == "auto" else desk.with_estimation(sway_compensation=SWAY_CHOICES[choice])
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--taps", type=int, default=1000, help="taps per desk (default 1000)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument(
        "--snap", type=float, metavar="MM", help="the taps' `snap` (default: the layout's)"
    )
    parser.add_argument(
        "--max-sigma",
        type=float,
        metavar="MM",
        help="the estimator's `max_sigma_m` on every desk (default: the profile's, 8 mm)",
    )
    add_sway_compensation_option(parser, "every desk")
    parser.add_argument(
        "--rate",
        type=float,
        metavar="HZ",
        help="every desk sampled at this rate (default: the profile's); the simulated "
        "sensors keep their noise per reading, as a polled sensor does",
    )
    parser.add_argument(
        "--noise",
        type=float,
        metavar="N",
        help="the simulated sensors' noise: its amplitude on the desk's total F_z (default: "
        "the paper's 0.4 N; each channel keeps its resolution, 1/2000 of its rating, where "
        "the profile rates it)",
    )
    parser.add_argument(
        "--resolution",
        type=float,
        metavar="SHARE",
        help="the simulated sensors' resolution step as a share of each channel's rating "
        "(default: the paper's 1/2000; 0: unrounded; six-axis sensors only)",
    )
    parser.add_argument(
        "--desk",
        choices=(
            "paper",
            "unseen",
            "unseen-six",
            "unseen-four",
            "unseen-switched",
            "loadcells",
            "all",
        ),
        default="all",
    )
    args = parser.parse_args()
    print("| desk | taps | under 2 N | right | wrong | missed | phantom | light 2–3 N right |")
    print("|---|---|---|---|---|---|---|---|")
    for label, desk in desks(args.desk).items():
        if args.max_sigma is not None:
            desk = desk.with_estimation(max_sigma_m=args.max_sigma / 1000)
        desk = with_sway_compensation(desk, args.sway_compensation)
        if args.rate is not None:
            desk = replace(desk, sample_rate_hz=args.rate)
            label += f", at {args.rate:g} Hz"
        started = time.monotonic()
        layout = buttons(desk, args.snap)
        sensors = cells = None
        if not desk.six_axis_only:  # load cells: the same amplitude, shared by the cells
            cells = None if args.noise is None else with_total_amplitude(desk, args.noise)
        elif args.noise is not None or args.resolution is not None:
            given = {"noise_amplitude_n": args.noise, "resolution": args.resolution}
            sensors = SensorParameters(**{k: v for k, v in given.items() if v is not None})
        tally = measure(desk, layout, args.taps, args.seed, sensors=sensors, cells=cells)
        print(tally.line(label) + f"  <!-- {time.monotonic() - started:.0f} s -->")


if __name__ == "__main__":
    main()
