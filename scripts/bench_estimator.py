#!/usr/bin/env python3
"""Benchmark of the contact estimator alone (issue 2): batch throughput and streaming cost.

Input, simulated on the paper's four-sensor desk with the paper's noise, repeated to two
million samples for the batch figure: ``--scene paper`` the paper's experiment (presses one
after the other, three quarters of the samples in contact: the worst case), ``--scene day``
ordinary use (a touch every 5–15 s, about a tenth in contact). Each figure is the best of
several runs. The targets are for one core, so the process is pinned to one CPU and the
linear algebra library to one thread (``--all-cores`` lifts both). Run on an otherwise idle
machine:

    python scripts/bench_estimator.py [--scene paper|day] [--samples 2000000] [--repeats 5]
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
import json  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from hapticdesk.bench.scenes import desk_day, paper_experiment  # noqa: E402
from hapticdesk.bench.timing import measure_cost  # noqa: E402
from hapticdesk.estimator import ContactEstimator  # noqa: E402
from hapticdesk.files.profile import METHODS, load_profile  # noqa: E402
from hapticdesk.sim import simulate  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=2_000_000)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--scene", choices=("paper", "day"), default="paper")
    parser.add_argument("--json", action="store_true")
    parser.add_argument(
        "--all-cores", action="store_true", help="do not pin to one CPU and one BLAS thread"
    )
    args = parser.parse_args()

    desk = load_profile("kitamura2017")
    scene = paper_experiment() if args.scene == "paper" else desk_day()
    rec = simulate(desk, scene, seed=0)
    reps = -(-args.samples // len(rec.t))
    wrench = np.ascontiguousarray(np.tile(rec.wrench, (reps, 1, 1))[: args.samples])
    t = np.arange(args.samples) / desk.sample_rate_hz
    rows = []
    for method in METHODS:
        best = float("inf")
        for _ in range(args.repeats):
            est = ContactEstimator(desk, method=method)
            start = time.perf_counter()
            block = est.push(t, wrench)
            best = min(best, time.perf_counter() - start)
        cost = measure_cost(
            desk, rec.t, rec.wrench, method, repeats=args.repeats, stream_samples=12_000
        )
        rows.append(
            {
                "method": method,
                "batch_samples_per_s": round(args.samples / best),
                "us_per_sample_block1": round(cost.us_per_sample_stream, 1),
                "us_per_sample_block12": round(cost.us_per_sample_block12, 2),
                "contact_share": round(float(block.in_contact.mean()), 2),
            }
        )
    info = {
        "desk": desk.name,
        "sensors": len(desk.sensors),
        "batch_samples": args.samples,
        "cpu_count": os.cpu_count(),
        "cpus_used": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else None,
        "methods": rows,
    }
    if args.json:
        print(json.dumps(info, indent=1))
        return
    print(
        f"{desk.name}: {len(desk.sensors)} sensors, scene `{args.scene}`, batch of "
        f"{args.samples:,} samples, best of {args.repeats}, "
        f"{'all cores' if args.all_cores else 'one core, one BLAS thread'}"
    )
    print(
        f"{'method':<10}{'in contact':>11}{'batch samples/s':>18}{'µs/sample k=1':>16}"
        f"{'µs/sample k=12':>16}"
    )
    for r in rows:
        print(
            f"{r['method']:<10}{r['contact_share']:>11.2f}{r['batch_samples_per_s']:>18,}"
            f"{r['us_per_sample_block1']:>16}{r['us_per_sample_block12']:>16}"
        )


if __name__ == "__main__":
    main()
