"""Recordings of taps made from statics alone, so runtime tests need no simulator.

A vertical finger force at P on the top board, and the desk's weight at its centre, are
carried by the legs: F_o = -F_e and M_o = -(P × F_e) about P_o (paper eqs. 1–4). The split
between the legs is the least-norm one of vertical leg forces (the estimator only sees their
sum), so each sensor reads a vertical force and no moment, plus a little noise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.recording import Recording


@dataclass(frozen=True)
class Tap:
    start_s: float
    x: float
    y: float
    duration_s: float = 0.15
    peak_n: float = 10.0

    @property
    def release_s(self) -> float:
        return self.start_s + self.duration_s


def tap_recording(
    profile: DeskProfile,
    taps: list[Tap],
    duration_s: float,
    *,
    noise_n: float = 0.02,
    seed: int = 0,
) -> Recording:
    rate = profile.sample_rate_hz
    t = np.arange(int(duration_s * rate)) / rate
    rng = np.random.default_rng(seed)
    fz = np.zeros_like(t)  # downward finger force, newtons (positive)
    px = np.zeros_like(t)
    py = np.zeros_like(t)
    for tap in taps:
        phase = (t - tap.start_s) / tap.duration_s
        inside = (phase >= 0) & (phase <= 1)
        fz[inside] += tap.peak_n * np.sin(np.pi * phase[inside]) ** 2  # smooth press and release
        px[inside], py[inside] = tap.x, tap.y
    weight = 13.7 * 9.80665  # the desk's own weight: a constant the tare removes
    # vertical leg forces f with sum(f) = load, sum(y_i f_i) = y·load, sum(x_i f_i) = x·load
    pos = np.array([sensor.position for sensor in profile.sensors])
    balance = np.vstack([np.ones(len(pos)), pos[:, 0], pos[:, 1]])
    load = fz + weight
    targets = np.stack([load, fz * px, fz * py])  # the weight acts at the centre (0, 0)
    legs = np.linalg.pinv(balance) @ targets  # (S, k)
    wrench = np.zeros((len(t), len(pos), 6))
    wrench[:, :, 2] = legs.T
    wrench += rng.normal(0.0, noise_n, wrench.shape) * np.array([1, 1, 1, 0.01, 0.01, 0.01])
    return Recording(t, wrench, profile.sensor_names, {"true_fn": fz})
