#!/usr/bin/env python3
"""Taps on load-cell desks as they are really built: converters on their own clocks, cells
whose gains and places the profile has a little wrong (and the set-up with a known weight
that corrects them), cells under the legs instead of under the top, more noise, and desks
nothing was tuned on.

Every row is scripts/tap_accuracy.py's edge-tap test (taps 2–10 mm inside a 5 cm button's
edge, light and firm, with swipes, presses and a mug that must fire nothing), judged the same
way. The cases, on each shipped load-cell profile:

- as profiled: the converter the rate implies (HX711s converting in step at 80 Hz, an
  ADS1256 taking the cells in turn at 1 kHz; hapticdesk.sim.loadcells);
- own clocks: every HX711 on its own oscillator (its readings up to a period old, drifting);
- … aligned: the same readings, each channel interpolated to t − T at its own conversion
  times (which a board that stamps each conversion would send) before the estimator: what
  an alignment stage would give;
- gains 5 % off, cells 2 cm off: the desk as built differs from its profile, uncalibrated;
- … calibrated: the same desk after the set-up with a 1 kg weight on four spots
  (hapticdesk.analysis.known_weight, fitted on a simulated set-up on the built desk);
- cells under the legs: the same top, its cells on the floor under the legs (a 0.73 m
  lever for the finger's sideways push, which the cells cannot see);
- 3 × noise (``--noise-scale``).

``--set KEY=VALUE`` changes an estimation setting on every desk (the low-passes compared in
docs/loadcells.md: ``--set force_lowpass_hz=4.77 --set diff_lowpass_hz=4.77``).

Then ``--unseen N`` desks drawn at random (seeded): 0.5–1.6 m wide, 0.4–0.9 m deep, three to
six cells (turned, some upside down or reporting the load), the top 2–6 cm above them, 80 Hz
or 1 kHz, a sway of 4–9 Hz, 3–15 kg on the cells, cells of 20, 50 or 100 kg; each as
profiled and calibrated from gains and places off.

    python scripts/loadcell_accuracy.py                     # 1,000 taps a row, some minutes
    python scripts/loadcell_accuracy.py --taps 300 --desk balance-board --unseen 0
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from tap_accuracy import (  # (beside this)
    LOADCELL_DESKS,
    Tally,
    buttons,
    edge_taps,
    gesture_events,
    judge_taps,
    measure,
    true_touches,
)

from hapticdesk.analysis.calibrated_profile import calibrated_profile
from hapticdesk.analysis.known_weight import calibrate, suggested_spots
from hapticdesk.analysis.weight_rests import spots_from_recording
from hapticdesk.estimator import estimate
from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.profile_reader import load_profile, profile_from_mapping
from hapticdesk.files.recording import Recording
from hapticdesk.files.yamlfile import load_marked_yaml
from hapticdesk.sim import Idle, LiftObject, PutObject, Scene, SimulationRun, Tap, simulate
from hapticdesk.sim.loadcells import LoadCellParameters

SETUP_MASS_KG = 1.0  # a bag of sugar
GAIN_ERROR = 0.05
PLACE_ERROR_M = 0.02


def built_off(desk: DeskProfile, rng: np.random.Generator) -> tuple[DeskProfile, tuple[float, ...]]:
    """``desk`` as built: every cell ``PLACE_ERROR_M`` from its profiled place (a random
    direction), and each cell's gain ``GAIN_ERROR`` off, signs alternating."""
    sensors = []
    for s in desk.sensors:
        angle = rng.uniform(0, 2 * math.pi)
        shift = PLACE_ERROR_M * np.array([math.cos(angle), math.sin(angle), 0.0])
        sensors.append(replace(s, position=s.position + shift))
    gains = tuple(1.0 + GAIN_ERROR * (-1) ** i for i in range(desk.channel_count))
    return replace(desk, sensors=tuple(sensors)), gains


