#!/usr/bin/env python3
"""The estimator's minute, two checkouts side by side: alternating process pairs.

Two installs of hapticdesk cannot share a process, so each is run in turn in its own
process (A B A B …, ``--pairs`` times), each process timing the paper scene's minute (72,000
samples, scripts/bench_estimator.py's) for every method ``--repeats`` times, one CPU, one BLAS
thread, and printing the medians (CPU time of the thread, ms) with the time of it spent making
the tare's covariances (``ContactEstimator._make_covariances``) apart. The figure per method is
the median over the pairs; the ratio is B over A.

    python scripts/bench_ab_pairs.py --a /work/venv/bin/python --b .venv/bin/python [--pairs 5]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time


def _child(repeats: int) -> None:
    """One process's medians, as one JSON line: {method: [minute ms, tare covariances ms]}."""
    os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
    import numpy as np

    from hapticdesk.bench.scenes import paper_experiment
    from hapticdesk.estimator import ContactEstimator
    from hapticdesk.files.profile import METHODS
    from hapticdesk.files.profile_reader import load_profile
    from hapticdesk.sim import simulate

    desk = load_profile("kitamura2017")
    rec = simulate(desk, paper_experiment(), seed=0)
    n = int(60 * desk.sample_rate_hz)
    t, w = np.ascontiguousarray(rec.t[:n]), np.ascontiguousarray(rec.wrench[:n])
    spent = [0.0]
    make = ContactEstimator._make_covariances

    def timed(self: ContactEstimator) -> None:
        began = time.thread_time()
        make(self)
        spent[0] += time.thread_time() - began

    ContactEstimator._make_covariances = timed  # type: ignore[method-assign]
    ContactEstimator(desk).push(t, w)  # (compiled or loaded, caches warm)
    runs: dict[str, list[tuple[float, float]]] = {m: [] for m in METHODS}
    for _ in range(repeats):
        for method in METHODS:
            est = ContactEstimator(desk, method=method)
            spent[0] = 0.0
            began = time.thread_time()
            est.push(t, w)
            runs[method].append((time.thread_time() - began, spent[0]))
    print(
        json.dumps(
            {
                m: [
                    statistics.median(a for a, _ in v) * 1e3,
                    statistics.median(b for _, b in v) * 1e3,
                ]
                for m, v in runs.items()
            }
        )
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--a", required=True, help="python of checkout A (the reference)")
    parser.add_argument("--b", required=True, help="python of checkout B")
    parser.add_argument("--pairs", type=int, default=5)
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        _child(args.repeats)
        return
    env = {
        **os.environ,
        "OPENBLAS_NUM_THREADS": "1",
        "OMP_NUM_THREADS": "1",
        "MKL_NUM_THREADS": "1",
    }
    got: dict[str, list[dict[str, list[float]]]] = {"a": [], "b": []}
    for _ in range(args.pairs):
        for side in ("a", "b"):
            python = getattr(args, side)
            command = [
                python,
                __file__,
                "--child",
                "--a",
                "-",
                "--b",
                "-",
                "--repeats",
                str(args.repeats),
            ]
            out = subprocess.run(command, env=env, capture_output=True, text=True, check=True)
            got[side].append(json.loads(out.stdout.strip().splitlines()[-1]))
    print(f"{'method':<9}{'A ms':>8}{'B ms':>8}{'B/A':>7}{'A tare':>8}{'B tare':>8}"
          f"{'A rest':>8}{'B rest':>8}{'B/A':>7}")  # fmt: skip
    for method in got["a"][0]:
        a, b = ([statistics.median(r[method][k] for r in got[s]) for k in (0, 1)] for s in "ab")
        rest_a, rest_b = a[0] - a[1], b[0] - b[1]
        print(f"{method:<9}{a[0]:>8.2f}{b[0]:>8.2f}{b[0] / a[0]:>7.3f}{a[1]:>8.2f}{b[1]:>8.2f}"
              f"{rest_a:>8.2f}{rest_b:>8.2f}{rest_b / rest_a:>7.3f}")  # fmt: skip
    print(f"({args.pairs} pairs, medians; tare: the tare's covariances; rest: the minute without)")
    sys.stdout.flush()


if __name__ == "__main__":
    main()
