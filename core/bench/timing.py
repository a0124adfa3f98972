"""Run-time cost of the estimator, measured the same way for every method and setting.

- batch throughput: one ``push`` of the whole recording, samples per second;
- streaming cost: µs per sample when the recording is pushed in blocks of 1 and of 12
  samples (12 = one CAN burst of a four-sensor desk at 1.2 kHz, or 10 ms at 1.2 kHz).

Each figure is the best of ``repeats`` runs (the least disturbed by the rest of the machine).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from hapticdesk.estimator import ContactEstimator
from hapticdesk.files.profile import DeskProfile, EstimationSettings


@dataclass(frozen=True)
class Cost:
    """What one method with one setting costs on one recording."""

    samples_per_s: float  # batch
    us_per_sample_stream: float  # single-sample pushes
    us_per_sample_block12: float  # 12-sample pushes


def measure_cost(
    profile: DeskProfile,
    t: np.ndarray,
    wrench: np.ndarray,
    method: str,
    settings: EstimationSettings | None = None,
    *,
    stream_samples: int = 6000,
    repeats: int = 3,
) -> Cost:
    """Time batch estimation of (t, wrench) and streaming of its first ``stream_samples``."""
    settings = replace(settings or profile.estimation, method=method)
    batch_s = float("inf")
    for _ in range(repeats):
        est = ContactEstimator(profile, settings=settings)  # (building it is not estimation)
        start = time.perf_counter()
        est.push(t, wrench)
        batch_s = min(batch_s, time.perf_counter() - start)
    n = min(stream_samples, len(t))
    # start streaming after the tare, where every stage runs
    start = min(len(t) - n, int(2.0 * profile.sample_rate_hz))

    def stream(block: int) -> float:
        est = ContactEstimator(profile, settings=settings)
        est.push(t[:start], wrench[:start])
        stop = start + n - (n % block)
        begin = time.perf_counter()
        for i in range(start, stop, block):
            est.push(t[i : i + block], wrench[i : i + block])
        return (time.perf_counter() - begin) / (stop - start)

    one = min(stream(1) for _ in range(repeats))
    twelve = min(stream(12) for _ in range(repeats))
    return Cost(len(t) / batch_s, one * 1e6, twelve * 1e6)