def setup_with_weight(
    desk: DeskProfile, built: DeskProfile, cells: LoadCellParameters, seed: int
) -> tuple[DeskProfile, str]:
    """Simulate the set-up on the built desk (the weight on four suggested spots, lifted off
    between them), fit the cells on the profile ``desk``: the calibrated profile and a note
    of its leave-one-out errors."""
    spots = suggested_spots(desk, 4)
    actions: list = []
    for point in spots:
        where = (float(point[0]), float(point[1]))
        actions.append(
            PutObject(name="weight", mass_kg=SETUP_MASS_KG, point=where, duration_s=0.4, wait_s=1.5)
        )
        actions.append(LiftObject(name="weight", duration_s=0.3, wait_s=2.5))
    actions.append(Idle(duration_s=2.0))
    rec = simulate(built, Scene(actions, seed=seed), seed=seed, cells=cells)
    found = spots_from_recording(desk, rec.t, rec.channels, spots, SETUP_MASS_KG)
    result = calibrate(desk, found, SETUP_MASS_KG, check_index=None)
    worst = max(c.error_m for c in result.leave_one_out)
    return calibrated_profile(result.fit), f"leave-one-out ≤ {worst * 1000:.1f} mm"


def aligned(desk: DeskProfile, rec: Recording, run: SimulationRun) -> Recording:
    """``rec`` with each channel interpolated to t − T from its own conversion times (the
    latest conversion of every channel ends within the period before t, so t − T lies
    between each one's last two)."""
    assert run.cells is not None
    k = np.arange(len(rec.t))
    times = run.cells.conversions.times(k, desk.sample_rate_hz)
    out = rec.channels.copy()
    for c in range(out.shape[1]):
        when, first = np.unique(times[:, c], return_index=True)  # a conversion read twice
        out[:, c] = np.interp(rec.t - 1.0 / desk.sample_rate_hz, when, rec.channels[first, c])
    return replace(rec, wrench=out)


def aligned_taps(desk: DeskProfile, n: int, seed: int, cells: LoadCellParameters) -> Tally:
    """tap_accuracy's test with the readings :func:`aligned` before the estimator."""
    layout = buttons(desk)
    total = Tally()
    for k, start in enumerate(range(0, n, 250)):
        scene, which, peak = edge_taps(np.random.default_rng(seed + k), min(250, n - start))
        rec = simulate(desk, scene, seed=seed + k, cells=cells)
        rec = aligned(desk, rec, SimulationRun(desk, scene, seed + k, cells=cells))
        contacts = estimate(desk, rec)
        taps = [i for i, a in enumerate(scene.actions) if isinstance(a, Tap)]
        touches = [t for t in true_touches(rec) if t[2] in taps]
        events = [e for e in gesture_events(desk, layout, contacts) if e.gesture == "tap"]
        total.add(judge_taps(desk, contacts, touches, which, peak, events).tally)
    return total


def under_the_legs(desk: DeskProfile) -> DeskProfile:
    """The same top with its cells on the floor under the legs, carrying the whole desk (the
    paper's 13.7 kg, swaying at its 5.9 Hz)."""
    sensors = tuple(replace(s, position=np.array([*s.position[:2], 0.0])) for s in desk.sensors)
    return replace(desk, sensors=sensors, mass_kg=13.7, center_of_mass_m=None)


