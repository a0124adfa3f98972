#!/usr/bin/env python3
"""What the load-cell desks cost to run, beside the paper's six-axis desk, in one process:
the estimator and the gesture engine per second of desk time (batch, medians of
``--repeats``), one sample's estimate in a stream (µs per push, median), the located points'
delay (the force low-pass's), how long after the finger leaves a tap fires (median and
90th percentile over the taps of tap_accuracy's test), and how far each tap event is from
where the finger was (median and 95th percentile: the literature's anchors are 2–7 cm for
load-cell tables and ±4.1 mm for a calibrated Wii Balance Board).

    python scripts/loadcell_cost.py [--taps 200] [--repeats 5]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from tap_accuracy import LOADCELL_DESKS, buttons, gesture_events, simulate_taps  # (beside this)

from hapticdesk.estimator import ContactEstimator, estimate
from hapticdesk.files.profile_reader import load_profile


def cost(name: str, taps: int, repeats: int, seed: int) -> str:
    """One desk's row."""
    desk = load_profile(name)
    layout = buttons(desk)
    run = simulate_taps(desk, taps, seed)
    rec = run.rec
    seconds = float(rec.t[-1] - rec.t[0])
    est, ges = [], []
    for _ in range(repeats):
        started = time.perf_counter()
        contacts = estimate(desk, rec)
        est.append(time.perf_counter() - started)
        started = time.perf_counter()
        events = gesture_events(desk, layout, contacts)
        ges.append(time.perf_counter() - started)
    # one sample at a time, after the tare, over 5 s of desk time
    estimator = ContactEstimator(desk)
    first = int(2.0 * desk.sample_rate_hz)
    estimator.push(rec.t[:first], rec.wrench[:first])
    pushes = []
    for k in range(first, first + int(5.0 * desk.sample_rate_hz)):
        started = time.perf_counter()
        estimator.push(rec.t[k : k + 1], rec.wrench[k : k + 1])
        pushes.append(time.perf_counter() - started)
    taps = [e for e in events if e.gesture == "tap"]
    fired = np.array([e.t for e in taps])
    latency, miss = [], []
    for start, end, _, _ in run.touches:
        after = np.flatnonzero((fired >= start) & (fired <= end + 0.3))
        if len(after):
            event = taps[after[0]]
            latency.append(event.t - end)
            during = (rec.t >= start) & (rec.t <= end)
            true_x = np.nanmedian(rec.extra["true_x"][during])
            true_y = np.nanmedian(rec.extra["true_y"][during])
            miss.append(np.hypot(event.x - true_x, event.y - true_y))
    lat = np.array(latency) * 1000
    err = np.array(miss) * 1000
    return (
        f"| {name} | {desk.sample_rate_hz:g} Hz, {desk.channel_count} channels | "
        f"{np.median(est) / seconds * 1000:.2f} ms | {np.median(ges) / seconds * 1000:.2f} ms | "
        f"{np.median(pushes) * 1e6:.0f} µs | "
        f"{estimator.position_delay_s * 1000:.0f} ms | "
        f"{np.median(lat):.0f} ms ({np.percentile(lat, 90):.0f} ms) | "
        f"{np.median(err):.1f} mm ({np.percentile(err, 95):.1f} mm) |"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--taps", type=int, default=200)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    print(
        "| desk | samples | estimator per s of desk | gestures per s of desk | one push "
        "| position delay | tap fires after the release (90 %) | tap off the finger (95 %) |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for name in ("kitamura2017", *LOADCELL_DESKS):
        print(cost(name, args.taps, args.repeats, args.seed))


if __name__ == "__main__":
    main()
