"""Vibration compensation measured on the simulator (issue 15 item 6): the same runs of a desk
with an accelerometer estimated with and without its readings.

- dragged strokes (``examples/scenes/slider.yaml``'s drags, ``kita.yaml``'s traced 北,
  ``shapes.yaml``'s gesture strokes at 12 cm/s): the located points' error against the true
  contact point, p50/p95 over every located sample in true contact; and against the true
  point ``position_delay_s`` earlier (the low-pass's lag taken out, so what is left is the
  path's shape: the sway's ripple and noise);
- the same drags with ``estimation.sway_compensation`` instead of the accelerometer (the legs'
  force twice differentiated, :mod:`hapticdesk.estimator.sway`);
- the sway ring after a swipe lifts off (``swipes.yaml``): the peak of the desk's inertial
  force left in the resultant wrench (low-passed at the detection's 30 Hz) from 50 ms to 1 s
  after each release, and the phantom touch-downs there (a contact starting while nobody
  touches);
- presses and taps at touch-down (``--panel``): the panel desk with three accelerometers
  (``kitamura2017-panel-accel``), ``touch_release_eval.py``'s presses and taps on its top and
  its upright front panel: the share of presses located and the error p50/p95 at +20 and
  +50 ms after the true touch-down (``fused``; a press not located counts as a miss), without
  the readings, with one accelerometer at the top's centre instead, with the three, with the
  three on a desk whose true inertia is half or twice the box the estimator assumes; and, as
  the bound, with the simulator's exact inertial wrench ``M q̈`` taken out of the readings;
- the same on panel desks unlike the shipped one (``--panel-variants``, :data:`PANEL_VARIANTS`:
  wider with five legs turned and upside down and accelerometers turned, small and light,
  heavy with six legs), each with a true inertia off the box the profile assumes: the yaw
  fitted by ``characterize`` from eight presses among taps, then presses and taps on the top
  and the panel estimated without the readings, with the box and with the fitted inertia.

    python scripts/vibration_eval.py --seeds 5      # the figures in README and docs/stability.md
    python scripts/vibration_eval.py --panel --seeds 6
    python scripts/vibration_eval.py --panel-variants --seeds 3
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
import scipy.signal

from hapticdesk.estimator import ContactEstimator
from hapticdesk.estimator.filters import butter_lowpass_sos
from hapticdesk.estimator.inertia import InertiaSettings, InertiaStage, accelerometer_readings
from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.profile_reader import load_profile
from hapticdesk.files.recording import Recording
from hapticdesk.sim import Action, Press, Scene, Tap, simulate
from hapticdesk.sim.scene import load_scene

SCENES = Path(__file__).resolve().parent.parent / "examples" / "scenes"
RING_FROM_S, RING_TO_S = 0.05, 1.0  # the window after a release where the ring is judged


#: how the sway is taken out of a run, and the label its rows get
COMPENSATIONS = {
    "none": "without compensation ",
    "accelerometer": "with the accelerometer",
    "legs": "legs as accelerometer ",
}


def drag_errors(profile: DeskProfile, rec: Recording, how: str) -> tuple[np.ndarray, ...]:
    """Errors (m) of the located samples in true contact: against the truth, and against the
    truth one low-pass delay earlier. ``how``, one of COMPENSATIONS: ``"accelerometer"`` with
    its readings, ``"legs"`` with ``estimation.sway_compensation`` instead (no readings),
    ``"none"`` with neither."""
    profile = profile.with_estimation(sway_compensation=how == "legs")
    est = ContactEstimator(profile)
    accel = accelerometer_readings(profile, rec.extra) if how == "accelerometer" else None
    block = est.push(rec.t, rec.wrench, accel)
    tx, ty = rec.extra["true_x"], rec.extra["true_y"]
    touching = rec.extra["true_fn"] > 0
    ok = block.located & touching
    err = np.hypot(block.x[ok] - tx[ok], block.y[ok] - ty[ok])
    lag = round(est.position_delay_s * profile.sample_rate_hz)
    idx = np.flatnonzero(ok)
    idx = idx[(idx >= lag) & touching[np.maximum(idx - lag, 0)]]
    shape = np.hypot(block.x[idx] - tx[idx - lag], block.y[idx] - ty[idx - lag])
    return err, shape


def ring(profile: DeskProfile, rec: Recording, compensate: bool) -> tuple[list[float], int]:
    """Peak inertial force (N) left after each release, and phantom touch-downs."""
    inertia = InertiaSettings.of(profile)
    assert inertia is not None
    raw = profile.wrench_map() @ rec.wrench.reshape(len(rec.t), -1).T  # (6, k)
    if compensate:
        InertiaStage(inertia).process(raw, accelerometer_readings(profile, rec.extra))
    # raw = M q̈ - u: add the finger's force back, take the desk's weight off (the still start)
    force = raw[:3] + np.vstack([rec.extra[c] for c in ("true_fx", "true_fy", "true_fz")])
    force -= np.median(force[:, : int(profile.sample_rate_hz)], axis=1, keepdims=True)
    sos = butter_lowpass_sos(30.0, profile.sample_rate_hz)
    left = np.linalg.norm(scipy.signal.sosfilt(sos, force, axis=1), axis=0)
    block = ContactEstimator(profile).push(
        rec.t, rec.wrench, accelerometer_readings(profile, rec.extra) if compensate else None
    )
    touching = rec.extra["true_fn"] > 0
    starts = np.flatnonzero(block.in_contact[1:] & ~block.in_contact[:-1]) + 1
    releases = np.flatnonzero(touching[:-1] & ~touching[1:]) + 1
    fs = profile.sample_rate_hz
    peaks, phantoms = [], 0
    for r in releases:
        a, b = r + round(RING_FROM_S * fs), r + round(RING_TO_S * fs)
        if b > len(rec.t) or touching[r:b].any():
            continue
        peaks.append(float(left[a:b].max()))
        phantoms += int(np.count_nonzero((starts >= r) & (starts < b)))
    return peaks, phantoms


def panel_touch_down(seeds: int) -> None:
    """Touch-down on the panel desk without accelerometer readings, with one accelerometer
    (the desk taken as translating), with the three of ``kitamura2017-panel-accel`` (its
    rotation too), and with the simulator's exact inertial wrench removed (the bound)."""
    import touch_release_eval as tre  # beside this script

    three = load_profile("kitamura2017-panel-accel")
    text = Path(str(three.path)).read_text()
    start = text.index("accelerometers:\n")
    end = text.index("sensors:\n", start)
    text = (
        text[:start]
        + "accelerometer: {position: [0.0, 0.0, 0.71], noise_m_s2: 0.005, range_m_s2: 19.6}\n"
        + text[end:]
    ).replace("name: kitamura2017-panel-accel", "name: kitamura2017-panel-one-accel", 1)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "kitamura2017-panel-one-accel.yaml"
        path.write_text(text)
        one = load_profile(path)
    # the same desk whose true inertia is half or twice the box the estimator assumes
    ixx, iyy, izz = np.diag(three.inertia_about_com())
    off = {}
    for factor in (0.5, 2.0):
        moments = f"[{factor * ixx:.4f}, {factor * iyy:.4f}, {factor * izz:.4f}]"
        changed = (
            Path(str(three.path))
            .read_text()
            .replace(
                "desk: {mass_kg: 13.7, natural_frequency_hz: 5.9}",
                f"desk: {{mass_kg: 13.7, natural_frequency_hz: 5.9, inertia_kg_m2: {moments}}}",
            )
        )
        with tempfile.TemporaryDirectory() as folder:
            path = Path(folder) / "inertia.yaml"
            path.write_text(changed.split("can:")[0])
            off[factor] = load_profile(path)
    labels = {
        "without": "without accelerometers ",
        "one": "one accelerometer      ",
        "three": "three accelerometers   ",
        "half": "three, true inertia ×0.5",
        "twice": "three, true inertia ×2  ",
        "exact": "exact M q̈ removed      ",
    }
    for surface, points in (("top", tre.PAPER_POINTS), ("front", tre.PANEL_POINTS)):
        scene = tre.presses_and_taps(points, f"va-{surface}", surface=surface)
        runs = {
            "without": [simulate(three, scene, seed) for seed in range(seeds)],
            "one": [simulate(one, scene, seed) for seed in range(seeds)],
            "exact": [exact_compensation(three, scene, seed) for seed in range(seeds)],
            "half": [simulate(off[0.5], scene, seed) for seed in range(seeds)],
            "twice": [simulate(off[2.0], scene, seed) for seed in range(seeds)],
        }
        runs["three"] = runs["without"]
        for how, label in labels.items():
            desk = one if how == "one" else three
            use = how in ("one", "three", "half", "twice")
            at = _touch_down_errors(desk, runs[how], use)
            print(f"  panel desk, {surface:5s} {label} " + _at_times_line(at))