def random_desk(
    rng: np.random.Generator,
    index: int,
    *,
    count: int | None = None,
    rate_hz: float | None = None,
    widths_m: tuple[float, float] = (0.5, 1.6),
    name: str = "unseen-loadcells",
) -> DeskProfile:
    """An unseen load-cell desk (see the module docstring); ``count`` cells (3–6, or 8: four
    along each long side), ``rate_hz`` and the range of widths fix what is otherwise drawn
    (the same draws either way, so the unseen desks stay as they were)."""
    width, depth = rng.uniform(*widths_m), rng.uniform(0.4, 0.9)
    drawn = int(rng.integers(3, 7))
    count = count or drawn
    inset = rng.uniform(0.03, 0.08)
    hx, hy = width / 2 - inset, depth / 2 - inset
    places = {
        3: [(-hx, -hy), (hx, -hy), (0.0, hy)],
        4: [(-hx, -hy), (hx, -hy), (-hx, hy), (hx, hy)],
        5: [(-hx, -hy), (hx, -hy), (-hx, hy), (hx, hy), (0.0, hy)],
        6: [(-hx, -hy), (0.0, -hy), (hx, -hy), (-hx, hy), (0.0, hy), (hx, hy)],
        8: [(x, y) for y in (-hy, hy) for x in (-hx, -hx / 3, hx / 3, hx)],
    }[count]
    cells_z = rng.uniform(0.4, 0.75)
    top = cells_z + rng.uniform(0.02, 0.06)
    rate = rate_hz or (80, 1000)[index % 2]
    rated = float(rng.choice([196.0, 490.0, 980.0]))
    lines = []
    for i, (x, y) in enumerate(places):
        yaw = float(rng.uniform(-180, 180))
        flip = rng.random()
        if flip < 0.2:  # upside down, reporting the load: its readings are still positive
            extra = f", rotation_rpy_deg: [180, 0, {yaw:.1f}], reports: load"
        elif flip < 0.4:
            extra = f", rotation_rpy_deg: [0, 0, {yaw:.1f}], reports: load"
        else:
            extra = f", rotation_rpy_deg: [0, 0, {yaw:.1f}]"
        lines.append(
            f"  - {{name: c{i + 1}, kind: load_cell, position: [{x:.4f}, {y:.4f}, "
            f"{cells_z:.4f}], range: {{force_n: {rated:g}}}{extra}}}"
        )
    w2, d2 = width / 2, depth / 2
    outline = [[-w2, -d2], [w2, -d2], [w2, d2], [-w2, d2]]
    # what stands on the cells is the top board: its mass in it, 15 mm under its surface,
    # and a 3 cm board's inertia (given, so the drawn desks stay as they were)
    mass = rng.uniform(3, 15)
    board = 0.03
    inertia = [
        mass / 12 * (depth**2 + board**2),
        mass / 12 * (width**2 + board**2),
        mass / 12 * (width**2 + depth**2),
    ]
    text = f"""name: {name}-{index + 1}
sample_rate_hz: {rate:g}
desk:
  mass_kg: {mass:.3f}
  natural_frequency_hz: {rng.uniform(4, 9):.2f}
  center_of_mass_m: [0.0, 0.0, {top - 0.015:.4f}]
  inertia_kg_m2: [{inertia[0]:.5f}, {inertia[1]:.5f}, {inertia[2]:.5f}]
sensors:
{chr(10).join(lines)}
surfaces:
  - name: top
    origin: [0.0, 0.0, {top:.4f}]
    normal: [0, 0, 1]
    polygon: {outline}
estimation: {{method: fused, sway_compensation: false, force_lowpass_hz: 8, diff_lowpass_hz: 8}}
"""
    path = Path(f"{name}-{index + 1}.yaml")
    return profile_from_mapping(load_marked_yaml(path, text), path)


def describe(desk: DeskProfile) -> str:
    """A desk's shape in a few words, for the table."""
    span = np.ptp(desk.surfaces[0].polygon, axis=0)
    height = desk.surfaces[0].origin[2] - np.mean([s.position[2] for s in desk.sensors])
    rated = desk.sensors[0].channel_limits()[0]
    cells = LoadCellParameters.for_rate(desk.sample_rate_hz)
    noise = 3 * cells.noise_n * rated / cells.rated_n * math.sqrt(len(desk.sensors))
    return (
        f"{span[0]:.2f} × {span[1]:.2f} m, {len(desk.sensors)} cells of {rated:g} N, top "
        f"{height * 100:.0f} cm above them, {desk.sample_rate_hz:g} Hz, noise {noise:.2f} N "
        "(3σ on F_z)"
    )


