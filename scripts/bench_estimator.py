#!/usr/bin/env python3
"""Benchmark of the contact estimator alone (issues 2, 15): against an independent reference,
in batch and streaming, as medians.

Input, simulated on the paper's four-sensor desk with the paper's noise: ``--scene paper`` the
paper's experiment (presses one after the other, about three quarters of the samples in
contact: the worst case) or ``--scene day`` ordinary use (about a tenth in contact).

1. One minute (72,000 samples): each method of ``hapticdesk.estimator`` and the plain
   vectorised numpy/scipy version of the paper's method in ``scripts/reference_paper.py``
   (``force``, ``diff``, ``switched``), run in turn in this process, ``--repeats`` times
   each; the figure is the median. ``× ref`` is the reference's time over the method's (the
   reference's own method, or its ``switched`` for ``fused``). ``floor`` is what every
   sample must go through in this design before anything is detected or located: the wrench
   map and the estimator's own filter bank (:class:`FilterBank`, the method's filters) in
   the same pieces as a push; ``floor × ref`` bounds what the method's ``× ref`` can reach.
   ``ref floor`` is the reference's own share of that: its map, tare and two filters
   (``reference_filtered``), which any implementation of the paper's method must compute;
   the last line says how it compares with half the reference's time (a method twice as
   fast as the reference must finish in that half).
2. A long batch (``--samples``, 2 million by default: the recording repeated), medians of
   ``--batch-repeats`` runs; ``--samples 0`` skips it.
3. Streaming: 10 s after the tare pushed one sample at a time and in blocks of 12, each push
   timed: the median µs per push, overall and while in contact, its 99.9th percentile and
   maximum, and how many pushes a second take over 3× the median (a slow path every 0.2 s
   window would show as ≥ 5 a second).

The targets are for one core, so the process is pinned to one CPU and the linear algebra
library to one thread (``--all-cores`` lifts both). Noisy on a shared machine: the ratios,
measured side by side, are the figures to trust.

    python scripts/bench_estimator.py [--scene paper|day] [--repeats 9] [--samples 2000000]
        [--json]
"""

from __future__ import annotations

import os
import sys

if "--all-cores" not in sys.argv:  # before numpy starts its BLAS threads
    for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[_name] = "1"
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})

import argparse  # noqa: E402
import datetime  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402

from hapticdesk.bench.scenes import desk_day, paper_experiment  # noqa: E402
from hapticdesk.estimator import BATCH_CHUNK, ContactEstimator  # noqa: E402
from hapticdesk.estimator.filter_bank import FilterBank  # noqa: E402
from hapticdesk.estimator.samples import SampleStage  # noqa: E402
from hapticdesk.estimator.settings import EstimatorSettings  # noqa: E402
from hapticdesk.files.profile import METHODS, DeskProfile
from hapticdesk.files.profile_reader import load_profile  # noqa: E402
from hapticdesk.sim import simulate  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from reference_paper import (  # noqa: E402
    REFERENCE_METHODS,
    reference_contacts,
    reference_filtered,
)

MINUTE_S = 60.0
STREAM_S = 10.0
SLOW_FACTOR = 3.0