def _touch_down_errors(
    desk: DeskProfile, runs: list[Recording], use_readings: bool
) -> dict[str, list[np.ndarray]]:
    """``fused``'s errors at +20 and +50 ms after each true touch-down of ``runs`` (a press
    not located: inf), estimated on ``desk``, with its accelerometers' readings or without."""
    from hapticdesk.bench.accuracy import measure_accuracy

    at: dict[str, list[np.ndarray]] = {"touch+20": [], "touch+50": []}
    for rec in runs:
        accel = accelerometer_readings(desk, rec.extra) if use_readings else None
        block = ContactEstimator(desk, method="fused").push(rec.t, rec.wrench, accel)
        found = measure_accuracy(block, rec.extra).at_times
        for key in at:
            at[key].append(found[key])
    return at


def _at_times_line(at: dict[str, list[np.ndarray]]) -> str:
    """The share located, p50 and p95 (a miss counted as a miss) of each time's errors."""
    import touch_release_eval as tre  # beside this script

    parts = []
    for key, errs in at.items():
        err = np.concatenate(errs) * 1000
        ok = np.isfinite(err)
        p50 = f"{np.median(err[ok]):.1f}" if ok.any() else "-"
        with np.errstate(invalid="ignore"):  # (a miss is infinite)
            p95 = tre.p95_mm(err / 1000)
        parts.append(f"{key} ms located {ok.mean():.0%} p50 {p50} p95 {p95} mm")
    return f"({sum(len(p) for p in at['touch+20'])} presses): " + "; ".join(parts)