def row(label: str, tally: Tally, seconds: float, note: str = "") -> None:
    print(tally.line(label + (f" ({note})" if note else "")) + f" {seconds:.0f} s |")


def cases(desk: DeskProfile, n: int, seed: int, full: bool, loudness: float = 3.0) -> None:
    """The rows of one desk (``full``: every case, the noise row ``loudness`` times the
    converter's; else as profiled and calibrated)."""
    layout = buttons(desk)
    cells = LoadCellParameters.for_rate(desk.sample_rate_hz)
    started = time.monotonic()
    row(
        f"{desk.name}: as profiled",
        measure(desk, layout, n, seed, cells=cells),
        time.monotonic() - started,
    )
    if full and cells.sampling == "simultaneous":
        started = time.monotonic()
        own = replace(cells, sampling="independent")
        row(
            f"{desk.name}: own clocks",
            measure(desk, layout, n, seed, cells=own),
            time.monotonic() - started,
        )
        started = time.monotonic()
        row(f"{desk.name}: … aligned", aligned_taps(desk, n, seed, own), time.monotonic() - started)
    built, gains = built_off(desk, np.random.default_rng(seed))
    off = replace(cells, gains=gains)
    if full:
        started = time.monotonic()
        tally = measure(desk, layout, n, seed, cells=off, built=built)
        row(f"{desk.name}: gains 5 % off, cells 2 cm off", tally, time.monotonic() - started)
    started = time.monotonic()
    fitted, note = setup_with_weight(desk, built, off, seed)
    tally = measure(fitted, buttons(fitted), n, seed, cells=off, built=built)
    row(f"{desk.name}: … calibrated, 1 kg on 4 spots", tally, time.monotonic() - started, note)
    cells_z = np.mean([s.position[2] for s in desk.sensors])
    if full and desk.surfaces[0].origin[2] - cells_z < 0.2 and cells_z > 0.3:
        legs = under_the_legs(desk)
        started = time.monotonic()
        row(
            f"{desk.name}: cells under the legs",
            measure(legs, buttons(legs), n, seed, cells=cells),
            time.monotonic() - started,
        )
    if full:
        started = time.monotonic()
        loud = replace(cells, noise_n=loudness * cells.noise_n)
        row(
            f"{desk.name}: {loudness:g} × noise",
            measure(desk, layout, n, seed, cells=loud),
            time.monotonic() - started,
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--taps", type=int, default=1000, help="taps per row (default 1000)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument(
        "--desk", choices=(*LOADCELL_DESKS, "all", "none"), default="all", help="shipped desks"
    )
    parser.add_argument("--unseen", type=int, default=6, help="random unseen desks (default 6)")
    parser.add_argument(
        "--noise-scale", type=float, default=3.0, help="the noise row's factor (default 3)"
    )
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="an estimation setting (a number) on every desk, e.g. force_lowpass_hz=4.77",
    )
    args = parser.parse_args()
    settings = {}
    for item in args.set:
        key, _, value = item.partition("=")
        settings[key] = float(value)
    print(
        "| desk, case | taps | under 2 N | right | wrong | missed | phantom "
        "| light 2–3 N right | time |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    names = LOADCELL_DESKS if args.desk == "all" else () if args.desk == "none" else (args.desk,)
    for name in names:
        desk = load_profile(name).with_estimation(**settings)
        cases(desk, args.taps, args.seed, full=True, loudness=args.noise_scale)
    rng = np.random.default_rng(args.seed + 1000)
    for index in range(args.unseen):
        desk = random_desk(rng, index).with_estimation(**settings)
        print(f"| *{desk.name}: {describe(desk)}* | | | | | | | | |")
        cases(desk, args.taps, args.seed, full=False)


if __name__ == "__main__":
    main()
