#!/usr/bin/env python3
"""Record or check the estimator's outputs (the golden file of tests/core/test_core_golden.py).

Behind a refactor of the estimator its outputs must stay equal (to 1e-9) on the paper, shelf
and day scenes, and on two desks with accelerometers (one; three, one board's readings lost
for a while), for every method, in batch and in 1- and 7-sample pushes. ``--write`` records
them from the code as it is; ``--check`` compares the code as it is now against a recording.
``--short`` uses the shortened scenes the committed golden file holds (a few seconds of each);
without it the full scenes are used (a local check before and after a refactor: a few MB).

    python scripts/golden_contacts.py --write /tmp/golden.npz [--short]
    python scripts/golden_contacts.py --check /tmp/golden.npz [--short] [--pushes]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from hapticdesk.bench.scenes import desk_day, paper_experiment
from hapticdesk.estimator import ContactEstimator
from hapticdesk.estimator.inertia import accelerometer_readings
from hapticdesk.files.profile import METHODS, DeskProfile
from hapticdesk.files.profile_reader import load_profile
from hapticdesk.files.recording import Recording
from hapticdesk.sim import Press, Scene, Swipe, simulate

FIELDS = ("in_contact", "located", "surface", "x", "y", "z", "force_n", "source", "phase")
FIELDS += ("sigma_m", "flags")
TOLERANCE = 1e-9


def _scenes(short: bool) -> dict[str, tuple[str, Scene]]:
    """name -> (profile, scene); the short ones keep the first seconds of each."""
    shelf = Scene(
        actions=[
            Press(point=(0.1, 0.3), surface="shelf"),
            Press(point=(-0.2, 0.1)),
            Press(point=(-0.3, 0.35), surface="shelf"),
        ],
        quiet_s=2.0,
        name="shelf",
    )
    paper = paper_experiment()
    day = desk_day(minutes=0.5 if short else 10.0)
    if short:
        paper = Scene(actions=paper.actions[:3], quiet_s=paper.quiet_s, name="paper-short")
    accel = Scene(
        actions=[Swipe(from_point=(-0.2, 0.0), to_point=(0.1, 0.0)), Press(point=(-0.2, -0.1))],
        quiet_s=2.0,
        name="accel",
    )
    panel = Scene(
        actions=[Press(point=(-0.25, 0.0), surface="front", hold_s=1.0)],
        quiet_s=2.0,
        name="panel-accel",
    )
    return {
        "paper": ("kitamura2017", paper),
        "shelf": ("kitamura2017-shelf", shelf),
        "day": ("kitamura2017", day),
        "accel": ("kitamura2017-accel", accel),
        "panel-accel": ("kitamura2017-panel-accel", panel),
    }


def _readings(desk: DeskProfile, rec: Recording) -> np.ndarray | None:
    """The desk's accelerometer readings; on a desk with several, the second board's lost
    for 0.8 s from 2.4 s on (the partial-readings path, in the press) and one reading at
    its range."""
    accel = accelerometer_readings(desk, rec.extra)
    if accel is None or len(desk.accelerometers) < 2:
        return accel
    accel = accel.copy()
    fs = desk.sample_rate_hz
    accel[int(2.4 * fs) : int(3.2 * fs), 3:6] = np.nan
    accel[int(3.5 * fs), 0] = desk.accelerometers[0].range_m_s2
    return accel


def _pushed(
    est: ContactEstimator, t: np.ndarray, w: np.ndarray, k: int, accel: np.ndarray | None
) -> dict[str, np.ndarray]:
    blocks = [
        est.push(t[i : i + k], w[i : i + k], None if accel is None else accel[i : i + k])
        for i in range(0, len(t), k)
    ]
    return {f: np.concatenate([getattr(b, f) for b in blocks]) for f in FIELDS}


def _thinned(fields: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Float fields kept where a contact is located and at every 16th sample elsewhere (the
    committed file stays small); the integer and boolean fields whole."""
    keep = fields["located"] | (np.arange(len(fields["located"])) % 16 == 0)
    return {f: v[keep] if v.dtype.kind == "f" else v for f, v in fields.items()}


def golden_outputs(short: bool, pushes: bool) -> dict[str, np.ndarray]:
    """Every field of the estimator's contacts, per scene, method and push size (thinned
    with ``short``)."""
    out: dict[str, np.ndarray] = {}
    for scene_name, (desk_name, scene) in _scenes(short).items():
        desk = load_profile(desk_name)
        rec = simulate(desk, scene, seed=0)
        accel = _readings(desk, rec)
        for method in METHODS:
            sizes = ("batch", 1, 7) if pushes else ("batch",)
            for size in sizes:
                est = ContactEstimator(desk, method=method)
                k = len(rec.t) if size == "batch" else int(size)
                fields = _pushed(est, rec.t, rec.wrench, k, accel)
                if short:
                    fields = _thinned(fields)
                for f, values in fields.items():
                    out[f"{scene_name}/{method}/{size}/{f}"] = values
                notices = "\n".join(f"{n.t:.9f} {n.kind} {n.message}" for n in est.notices)
                out[f"{scene_name}/{method}/{size}/notices"] = np.array(notices)
    return out


def check_golden(now: dict[str, np.ndarray], stored: dict[str, np.ndarray]) -> list[str]:
    """What differs between two sets of outputs (push sizes missing from ``now`` are skipped)."""
    problems = []
    for key, expected in stored.items():
        if key not in now:
            if "/batch/" in key:
                problems.append(f"{key}: missing")
            continue
        got = now[key]
        if got.shape != expected.shape:
            problems.append(f"{key}: shape {got.shape}, expected {expected.shape}")
        elif got.dtype.kind in "fc":
            worst = float(np.max(np.abs(got - expected), initial=0.0))
            if not worst <= TOLERANCE:
                problems.append(f"{key}: differs by up to {worst:.3g}")
        elif not np.array_equal(got, expected):
            bad = int(np.sum(got != expected)) if got.ndim else 1
            problems.append(f"{key}: {bad} values differ")
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
        np.savez_compressed(args.write, **outputs)
        print(f"wrote {len(outputs)} arrays to {args.write}")
        return 0
    with np.load(args.check) as stored:
        problems = check_golden(outputs, dict(stored))
    for line in problems:
        print(line)
    print(f"{len(outputs)} arrays compared, {len(problems)} differ")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
