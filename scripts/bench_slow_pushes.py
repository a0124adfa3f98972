#!/usr/bin/env python3
"""Which single-sample pushes take over 100 µs, and what they did (issue 29: "no sample over
100 µs in a minute", no slow path at a window's end).

A minute of a desk (simulated with ``hapticdesk.sim``: the paper's experiment, or ordinary
use) is pushed into a :class:`~hapticdesk.estimator.ContactEstimator` one sample at a time
after the tare, each push timed in the thread's CPU time (a push the machine preempts is slow
on the wall clock only). Printed: the pushes' median and 99th percentile, how many took over
100 µs and, for each of those, the events the kernel left to Python (``kernel_slots.EV_*``);
and the CPU time of Python's part of each zero window's end (``EV_WINDOW``), median and
maximum.

With ``--against DIR`` the same is measured for another checkout's ``core/`` (e.g. ``git
archive <commit> core | tar -x -C DIR``), in turn with this one (A B A B …, ``--repeats``
each, a fresh process each), so both are measured on the same machine at the same time:

    python scripts/bench_slow_pushes.py [--scene paper|day] [--repeats 3] [--against DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SLOW_US = 100.0
MINUTE_S = 60.0


def simulated(scene_name: str, path: Path) -> None:
    """The scene on the paper's desk, simulated once (seed 0) into ``path`` (.npz): every
    tree measured pushes the same samples."""
    import numpy as np

    from hapticdesk.bench.scenes import desk_day, paper_experiment
    from hapticdesk.files.profile_reader import load_profile
    from hapticdesk.sim import simulate

    desk = load_profile("kitamura2017")
    scene = paper_experiment() if scene_name == "paper" else desk_day(minutes=1.5)
    rec = simulate(desk, scene, seed=0)
    stop = int((2.0 + MINUTE_S) * desk.sample_rate_hz)
    np.savez(path, t=rec.t[:stop], wrench=rec.wrench[:stop])


def measure(path: Path) -> dict[str, object]:
    """One minute of single-sample pushes of the samples in ``path`` in this process:
    per-push CPU µs, the slow ones' events, and the µs of Python's part of each window's
    end."""
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
    import numpy as np

    from hapticdesk.estimator import ContactEstimator
    from hapticdesk.estimator import kernel_slots as slots
    from hapticdesk.files.profile_reader import load_profile

    names = {getattr(slots, n): n[3:] for n in dir(slots) if n.startswith("EV_")}
    desk = load_profile("kitamura2017")
    with np.load(path) as samples:
        t = np.ascontiguousarray(samples["t"])
        wrench = np.ascontiguousarray(samples["wrench"])
    start = int(2.0 * desk.sample_rate_hz)  # after the tare
    stop = len(t)
    ContactEstimator(desk).push(t[:start], wrench[:start])  # (compiled or loaded: warm)

    est = ContactEstimator(desk)
    est.push(t[:start], wrench[:start])
    handled: list[int] = []  # the events of the push under way
    window_us: list[float] = []
    handle = est._handle
    clock = time.thread_time_ns

    def timed_handle(events: int, *args: object) -> None:
        handled.append(events)
        began = clock()
        handle(events, *args)  # type: ignore[arg-type]
        if events & slots.EV_WINDOW:
            window_us.append((clock() - began) / 1e3)

    est._handle = timed_handle  # type: ignore[method-assign]
    us = np.empty(stop - start)
    slow: list[tuple[float, float, list[str]]] = []
    for j, i in enumerate(range(start, stop)):
        handled.clear()
        began = clock()
        est.push(t[i : i + 1], wrench[i : i + 1])
        us[j] = (clock() - began) / 1e3
        if us[j] > SLOW_US:
            what = [
                "|".join(name for bit, name in names.items() if events & bit) for events in handled
            ]
            slow.append((float(t[i]), float(us[j]), what))
    return {
        "p50_us": float(np.median(us)),
        "p99_us": float(np.percentile(us, 99)),
        "max_us": float(us.max()),
        "pushes": len(us),
        "over_100us": len(slow),
        "slow": slow,
        "windows": len(window_us),
        "window_p50_us": statistics.median(window_us) if window_us else 0.0,
        "window_max_us": max(window_us) if window_us else 0.0,
    }


def run_in(core: Path | None, samples: Path) -> dict[str, object]:
    """:func:`measure` in a fresh process, importing ``hapticdesk`` from ``core`` (None: the
    installed one)."""
    env = dict(os.environ)
    with tempfile.TemporaryDirectory() as tmp:
        if core is not None:
            os.symlink(core.resolve(), Path(tmp) / "hapticdesk")
            env["PYTHONPATH"] = tmp + os.pathsep + env.get("PYTHONPATH", "")
        out = subprocess.run(
            [sys.executable, __file__, "--worker", str(samples)],
            env=env,
            check=True,
            capture_output=True,
            text=True,
        ).stdout
    return dict(json.loads(out))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", choices=("paper", "day"), default="paper")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--against", type=Path, help="another checkout's core/ to compare")
    parser.add_argument("--worker", type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        print(json.dumps(measure(args.worker)))
        return
    here = Path(__file__).resolve().parents[1] / "core"
    trees = {"this": here, **({"against": args.against / "core"} if args.against else {})}
    runs: dict[str, list[dict[str, object]]] = {name: [] for name in trees}
    with tempfile.TemporaryDirectory() as tmp:
        samples = Path(tmp) / "minute.npz"
        simulated(args.scene, samples)
        for _ in range(args.repeats):
            for name, core in trees.items():
                runs[name].append(run_in(None if name == "this" else core, samples))
    print(
        f"scene `{args.scene}`, a minute of single-sample pushes after the tare, CPU time of "
        f"the thread, {args.repeats} runs each (in turn), medians over the runs"
    )
    print(f"{'tree':<9}{'p50 µs':>8}{'p99 µs':>8}{'max µs':>8}{'>100µs':>8}{'windows':>9}")
    print(f"{'':<9}{'':>8}{'':>8}{'':>8}{'':>8}{'p50 µs':>9}{'max µs':>8}")
    for name, results in runs.items():

        def med(key: str, results: list[dict[str, object]] = results) -> float:
            return statistics.median(float(r[key]) for r in results)  # type: ignore[arg-type]

        print(
            f"{name:<9}{med('p50_us'):>8.1f}{med('p99_us'):>8.1f}{med('max_us'):>8.0f}"
            f"{med('over_100us'):>8.0f}{med('window_p50_us'):>9.1f}{med('window_max_us'):>8.1f}"
            f"  ({int(med('windows'))} windows to Python; {trees[name]})"
        )
        for t, us, what in results[-1]["slow"]:  # type: ignore[union-attr]
            print(f"{'':<9}slow push at t={t:.3f} s: {us:.0f} µs, events {what or '(none)'}")


if __name__ == "__main__":
    main()