_RANGE = "range: {force_n: [150, 150, 300], moment_nm: [4, 4, 4]}"
_ACC = "noise_m_s2: 0.005, range_m_s2: 19.6"

#: panel desks unlike ``kitamura2017-panel-accel``: ``desk`` and ``sensors`` / ``accelerometers``
#: entries, the top (height, half width, half depth) and the front panel (middle's height,
#: half width, half height); ``true``: the true moments of inertia as multiples of the box the
#: profile assumes (roll, pitch, yaw)
PANEL_VARIANTS: dict[str, dict[str, Any]] = {
    "wide-five": {
        "desk": "mass_kg: 22.0, natural_frequency_hz: 7.5, center_of_mass_m: [0.06, 0.04, 0.45]",
        "true": (0.8, 1.2, 1.6),
        "sensors": [
            f"{{name: a, position: [-0.55, -0.30, 0.0], rotation_rpy_deg: [0, 0, 90], "
            f"reports: load, {_RANGE}}}",
            f"{{name: b, position: [0.55, -0.30, 0.0], rotation_rpy_deg: [180, 0, 0], "
            f"reports: load, {_RANGE}}}",
            f"{{name: c, position: [0.55, 0.30, 0.0], rotation_rpy_deg: [0, 0, 180], "
            f"reports: load, {_RANGE}}}",
            f"{{name: d, position: [-0.55, 0.30, 0.0], rotation_rpy_deg: [180, 0, 90], "
            f"reports: load, {_RANGE}}}",
            f"{{name: e, position: [0.0, 0.30, 0.0], reports: load, {_RANGE}}}",
        ],
        "accelerometers": [
            f"{{position: [-0.45, -0.25, 0.72], rotation_rpy_deg: [0, 0, 90], {_ACC}}}",
            f"{{position: [0.50, 0.10, 0.72], rotation_rpy_deg: [180, 0, 0], {_ACC}}}",
            f"{{position: [-0.20, 0.30, 0.72], {_ACC}}}",
        ],
        "top": (0.74, 0.6, 0.35),
        "panel": (0.56, 0.6, 0.15),
    },
    "small-light": {
        "desk": "mass_kg: 8.0, natural_frequency_hz: 9.0",
        "true": (1.3, 0.7, 0.6),
        "sensors": [
            f"{{name: {n}, position: [{x}, {y}, 0.0], {_RANGE}}}"
            for n, x, y in (
                ("fl", -0.26, -0.17),
                ("fr", 0.26, -0.17),
                ("bl", -0.26, 0.17),
                ("br", 0.26, 0.17),
            )
        ],
        "accelerometers": [  # near the feet, not under the top
            f"{{position: [{x}, {y}, 0.05], {_ACC}}}"
            for x, y in ((-0.26, -0.17), (0.26, -0.17), (0.26, 0.17))
        ],
        "top": (0.70, 0.30, 0.20),
        "panel": (0.60, 0.30, 0.08),
    },
    "heavy-six": {
        "desk": "mass_kg: 40.0, natural_frequency_hz: 4.2",
        "true": (1.0, 1.2, 1.3),
        "sensors": [
            f"{{name: s{i}, position: [{x}, {y}, 0.0], {_RANGE}}}"
            for i, (x, y) in enumerate(
                [(-0.75, -0.3), (0.0, -0.3), (0.75, -0.3), (-0.75, 0.3), (0.0, 0.3), (0.75, 0.3)]
            )
        ],
        "accelerometers": [
            f"{{position: [{x}, {y}, 0.70], {_ACC}}}"
            for x, y in ((-0.6, -0.2), (0.6, -0.2), (0.1, 0.3))
        ],
        "top": (0.73, 0.8, 0.35),
        "panel": (0.58, 0.8, 0.12),
    },
}


