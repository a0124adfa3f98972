#!/usr/bin/env python3
"""Record or check the estimator's outputs (the golden file of tests/core/test_core_golden.py).

Behind a refactor of the estimator its outputs must stay equal (to 1e-9, relative for values
above 1) on every desk it is judged on, for every method, in batch and in 1- and 7-sample
pushes: every field of its contact blocks, its notices and, on the paper scene, the
candidates it traces. The scenes:

- ``paper``, ``shelf``, ``day``: the paper's desk (its experiment, a shelf, ordinary use);
- ``accel``, ``panel-accel``: one accelerometer; three (one board's readings lost for a
  while, one reading at its range); ``accel-missing``: the accelerometer desk without its
  readings; ``panel``: the upright front panel without an accelerometer;
- ``unseen-six``, ``unseen-four`` (scripts/tap_accuracy.py) and ``unseen-wide``
  (scripts/touch_release_eval.py), the last with a separate low-pass for the differentiated
  force (the filter bank's second path);
- ``objects``: objects put down and lifted (the object rule, the resting flag, the lift);
  ``two-finger``: the second-finger stage on, pairs and single touches; ``hostile``: a NaN
  burst, a saturated sample, time going back, a gap and a stuck input; ``noise-free``: the
  ideal sensors (no stuck check); ``quiet``: a sensor quieter than its resolution step (the
  steps learned at the first touches, the covariances made anew).

``--write`` records them from the code as it is; ``--check`` compares the code as it is now
against a recording. ``--short`` uses the shortened scenes the committed golden file holds
(a few seconds of each); without it the full scenes are used (a local check before and after
a refactor: a few MB).

    python scripts/golden_contacts.py --write /tmp/golden.npz [--short]
    python scripts/golden_contacts.py --check /tmp/golden.npz [--short] [--pushes]
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
from collections.abc import Callable
from dataclasses import dataclass, fields
from functools import cache
from pathlib import Path
from types import ModuleType

import numpy as np

from hapticdesk.bench.scenes import desk_day, paper_experiment
from hapticdesk.estimator import CandidateTrace, ContactEstimator
from hapticdesk.estimator.contacts import ContactBlock
from hapticdesk.estimator.inertia import accelerometer_readings
from hapticdesk.files.profile import METHODS, DeskProfile
from hapticdesk.files.profile_reader import load_profile
from hapticdesk.files.recording import Recording
from hapticdesk.sim import Press, Scene, SimEffects, Swipe, Tap, simulate
from hapticdesk.sim.actions import Idle, LiftObject, PutObject
from hapticdesk.sim.sensors import SensorParameters

SCRIPTS = Path(__file__).resolve().parent
FIELDS = tuple(f.name for f in fields(ContactBlock))
TRACE_FIELDS = tuple(f.name for f in fields(CandidateTrace))
TOLERANCE = 1e-9


@dataclass(frozen=True)
class GoldenScene:
    """A desk, a scene on it and how its recording is fed to the estimator."""

    desk: Callable[[], DeskProfile]
    scene: Scene
    accel: str = "given"  # the accelerometer's readings: given, lossy (see _readings), none
    effects: SimEffects | None = None
    sensors: SensorParameters | None = None
    spoil: Callable[[DeskProfile, Recording], Recording] | None = None  # faults put in
    trace: bool = False  # also the candidates traced (CandidateTrace)


@cache
def _script(name: str) -> ModuleType:
    """A script beside this one, as a module (for its desks)."""
    spec = importlib.util.spec_from_file_location(name, SCRIPTS / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # (its dataclasses look their module up)
    sys.path.insert(0, str(SCRIPTS))  # (the scripts import each other)
    try:
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(SCRIPTS))
    return module


def _unseen(name: str) -> DeskProfile:
    return _script("tap_accuracy").unseen_desk(name, "switched")


def _unseen_wide() -> DeskProfile:
    # a low-pass of its own for the differentiated force: the filter bank's second path
    return _script("touch_release_eval").unseen_desk().with_estimation(diff_lowpass_hz=3.5)


def _two_finger_desk() -> DeskProfile:
    return load_profile("kitamura2017").with_estimation(second_finger=True)


def _spoiled(desk: DeskProfile, rec: Recording) -> Recording:
    """A NaN burst in a press, a saturated sample, time going back once, a gap and a stuck
    input (a long spell, and a short one soon after it ended)."""
    fs = desk.sample_rate_hz
    t, w = rec.t.copy(), rec.wrench.copy()
    at = [int(s * fs) for s in (2.6, 3.1, 3.4, 3.9, 4.4, 5.45)]
    w[at[0] : at[0] + 10, 2, 1] = np.nan
    limits = desk.saturation_limits()
    w[at[1], 1, 2] = 300.0 if limits is None else limits[1, 2]
    t[at[2]] = t[at[2] - 1] - 0.001
    w[at[3] : at[3] + 300] = w[at[3] - 1]
    t[at[4] :] += 0.2
    w[at[5] : at[5] + 12] = w[at[5] - 1]
    return Recording(t, w, rec.sensor_names, rec.extra)


def _scenes(short: bool) -> dict[str, GoldenScene]:
    """name -> how it is made; the short ones keep the first seconds of each."""
    paper = paper_experiment()
    if short:
        paper = Scene(actions=paper.actions[:3], quiet_s=paper.quiet_s, name="paper-short")
    presses = Scene(
        actions=[
            Press(point=(0.1, -0.1)),
            Tap(point=(-0.2, 0.1), wait_s=0.4),
            Swipe(from_point=(-0.2, -0.1), to_point=(0.2, -0.05), wait_s=0.4),
        ],
        quiet_s=2.0,
        name="presses",
    )
    objects = Scene(
        actions=[
            PutObject(name="cup", mass_kg=0.3, point=(0.2, 0.1)),
            Idle(duration_s=2.0),
            Press(point=(-0.1, -0.1)),
            PutObject(name="book", mass_kg=1.5, point=(-0.25, 0.15), wait_s=0.5),
            Idle(duration_s=1.5),
            LiftObject(name="book"),
            Idle(duration_s=1.5),
        ],
        quiet_s=2.0,
        name="objects",
    )
    two = Scene(
        actions=[
            Press(point=(-0.1, 0.0), hold_s=1.2),
            Press(point=(0.15, 0.1), hold_s=0.5, start_s=2.9),
            Press(point=(0.1, -0.1), hold_s=0.6, start_s=5.5),
            Tap(point=(-0.2, 0.1), start_s=7.5),
        ],
        quiet_s=2.0,
        name="two-finger",
    )
    taps = Scene(
        actions=[Idle(duration_s=2.0)]
        + [
            Tap(point=(0.1 * i - 0.2, 0.05), peak_n=4.0, duration_s=0.12, wait_s=0.5)
            for i in range(4)
        ],
        name="quiet",
    )
    return {
        "paper": GoldenScene(lambda: load_profile("kitamura2017"), paper, trace=True),
        "shelf": GoldenScene(
            lambda: load_profile("kitamura2017-shelf"),
            Scene(
                actions=[
                    Press(point=(0.1, 0.3), surface="shelf"),
                    Press(point=(-0.2, 0.1)),
                    Press(point=(-0.3, 0.35), surface="shelf"),
                ],
                quiet_s=2.0,
                name="shelf",
            ),
        ),
        "day": GoldenScene(
            lambda: load_profile("kitamura2017"), desk_day(minutes=0.5 if short else 10.0)
        ),
        "accel": GoldenScene(
            lambda: load_profile("kitamura2017-accel"),
            Scene(
                actions=[
                    Swipe(from_point=(-0.2, 0.0), to_point=(0.1, 0.0)),
                    Press(point=(-0.2, -0.1)),
                ],
                quiet_s=2.0,
                name="accel",
            ),
        ),
        "accel-missing": GoldenScene(
            lambda: load_profile("kitamura2017-accel"),
            Scene(actions=[Press(point=(-0.2, -0.1))], quiet_s=2.0, name="accel-missing"),
            accel="none",
        ),
        "panel-accel": GoldenScene(
            lambda: load_profile("kitamura2017-panel-accel"),
            Scene(
                actions=[Press(point=(-0.25, 0.0), surface="front", hold_s=1.0)],
                quiet_s=2.0,
                name="panel-accel",
            ),
            accel="lossy",
        ),
        "panel": GoldenScene(
            lambda: load_profile("kitamura2017-panel"),
            Scene(
                actions=[
                    Press(point=(0.2, 0.03), surface="front", hold_s=0.8),
                    Press(point=(-0.1, 0.1), wait_s=0.5),
                    Tap(point=(-0.3, -0.02), surface="front", wait_s=0.5),
                ],
                quiet_s=2.0,
                name="panel",
            ),
        ),
        "unseen-six": GoldenScene(lambda: _unseen("unseen-six"), presses),
        "unseen-four": GoldenScene(lambda: _unseen("unseen-four"), presses),
        "unseen-wide": GoldenScene(_unseen_wide, presses),
        "objects": GoldenScene(lambda: load_profile("kitamura2017"), objects),
        "two-finger": GoldenScene(_two_finger_desk, two),
        "hostile": GoldenScene(lambda: load_profile("kitamura2017"), presses, spoil=_spoiled),
        "noise-free": GoldenScene(
            lambda: load_profile("kitamura2017"), presses, effects=SimEffects.ideal()
        ),
        "quiet": GoldenScene(
            lambda: load_profile("kitamura2017"),
            taps,
            sensors=SensorParameters(noise_amplitude_n=0.1),
        ),
    }


def _readings(desk: DeskProfile, rec: Recording, how: str) -> np.ndarray | None:
    """The desk's accelerometer readings as ``how`` says: ``given``; ``none``; ``lossy``: on a
    desk with several, the second board's lost for 0.8 s from 2.4 s on (the partial-readings
    path, in the press) and one reading at its range."""
    accel = accelerometer_readings(desk, rec.extra)
    if accel is None or how == "none":
        return None
    if how == "given" or len(desk.accelerometers) < 2:
        return accel
    accel = accel.copy()
    fs = desk.sample_rate_hz
    accel[int(2.4 * fs) : int(3.2 * fs), 3:6] = np.nan
    accel[int(3.5 * fs), 0] = desk.accelerometers[0].range_m_s2
    return accel


def _pushed(
    est: ContactEstimator, t: np.ndarray, w: np.ndarray, k: int, accel: np.ndarray | None
) -> dict[str, np.ndarray]:
    """Every field of the contacts of (t, w) pushed ``k`` samples at a time (each block
    copied as it comes: a block is the estimator's until its next push)."""
    blocks = []
    for i in range(0, len(t), k):
        block = est.push(t[i : i + k], w[i : i + k], None if accel is None else accel[i : i + k])
        blocks.append({f: np.array(getattr(block, f)) for f in FIELDS})
    return {f: np.concatenate([b[f] for b in blocks]) for f in FIELDS}


#: the fields whose changes mark the samples every float field is kept at (see _thinned)
EVENT_FIELDS = ("in_contact", "located", "surface", "source", "phase", "flags", "located2")
EVENT_FIELDS += ("resting",)


def _thinned(fields: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The integer and boolean fields whole; the float fields (the committed file stays
    small) at every sample next to a change of an integer or boolean field (a touch-down, a
    release, a switch of candidate, a flag), at every 8th located sample and at every 64th
    sample elsewhere. The samples kept follow from the outputs themselves, so outputs that
    differ there differ in what is kept too."""
    n = len(fields["located"])
    change = np.zeros(n, bool)
    for name in EVENT_FIELDS:
        values = fields[name]
        change[1:] |= values[1:] != values[:-1]
    near = change.copy()
    near[:-1] |= change[1:]
    near[1:] |= change[:-1]
    located = fields["located"]
    keep = near | (located & (np.cumsum(located) % 8 == 0)) | (np.arange(n) % 64 == 0)
    return {f: v[keep] if v.dtype.kind == "f" else v for f, v in fields.items()}


def golden_outputs(short: bool, pushes: bool) -> dict[str, np.ndarray]:
    """Every field of the estimator's contacts, per scene, method and push size (thinned
    with ``short``), its notices, and the traced candidates of the scenes that ask."""
    out: dict[str, np.ndarray] = {}
    for scene_name, golden in _scenes(short).items():
        desk = golden.desk()
        rec = simulate(desk, golden.scene, seed=0, effects=golden.effects, sensors=golden.sensors)
        if golden.spoil is not None:
            rec = golden.spoil(desk, rec)
        accel = _readings(desk, rec, golden.accel)
        for method in METHODS:
            sizes = ("batch", 1, 7) if pushes else ("batch",)
            for size in sizes:
                trace = golden.trace and size == "batch"
                est = ContactEstimator(desk, method=method, trace=trace)
                k = len(rec.t) if size == "batch" else int(size)
                outputs = _pushed(est, rec.t, rec.wrench, k, accel)
                if short:
                    outputs = _thinned(outputs)
                for f, values in outputs.items():
                    out[f"{scene_name}/{method}/{size}/{f}"] = values
                notices = "\n".join(f"{n.t:.9f} {n.kind} {n.message}" for n in est.notices)
                out[f"{scene_name}/{method}/{size}/notices"] = np.array(notices)
                if trace:
                    traced = CandidateTrace.concat(est.traces)
                    every = 8 if short else 1
                    for f in TRACE_FIELDS:
                        out[f"{scene_name}/{method}/trace/{f}"] = getattr(traced, f)[..., ::every]
    return out


def batch_key(key: str) -> str:
    """The key of the batch's record of the same field (a push's record is only stored
    where it differs from the batch's)."""
    scene, method, _, name = key.split("/")
    return f"{scene}/{method}/batch/{name}"


def without_repeats(outputs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The outputs to store: the batch's, and a push's only where it differs from it."""
    return {
        key: values
        for key, values in outputs.items()
        if key == batch_key(key) or "/trace/" in key or _compare(values, outputs[batch_key(key)])
    }


def differs(got: np.ndarray, expected: np.ndarray) -> float:
    """The largest difference of two float arrays, relative where a value exceeds 1."""
    if got.size == 0:
        return 0.0
    scale = np.maximum(np.abs(expected), 1.0)
    return float(np.max(np.abs(got - expected) / scale))


def _compare(got: np.ndarray, expected: np.ndarray) -> str | None:
    """How ``got`` differs from ``expected``, or None where it does not."""
    if got.shape != expected.shape:
        return f"shape {got.shape}, expected {expected.shape}"
    if got.dtype.kind in "fc":
        worst = differs(got, expected)
        return None if worst <= TOLERANCE else f"differs by up to {worst:.3g}"
    if not np.array_equal(got, expected):
        return f"{int(np.sum(got != expected)) if got.ndim else 1} values differ"
    return None


def single_key(key: str) -> str:
    """The key of the single-sample pushes' record of the same field."""
    scene, method, _, name = key.split("/")
    return f"{scene}/{method}/1/{name}"


def check_golden(now: dict[str, np.ndarray], stored: dict[str, np.ndarray]) -> list[str]:
    """What differs between outputs ``now`` and the ``stored`` ones; a stored batch record
    missing ``now`` is a difference too.

    Every push size is judged against the record of single-sample pushes where there is one,
    else against the batch's. The estimator is one compiled pass per sample since main
    b5a43bd: any split gives the same, and the same as a sample at a time did on main. Main
    stored single samples apart only on two scenes (noise-free, quiet), where its batch and
    7-sample pushes made the covariances anew once per push, after a resolution step was
    learned somewhere in it; now they are made anew at the sample whose reading taught the
    step, as main's single-sample pushes did (so its batch and 7-sample records there, in
    sigma_m and in fused's choice, are main's per-push behaviour, no longer the reference).
    """
    problems = [f"{key}: missing" for key in stored if key == batch_key(key) and key not in now]
    for key, got in now.items():
        expected = stored.get(key) if "/trace/" in key else None
        if expected is None:
            expected = stored.get(single_key(key))
        if expected is None:
            expected = stored.get(batch_key(key))
        if expected is None:
            problems.append(f"{key}: not recorded")
            continue
        problem = _compare(got, expected)
        if problem is not None:
            problems.append(f"{key}: {problem}")
    return problems


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    group = parser.add_mutually_exclusive_group(required=True)
    group.add_argument("--write", type=Path)
    group.add_argument("--check", type=Path)
    parser.add_argument("--short", action="store_true", help="the committed golden's short scenes")
    parser.add_argument(
        "--pushes", action="store_true", help="also 1- and 7-sample pushes (slow on full scenes)"
    )
    args = parser.parse_args()
    outputs = golden_outputs(short=args.short, pushes=args.pushes)
    if args.write:
        stored = without_repeats(outputs)
        np.savez_compressed(args.write, **stored)
        print(f"wrote {len(stored)} arrays to {args.write}")
        return 0
    with np.load(args.check) as stored:
        problems = check_golden(outputs, dict(stored))
    for line in problems:
        print(line)
    print(f"{len(outputs)} arrays compared, {len(problems)} differ")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
