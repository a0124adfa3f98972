#!/usr/bin/env python3
"""The point hapticdesk locates on real force plates against the centre of pressure ezc3d
computes from the same C3D file (docs/forceplates.md prints this script's table).

For every plate of every file that carries load: the desk is built from the file's own
FORCE_PLATFORM parameters (:func:`hapticdesk.files.forceplate.plate_desk`), its analog
channels go through hapticdesk's estimator (`ContactEstimator.push`, the plate's own
estimation settings unless --lowpass/--method say otherwise), and each located point, taken
back to the lab frame, is compared with ezc3d's ``center_of_pressure`` at the same analog
sample. ezc3d's force-platform computation is only the yardstick: nothing of it is used to
locate. Compared are the samples where the plate carries more than 50 N (|F|, so whatever
axis is vertical) and ezc3d's point moves slower than 2 cm/s (its displacement over ±25 ms,
both ends loaded, over 50 ms). A file with fewer samples than that window (FP_Type3: 8)
is compared on every loaded sample, and also through the plate's map alone, unfiltered.

    python scripts/forceplate_accuracy.py                     # the table of docs/forceplates.md
    python scripts/forceplate_accuracy.py --lowpass 4.77 --lowpass 20 --lowpass 50   # a sweep
    python scripts/forceplate_accuracy.py --data DIR --json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from hapticdesk.estimator import ContactEstimator
from hapticdesk.files.c3d import import_ezc3d, open_c3d
from hapticdesk.files.forceplate import PlateDesk, plate_desk, read_plate_recording
from hapticdesk.files.plate_parameters import plate_count
from hapticdesk.files.profile import METHODS

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "forceplates"
FILES = ("BTS.c3d", "Qualisys.c3d", "FP_Type3.c3d")
LOAD_N = 50.0
SPEED_M_S = 0.02
HALF_WINDOW_S = 0.025  # the point's speed: its displacement over ±25 ms


def compare(
    desk: PlateDesk, t: np.ndarray, wrench: np.ndarray, cop_mm: np.ndarray, force: np.ndarray
) -> dict[str, object]:
    """One plate: the estimator's points against ezc3d's (mm, lab) on the loaded samples,
    and on those of them where ezc3d's point moves slower than 2 cm/s."""
    estimator = ContactEstimator(desk.profile)
    start = time.perf_counter()
    block = estimator.push(t, wrench)
    seconds = time.perf_counter() - start
    k = len(t)
    loaded = np.linalg.norm(force, axis=1) > LOAD_N
    rate = desk.profile.sample_rate_hz
    h = round(HALF_WINDOW_S * rate)
    speed = np.full(k, np.nan)  # NaN: too near the file's ends or a step's edge to tell
    if k > 2 * h:
        ends = loaded[: k - 2 * h] & loaded[2 * h :]
        step = np.linalg.norm(cop_mm[2 * h :] - cop_mm[: k - 2 * h], axis=1) / 1000.0
        speed[h : k - h] = np.where(ends, step / (2 * h / rate), np.nan)
    idx = np.flatnonzero(loaded)
    located = block.located[idx]
    points = np.stack([block.x, block.y, block.z], axis=1)[idx[located]]
    err = np.full(len(idx), np.nan)
    err[located] = np.linalg.norm(desk.to_lab(points) * 1000.0 - cop_mm[idx[located]], axis=1)
    slow = speed[idx] < SPEED_M_S

    def stats(where: np.ndarray) -> tuple[int, float, float, float]:
        e = err[where]
        got = e[np.isfinite(e)]
        if not got.size:  # (none located: 0 %, no error to take a median of)
            share = 0.0 if e.size else float("nan")
            return int(where.sum()), share, float("nan"), float("nan")
        share = got.size / e.size
        return int(where.sum()), share, float(np.median(got)), float(np.percentile(got, 95))

    n_all, share, median, p95 = stats(np.ones(len(idx), bool))
    n_slow, share_slow, _, p95_slow = stats(slow)
    moving = speed[idx][np.isfinite(speed[idx])]
    return {
        "plate": desk.plate.number,
        "type": desk.plate.type,
        "rate_hz": rate,
        "method": desk.profile.estimation.method,
        "lowpass_hz": desk.profile.estimation.force_lowpass_hz,
        "loaded": n_all,
        "located_share": share,
        "median_mm": median,
        "p95_mm": p95,
        "max_mm": float(np.nanmax(err)) if np.isfinite(err).any() else float("nan"),
        "slow": n_slow,
        "slow_located_share": share_slow,
        "slow_p95_mm": p95_slow,
        "median_speed_m_s": float(np.median(moving)) if moving.size else float("nan"),
        "estimate_s": seconds,
        "samples_per_s": k / seconds if seconds > 0 else float("nan"),
        "delay_ms": 1000.0 * estimator.position_delay_s,
    }