def _variant_profile(
    name: str, v: dict[str, Any], folder: Path, moments: Any = None
) -> DeskProfile:
    """The variant ``v`` as a profile (``moments``: its principal moments of inertia, None:
    the box)."""
    height, half_x, half_y = v["top"]
    middle, half_u, half_v = v["panel"]
    desk = v["desk"]
    if moments is not None:
        desk += ", inertia_kg_m2: [" + ", ".join(f"{m:.5g}" for m in moments) + "]"
    lines = [f"name: {name}", "sample_rate_hz: 1200", f"desk: {{{desk}}}", "accelerometers:"]
    lines += [f"  - {a}" for a in v["accelerometers"]]
    lines += ["sensors:"] + [f"  - {s}" for s in v["sensors"]]
    lines += [
        "surfaces:",
        f"  - {{name: top, origin: [0.0, 0.0, {height}], normal: [0, 0, 1], polygon: "
        f"[[-{half_x}, -{half_y}], [{half_x}, -{half_y}], [{half_x}, {half_y}], "
        f"[-{half_x}, {half_y}]]}}",
        f"  - {{name: front, origin: [0.0, -{half_y}, {middle}], normal: [0, -1, 0], "
        f"u_axis: [1, 0, 0], polygon: [[-{half_u}, -{half_v}], [{half_u}, -{half_v}], "
        f"[{half_u}, {half_v}], [-{half_u}, {half_v}]]}}",
        "estimation: {method: fused}",
    ]
    path = folder / f"{name}-{len(list(folder.iterdir()))}.yaml"
    path.write_text("\n".join(lines) + "\n")
    return load_profile(path)


def _calibration(half_u: float) -> Scene:
    """What the set-up asks (README, "Setting up a new desk"): firm presses near the panel's
    ends and on the top, here among taps (which the fit leaves out)."""
    steps: list[Action] = []
    for x in (-0.8 * half_u, 0.8 * half_u) * 2:
        steps += [Press(point=(x, 0.0), surface="front"), Press(point=(x / 2, 0.0))]
        steps.append(Tap(point=(x, 0.0), surface="front"))
    return Scene(steps, quiet_s=2.0)


def panel_variants(seeds: int) -> None:
    """Touch-down on each of :data:`PANEL_VARIANTS`: the yaw fitted from a calibration
    recording, then presses and taps estimated without the readings, with the box inertia
    and with the fitted one (``fused``; a miss counts as a miss)."""
    import touch_release_eval as tre  # beside this script

    from hapticdesk.analysis.characterize import characterize

    for name, v in PANEL_VARIANTS.items():
        with tempfile.TemporaryDirectory() as folder_name:
            folder = Path(folder_name)
            box = _variant_profile(name, v, folder)
            truth = np.diag(box.inertia_about_com()) * np.array(v["true"])
            true_desk = _variant_profile(name, v, folder, truth)
            found = characterize(box, simulate(true_desk, _calibration(v["panel"][1]), 100))
            fitted = (
                _variant_profile(name, v, folder, found.inertia_kg_m2)
                if found.inertia_kg_m2
                else box
            )
            rho = found.inertia.correlation if found.inertia else (0.0, 0.0, 0.0)
            print(
                f"{name}: {len(box.sensors)} legs, {box.mass_kg:g} kg, "
                f"{box.natural_frequency_hz:g} Hz; moments (roll, pitch, yaw) kg·m² true "
                f"{', '.join(f'{m:.3g}' for m in truth)}, box "
                f"{', '.join(f'{m:.3g}' for m in np.diag(box.inertia_about_com()))}, fitted "
                + (
                    ", ".join(f"{m:.3g}" for m in found.inertia_kg_m2)
                    if found.inertia_kg_m2
                    else "none"
                )
                + f" (yaw correlation {rho[2]:.3f})"
            )
            grid = [(x, y) for y in (0.5, 0.0, -0.5) for x in (-0.7, 0.0, 0.7)]
            spans = {"top": v["top"][1:], "front": v["panel"][1:]}
            for surface, (half_a, half_b) in spans.items():
                points = [(x * half_a, y * half_b) for x, y in grid]
                scene = tre.presses_and_taps(points, f"{name}-{surface}", surface=surface)
                runs = [simulate(true_desk, scene, seed) for seed in range(seeds)]
                for label, desk, use in (
                    ("without readings", box, False),
                    ("box inertia     ", box, True),
                    ("fitted inertia  ", fitted, True),
                ):
                    at = _touch_down_errors(desk, runs, use)
                    print(f"  {surface:5s} {label} " + _at_times_line(at))