def _median_seconds(run: Callable[[], object], repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        run()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def floor(settings: EstimatorSettings, t: np.ndarray, wrench: np.ndarray) -> None:
    """The wrench map (the samples stage's own, :meth:`SampleStage.resultant`) and the
    method's filter bank (``settings``) over (t, wrench), in the pieces a push uses: the part
    of a push no later stage can save."""
    bank = FilterBank(settings, [])
    samples = SampleStage(settings, [])
    stacked = wrench.reshape(len(t), -1)
    for a in range(0, len(t), BATCH_CHUNK):
        raw = samples.resultant(stacked[a : a + BATCH_CHUNK])
        bank.process(t[a : a + BATCH_CHUNK], raw, np.zeros(raw.shape[1], np.uint8), True)


def _reference_method(method: str) -> str:
    return method if method in REFERENCE_METHODS else "switched"


def side_by_side(
    desk: DeskProfile, t: np.ndarray, wrench: np.ndarray, repeats: int
) -> dict[str, dict[str, float]]:
    """Median seconds of each estimator method and each reference method on (t, wrench), run
    in turn (A B A B …) so that the machine's drift falls on all of them alike."""
    runs: dict[str, list[float]] = {}
    jobs: dict[str, Callable[[], object]] = {}
    for method in METHODS:
        # (building the estimator is not estimation: it is built outside the clock)
        jobs[method] = lambda m=method: ContactEstimator(desk, method=m)
    for method in REFERENCE_METHODS:
        jobs[f"ref:{method}"] = lambda m=method: reference_contacts(desk, t, wrench, m)
    jobs["ref:floor"] = lambda: reference_filtered(desk, wrench)
    for method in METHODS:
        settings = ContactEstimator(desk, method=method).stage_settings  # (not on the clock)
        jobs[f"floor:{method}"] = lambda s=settings: floor(s, t, wrench)
    for _ in range(repeats):
        for name, job in jobs.items():
            if name.startswith(("ref:", "floor:")):
                start = time.perf_counter()
                job()
            else:
                est = job()
                assert isinstance(est, ContactEstimator)
                start = time.perf_counter()
                est.push(t, wrench)
            runs.setdefault(name, []).append(time.perf_counter() - start)
    return {
        name: {"median_s": statistics.median(v), "min_s": min(v), "max_s": max(v)}
        for name, v in runs.items()
    }


def streaming(
    desk: DeskProfile, t: np.ndarray, wrench: np.ndarray, method: str, block: int, repeats: int
) -> dict[str, float]:
    """Per-push times of ``block``-sample pushes over STREAM_S after the tare, every push
    timed, pooled over ``repeats`` runs."""
    fs = desk.sample_rate_hz
    start = int(2.0 * fs)  # after the tare, where every stage runs
    stop = start + int(STREAM_S * fs)
    stop -= (stop - start) % block
    per_push: list[np.ndarray] = []
    contact: list[np.ndarray] = []
    clock = time.perf_counter_ns
    for _ in range(repeats):
        est = ContactEstimator(desk, method=method)
        est.push(t[:start], wrench[:start])
        ns = np.empty((stop - start) // block)
        touching = np.empty(len(ns), bool)
        for j, i in enumerate(range(start, stop, block)):
            begin = clock()
            out = est.push(t[i : i + block], wrench[i : i + block])
            ns[j] = clock() - begin
            touching[j] = out.in_contact.any()
        per_push.append(ns / 1e3)
        contact.append(touching)
    us = np.concatenate(per_push)
    touching = np.concatenate(contact)
    median = float(np.median(us))
    return {
        "us_per_push": median,
        "us_per_sample": median / block,
        "us_per_push_in_contact": float(np.median(us[touching])) if touching.any() else 0.0,
        "us_per_push_p999": float(np.percentile(us, 99.9)),
        "us_per_push_max": float(us.max()),
        "slow_pushes_per_s": float((us > SLOW_FACTOR * median).sum() / (repeats * STREAM_S)),
        "contact_share": float(touching.mean()),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", choices=("paper", "day"), default="paper")
    parser.add_argument("--repeats", type=int, default=9, help="runs of each one-minute figure")
    parser.add_argument("--samples", type=int, default=2_000_000, help="long batch; 0: skip")
    parser.add_argument("--batch-repeats", type=int, default=3)
    parser.add_argument("--stream-repeats", type=int, default=3)
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument(
        "--all-cores", action="store_true", help="do not pin to one CPU and one BLAS thread"
    )
    args = parser.parse_args()

    desk = load_profile("kitamura2017")
    scene = paper_experiment() if args.scene == "paper" else desk_day(minutes=2.0)
    rec = simulate(desk, scene, seed=0)
    minute = int(MINUTE_S * desk.sample_rate_hz)
    t = np.ascontiguousarray(rec.t[:minute])
    wrench = np.ascontiguousarray(rec.wrench[:minute])
    contact_share = float(ContactEstimator(desk).push(t, wrench).in_contact.mean())

    times = side_by_side(desk, t, wrench, args.repeats)
    long: dict[str, dict[str, float]] = {}
    if args.samples:
        reps = -(-args.samples // len(rec.t))
        big = np.ascontiguousarray(np.tile(rec.wrench, (reps, 1, 1))[: args.samples])
        big_t = np.arange(args.samples) / desk.sample_rate_hz
        long = side_by_side(desk, big_t, big, args.batch_repeats)
        del big
    rows: list[dict[str, Any]] = []
    for method in METHODS:
        ref = _reference_method(method)
        row: dict[str, Any] = {
            "method": method,
            "minute_ms": round(times[method]["median_s"] * 1e3, 1),
            "reference": ref,
            "reference_minute_ms": round(times[f"ref:{ref}"]["median_s"] * 1e3, 1),
            "times_reference_minute": round(
                times[f"ref:{ref}"]["median_s"] / times[method]["median_s"], 2
            ),
            "floor_minute_ms": round(times[f"floor:{method}"]["median_s"] * 1e3, 1),
            "floor_times_reference": round(
                times[f"ref:{ref}"]["median_s"] / times[f"floor:{method}"]["median_s"], 2
            ),
        }
        if long:
            row["batch_samples_per_s"] = round(args.samples / long[method]["median_s"])
            row["reference_batch_samples_per_s"] = round(
                args.samples / long[f"ref:{ref}"]["median_s"]
            )
            row["times_reference_batch"] = round(
                long[f"ref:{ref}"]["median_s"] / long[method]["median_s"], 2
            )
        one = streaming(desk, t, wrench, method, 1, args.stream_repeats)
        twelve = streaming(desk, t, wrench, method, 12, args.stream_repeats)
        row.update(
            {
                "us_per_push": round(one["us_per_push"], 1),
                "us_per_push_in_contact": round(one["us_per_push_in_contact"], 1),
                "us_per_push_p999": round(one["us_per_push_p999"], 1),
                "us_per_push_max": round(one["us_per_push_max"], 1),
                "slow_pushes_per_s": round(one["slow_pushes_per_s"], 2),
                "us_per_sample_block12": round(twelve["us_per_sample"], 2),
            }
        )
        rows.append(row)
    info = {
        "date_utc": datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M"),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "desk": desk.name,
        "sensors": len(desk.sensors),
        "scene": args.scene,
        "minute_samples": minute,
        "contact_share": round(contact_share, 2),
        "repeats": args.repeats,
        "batch_samples": args.samples,
        "batch_repeats": args.batch_repeats,
        "stream_repeats": args.stream_repeats,
        "cpu_count": os.cpu_count(),
        "cpus_used": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else None,
        "load_average": os.getloadavg() if hasattr(os, "getloadavg") else None,
        "methods": rows,
        "reference_floor_minute_ms": round(times["ref:floor"]["median_s"] * 1e3, 1),
    }
    if args.json:
        print(json.dumps(info, indent=1))
        return
    print(
        f"{info['date_utc']} UTC, {desk.name}: {len(desk.sensors)} sensors, scene `{args.scene}` "
        f"({contact_share:.0%} in contact), medians; "
        f"{'all cores' if args.all_cores else 'one core, one BLAS thread'}; load average "
        f"{' '.join(f'{x:.1f}' for x in info['load_average'] or ())}"
    )
    print(
        f"one minute ({minute:,} samples), median of {args.repeats}; batch of "
        f"{args.samples:,} samples, median of {args.batch_repeats}; pushes over "
        f"{STREAM_S:g} s, {args.stream_repeats} runs"
    )
    head = (
        f"{'method':<9}{'1 min ms':>9}{'ref ms':>8}{'× ref':>7}{'floor ms':>9}{'× ref':>7}"
        + (f"{'batch Msa/s':>12}{'ref Msa/s':>10}{'× ref':>7}" if long else "")
        + f"{'µs/push':>9}{'in cont.':>9}{'p99.9':>7}{'max':>7}{'slow/s':>7}{'µs/sa k=12':>11}"
    )
    print(head)
    for r in rows:
        line = f"{r['method']:<9}{r['minute_ms']:>9}{r['reference_minute_ms']:>8}"
        line += f"{r['times_reference_minute']:>7}"
        line += f"{r['floor_minute_ms']:>9}{r['floor_times_reference']:>7}"
        if long:
            line += f"{r['batch_samples_per_s'] / 1e6:>12.2f}"
            line += f"{r['reference_batch_samples_per_s'] / 1e6:>10.2f}"
            line += f"{r['times_reference_batch']:>7}"
        line += f"{r['us_per_push']:>9}{r['us_per_push_in_contact']:>9}{r['us_per_push_p999']:>7}"
        line += f"{r['us_per_push_max']:>7.0f}{r['slow_pushes_per_s']:>7}"
        line += f"{r['us_per_sample_block12']:>11}"
        print(line)
    print(
        "(ref: scripts/reference_paper.py, the same method; for `fused` its `switched`. "
        "floor: the wrench map and the method's filter bank alone)"
    )
    ref_floor = info["reference_floor_minute_ms"]
    fastest_ref = min(r["reference_minute_ms"] for r in rows)
    print(
        f"ref floor: the reference's own map, tare and two filters, {ref_floor} ms of its "
        f"{fastest_ref}-{max(r['reference_minute_ms'] for r in rows)} ms "
        f"({ref_floor / fastest_ref:.0%} of the fastest); twice as fast as the reference "
        f"means under {fastest_ref / 2:.1f} ms"
    )


if __name__ == "__main__":
    main()
