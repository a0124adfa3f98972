"""``hapticdesk simulate SCENE --desk DESK -o REC.csv|npz [--seed N]``: a scene on a simulated
desk into a recording (docs: File formats) with ground-truth columns ``true_x, true_y, true_fn``
(and ``true_z, true_fx, true_fy, true_fz, true_surface, true_action``)."""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import NamedTuple

import numpy as np

from hapticdesk.commands import seed_number
from hapticdesk.commands.output_path import cannot_write
from hapticdesk.errors import ConfigError
from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.profile_reader import load_profile
from hapticdesk.files.recording_io import RECORDING_SUFFIXES, write_recording
from hapticdesk.sim.loadcells import LoadCellParameters, with_total_amplitude
from hapticdesk.sim.scene import load_scene
from hapticdesk.sim.sensors import SensorParameters
from hapticdesk.sim.simulator import SimEffects, simulate

DEFAULT_DESK = "kitamura2017"

#: the most noise (N, amplitude on the total F_z) a simulated sensor is given
MAX_NOISE_N = 1e3


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "scene", help="scene file (YAML), e.g. examples/scenes/paper-experiment.yaml"
    )
    parser.add_argument(
        "--desk",
        help=f"desk profile name or path (default: the scene's `desk:`, else {DEFAULT_DESK})",
    )
    parser.add_argument("-o", "--output", required=True, help="recording to write (.csv or .npz)")
    parser.add_argument(
        "--seed", type=seed_number, help="random seed (default: the scene's `seed:`, else 0)"
    )
    parser.add_argument(
        "--no-noise", action="store_true", help="no sensor noise, zero offset or drift"
    )
    parser.add_argument(
        "--static", action="store_true", help="no desk dynamics: loads split statically"
    )
    parser.add_argument(
        "--ideal",
        action="store_true",
        help="statics only and perfect sensors (no noise, drift, resolution or saturation)",
    )
    parser.add_argument(
        "--noise-amplitude",
        type=float,
        metavar="N",
        help="noise amplitude on the total F_z at rest, newtons (3σ; default the paper's 0.4, "
        "or a load-cell desk's converter's)",
    )
    parser.add_argument("--json", action="store_true", help="print a JSON summary")


def run(args: argparse.Namespace) -> int:
    output = Path(args.output)
    if output.suffix.lower() not in RECORDING_SUFFIXES:
        raise ConfigError(
            str(output), f"unknown recording format {output.suffix!r}; expected .csv or .npz"
        )
    scene = load_scene(args.scene)
    if args.desk is not None:
        profile = load_profile(args.desk)
    else:
        relative = scene.path.parent if scene.path is not None else None
        profile = load_profile(scene.desk or DEFAULT_DESK, relative_to=relative)
    effects = SimEffects.ideal() if args.ideal else SimEffects(dynamics=not args.static)
    noise = _noise_amplitude(args.noise_amplitude, profile)
    start = time.perf_counter()
    rec = simulate(
        profile,
        scene,
        args.seed,
        noise=not args.no_noise,
        effects=effects,
        sensors=noise.sensors,
        cells=noise.cells,
    )
    seconds = time.perf_counter() - start
    try:
        write_recording(output, rec)
    except OSError as err:
        raise cannot_write(output, err) from None
    touching = rec.extra["true_fn"] > 0
    touches = int(np.count_nonzero(touching[1:] & ~touching[:-1]) + int(touching[:1].sum()))
    seed = scene.seed if args.seed is None else args.seed
    summary = {
        "output": str(output),
        "scene": scene.name,
        "desk": profile.name,
        "seed": seed,
        "samples": len(rec),
        "duration_s": round(float(rec.t[-1]), 6) if len(rec) else 0.0,
        "sample_rate_hz": profile.sample_rate_hz,
        "touches": touches,
        "simulate_seconds": round(seconds, 4),
    }
    if args.json:
        print(json.dumps(summary))
    else:
        print(
            f"wrote {output}: {summary['samples']} samples ({summary['duration_s']:.2f} s at "
            f"{profile.sample_rate_hz:g} Hz) on desk {profile.name}, {touches} touches, "
            f"seed {seed}"
        )
    return 0


class _SensorNoise(NamedTuple):
    """``--noise-amplitude`` as the simulator takes it: six-axis sensors' parameters or load
    cells' (the same amplitude on the total F_z, shared by the cells); None: the defaults."""

    sensors: SensorParameters | None = None
    cells: LoadCellParameters | None = None


def _noise_amplitude(amplitude: float | None, profile: DeskProfile) -> _SensorNoise:
    if amplitude is None:
        return _SensorNoise()
    if not 0 <= amplitude <= MAX_NOISE_N:  # (NaN too)
        raise ConfigError("--noise-amplitude", f"must be 0 to {MAX_NOISE_N:g} N, found {amplitude}")
    if profile.six_axis_only:
        return _SensorNoise(sensors=SensorParameters(noise_amplitude_n=amplitude))
    return _SensorNoise(cells=with_total_amplitude(profile, amplitude))