def exact_compensation(desk: DeskProfile, scene: object, seed: int) -> Recording:
    """The run's readings less the desk's exact inertial wrench ``M q̈`` (rotation included),
    spread over the sensors by the pseudo-inverse of the wrench map: what a compensation that
    measured the desk's whole motion would give. Uses the simulator's inner parts (a bound
    for research, not a model the estimator could have)."""
    from hapticdesk.sim.simulator import CHUNK, SimulationRun
    from hapticdesk.sim.timeline import STREAM_NOISE, stream

    run = SimulationRun(desk, scene, seed)  # type: ignore[arg-type]
    assert run._discrete is not None
    spread = np.linalg.pinv(desk.wrench_map())
    ts, ws, cols = [], [], []
    state = None
    for c, k0 in enumerate(range(0, run.n_samples, CHUNK)):
        k1 = min(k0 + CHUNK, run.n_samples)
        loads, truth = run.timeline.render(k0, k1)
        loads += run._base
        if state is None:
            state = run._discrete.initial_state(loads[0])
        true, motion, state = run._discrete.run_moving(loads, state)
        inertial = run.model.accelerations(loads, motion) @ run.model.mass_matrix.T
        t = np.arange(k0, k1) / run.fs
        wrench = run.sensor_model.apply(
            true,
            t,
            noise_rng=stream(run.seed, STREAM_NOISE, c),
            drift=run._drift,
            quantisation=True,
            saturation=True,
        )
        ts.append(t)
        ws.append(wrench - (inertial @ spread.T).reshape(wrench.shape))
        cols.append(truth)
    extra = {k: np.concatenate([c[k] for c in cols]) for k in cols[0]}
    return Recording(np.concatenate(ts), np.concatenate(ws), desk.sensor_names, extra)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--desk", default="kitamura2017-accel")
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--panel", action="store_true", help="only touch-down on the panel desk")
    parser.add_argument(
        "--panel-variants", action="store_true", help="only touch-down on other panel desks"
    )
    args = parser.parse_args()
    started = time.perf_counter()
    if args.panel_variants:
        panel_variants(args.seeds)
        print(f"({time.perf_counter() - started:.0f} s)")
        return
    if args.panel:
        panel_touch_down(args.seeds)
        print(f"({time.perf_counter() - started:.0f} s)")
        return
    profile = load_profile(args.desk)
    print(f"desk {profile.name}, seeds 1..{args.seeds}")
    for scene_name in ("slider", "kita", "shapes"):
        scene = load_scene(SCENES / f"{scene_name}.yaml")
        found: dict[str, list[list[np.ndarray]]] = {how: [[], []] for how in COMPENSATIONS}
        for seed in range(1, args.seeds + 1):
            rec = simulate(profile, scene, seed)
            for how in COMPENSATIONS:
                err, shape = drag_errors(profile, rec, how)
                found[how][0].append(err)
                found[how][1].append(shape)
        for how, label in COMPENSATIONS.items():
            err, shape = (np.concatenate(x) * 1000 for x in found[how])
            print(
                f"  {scene_name:7s} {label}: "
                f"error p50 {np.percentile(err, 50):.2f} p95 {np.percentile(err, 95):.2f} mm; "
                f"lag taken out p50 {np.percentile(shape, 50):.2f} "
                f"p95 {np.percentile(shape, 95):.2f} mm ({len(err)} samples)"
            )
    scene = load_scene(SCENES / "swipes.yaml")
    rings: dict[bool, tuple[list[float], int]] = {True: ([], 0), False: ([], 0)}
    for seed in range(1, args.seeds + 1):
        rec = simulate(profile, scene, seed)
        for comp in (False, True):
            peaks, phantoms = ring(profile, rec, comp)
            rings[comp] = (rings[comp][0] + peaks, rings[comp][1] + phantoms)
    for comp in (False, True):
        peaks, phantoms = np.array(rings[comp][0]), rings[comp][1]
        print(
            f"  ring after a swipe {'with   ' if comp else 'without'} accelerometer: peak "
            f"force left median {np.median(peaks):.3f} N, max {peaks.max():.3f} N over "
            f"{len(peaks)} releases; phantom touch-downs {phantoms}"
        )
    print(f"({time.perf_counter() - started:.0f} s)")


if __name__ == "__main__":
    main()