def unfiltered(desk: PlateDesk, wrench: np.ndarray, cop_mm: np.ndarray, force: np.ndarray) -> float:
    """The largest distance (mm) on loaded samples between ezc3d's point and the plate's map
    alone: [F; M] = A · channels (the profile's wrench map), x = −M_y / F_z, y = M_x / F_z on
    the top (z = 0, the desk's frame), taken to the lab."""
    w = desk.profile.flat_channels(wrench) @ desk.profile.wrench_map().T
    loaded = np.linalg.norm(force, axis=1) > LOAD_N
    f, m = w[loaded, :3], w[loaded, 3:]
    points = np.stack([-m[:, 1] / f[:, 2], m[:, 0] / f[:, 2], np.zeros(len(f))], axis=1)
    return float(np.linalg.norm(desk.to_lab(points) * 1000.0 - cop_mm[loaded], axis=1).max())


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, default=DATA, help="folder of the C3D files")
    parser.add_argument(
        "--lowpass", type=float, action="append", help="force low-pass, Hz (repeat: a sweep)"
    )
    parser.add_argument("--method", choices=METHODS, help="override the plate's method")
    parser.add_argument("--json", action="store_true", help="one JSON object per row")
    args = parser.parse_args(argv)
    ezc3d = import_ezc3d()
    if not any((args.data / name).is_file() for name in FILES):  # (not an empty table)
        print(
            f"forceplate_accuracy: error: none of {', '.join(FILES)} is in {args.data}: "
            "give their folder with --data DIR",
            file=sys.stderr,
        )
        return 2
    rows = []
    for name in FILES:
        path = args.data / name
        if not path.is_file():
            print(f"skipped {path}: not there", file=sys.stderr)
            continue
        file = open_c3d(path)
        platforms = ezc3d.c3d(str(path), extract_forceplat_data=True)["data"]["platform"]
        for number in range(1, plate_count(file) + 1):
            force = np.asarray(platforms[number - 1]["force"]).T
            if not (np.linalg.norm(force, axis=1) > LOAD_N).any():
                continue  # an unloaded plate: nothing to locate
            cop = np.asarray(platforms[number - 1]["center_of_pressure"]).T
            built = plate_desk(file, number)
            recording = read_plate_recording(path, built.profile, file)
            for lowpass in args.lowpass or [None]:
                desk = built
                changes: dict[str, object] = {}
                if lowpass is not None:
                    changes.update(force_lowpass_hz=lowpass, diff_lowpass_hz=lowpass)
                if args.method:
                    changes["method"] = args.method
                if changes:
                    desk = PlateDesk(
                        built.profile.with_estimation(**changes),
                        built.plate,
                        built.lab_rotation,
                        built.lab_origin,
                        built.point_metres,
                    )
                row = {"file": name, **compare(desk, recording.t, recording.wrench, cop, force)}
                row["map_max_mm"] = unfiltered(built, recording.wrench, cop, force)
                rows.append(row)
    if args.json:
        for row in rows:
            print(json.dumps(row))
        return 0
    print(
        "| file | plate (type) | loaded > 50 N | located | median | p95 | of them < 2 cm/s "
        "(p95) | method, low-pass (lag) | cost | map alone, max |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        slow = f"{r['slow']}" + (f" ({_mm(r['slow_p95_mm'])})" if r["slow"] else "")
        print(
            f"| {r['file']} | {r['plate']} ({r['type']}) | {r['loaded']} "
            f"({r['rate_hz']:g} Hz) | {100 * r['located_share']:.1f} % | "
            f"{_mm(r['median_mm'])} | {_mm(r['p95_mm'])} | {slow} | {r['method']}, "
            f"{r['lowpass_hz']:g} Hz ({r['delay_ms']:.1f} ms) | "
            f"{r['samples_per_s'] / 1e6:.1f} M samples/s | {r['map_max_mm']:.0e} mm |"
        )
    return 0


def _mm(value: float) -> str:
    """A distance for the table; "–" where nothing was located to measure it."""
    return f"{value:.2f} mm" if np.isfinite(value) else "–"


if __name__ == "__main__":
    sys.exit(main())
