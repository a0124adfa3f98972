"""Helpers for the contact-core tests: exact sensor readings for a known load.

The readings are the minimum-norm split of a wrench between the sensors (pseudo-inverse of
the profile's wrench map): any split that satisfies equilibrium gives the same resultant, so
this is enough to test the estimator without the simulator's dynamics.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.profile_reader import load_profile

GRAVITY_N = 134.4  # 13.7 kg desk
DITHER_N = 1e-9


def readings_for(profile: DeskProfile, force: np.ndarray, moment: np.ndarray) -> np.ndarray:
    """Sensor readings (k, S, 6) whose resultant about P_o is (force, moment), each (k, 3)."""
    wrench = np.hstack([np.atleast_2d(force), np.atleast_2d(moment)])  # (k, 6)
    pinv = np.linalg.pinv(profile.wrench_map())  # (6S, 6)
    readings = (wrench @ pinv.T).reshape(len(wrench), len(profile.sensors), 6)
    # a dither of a nanonewton, as a real sensor's noise: an exact reading of a steady load
    # repeats bit for bit, and where the input varied at first (someone leaning) the
    # estimator would take the repeats for a stuck driver
    return readings + np.random.default_rng(1).uniform(-DITHER_N, DITHER_N, readings.shape)


def push_at(point: np.ndarray, external_force: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The supports' resultant (F_o, M_o) for a finger force F_e at P_e: F_o = −F_e,
    M_o = P_e × F_o (paper eqs. 1–2)."""
    f_o = -np.atleast_2d(external_force)
    return f_o, np.cross(np.atleast_2d(point), f_o)


def press_profile(
    t: np.ndarray,
    start: float,
    peak: float = 20.0,
    rise: float = 45.0,
    fall: float = 80.0,
    hold: float = 1.0,
) -> np.ndarray:
    """Force magnitude of one press: ramp up at ``rise`` N/s, hold, ramp down at ``fall``."""
    up = np.clip(rise * (t - start), 0.0, peak)
    t_fall = start + peak / rise + hold
    down = np.clip(peak - fall * (t - t_fall), 0.0, peak)
    return np.where(t < t_fall, up, down)


def trembling(t: np.ndarray, magnitude: np.ndarray) -> np.ndarray:
    """A real finger's force: never as still as an object (or the idle desk), it wanders
    (≈3 % at 0.8 Hz) and trembles (≈1.5 % at 10 Hz), as the simulator's HumanModel does; the
    zero absorbs a load as still as the idle desk within ``object_settle_s``."""
    return magnitude * (1 + 0.03 * np.sin(2 * np.pi * 0.8 * t) + 0.015 * np.sin(2 * np.pi * 10 * t))


@pytest.fixture
def press_recording() -> Callable[..., tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Make (t, wrench, force) of presses at given points on a desk, with optional noise."""

    def make(
        profile: DeskProfile,
        points: list[tuple[float, float, float]],
        *,
        duration: float = 4.0,
        lead: float = 1.5,
        noise: float = 0.0,
        seed: int = 0,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        fs = profile.sample_rate_hz
        n = int(round((lead + duration * len(points)) * fs))
        t = np.arange(n) / fs
        f_o = np.zeros((n, 3))
        m_o = np.zeros((n, 3))
        f_o[:, 2] = GRAVITY_N  # the desk's weight, taken out by the tare
        magnitude = np.zeros(n)
        for i, p in enumerate(points):
            mag = press_profile(t, lead + i * duration + 0.2)
            if noise:  # with the sensor's noise, the finger's own unsteadiness too
                mag = trembling(t, mag)
            fo, mo = push_at(np.array(p), np.outer(mag, [0.0, 0.0, -1.0]))
            f_o += fo
            m_o += mo
            magnitude += mag
        wrench = readings_for(profile, f_o, m_o)
        if noise:
            wrench = wrench + np.random.default_rng(seed).normal(0.0, noise, wrench.shape)
        return t, wrench, magnitude

    return make


@pytest.fixture(scope="session")
def noisy_presses() -> tuple[np.ndarray, np.ndarray]:
    """Two presses (20 N and a light 6 N one) with a slight tangential push, Gaussian noise,
    and a NaN burst inside the first press: the input of the chunk-invariance tests."""
    from hapticdesk.files.profile_reader import load_profile

    desk = load_profile("kitamura2017")
    fs = desk.sample_rate_hz
    t = np.arange(int(7.5 * fs)) / fs
    mag = trembling(t, press_profile(t, 1.7) + press_profile(t, 4.5, peak=6.0))
    f_o, m_o = push_at(np.array([0.1, -0.15, 0.733]), np.outer(mag, [0.05, 0.0, -1.0]))
    f_o[:, 2] += GRAVITY_N
    w = readings_for(desk, f_o, m_o) + np.random.default_rng(7).normal(0, 0.07, (len(t), 4, 6))
    w[3000:3010, 2, 1] = np.nan
    return t, w


@pytest.fixture
def statics():
    """(push_at, press_profile, readings_for) for tests that build their own loads."""
    return push_at, press_profile, readings_for


def _shape_error_p95(profile, rec, accel=None) -> float:
    """p95 (m) of the located points against the true point one low-pass delay earlier (the
    lag taken out: what is left is the path's ripple and noise)."""
    from hapticdesk.estimator import ContactEstimator

    est = ContactEstimator(profile)
    block = est.push(rec.t, rec.wrench, accel)
    lag = round(est.position_delay_s * profile.sample_rate_hz)
    touching = rec.extra["true_fn"] > 0
    idx = np.flatnonzero(block.located & touching)
    idx = idx[(idx >= lag) & touching[np.maximum(idx - lag, 0)]]
    err = np.hypot(
        block.x[idx] - rec.extra["true_x"][idx - lag], block.y[idx] - rec.extra["true_y"][idx - lag]
    )
    return float(np.percentile(err, 95))


@pytest.fixture(scope="session")
def accel_desk() -> DeskProfile:
    """The paper's desk with an accelerometer under its top (vibration tests)."""
    return load_profile("kitamura2017-accel")


@pytest.fixture
def shape_error_p95() -> Callable[..., float]:
    """How far a located path strays from the true one, its lag taken out (vibration tests)."""
    return _shape_error_p95


@pytest.fixture(scope="session")
def five_taps() -> object:
    """Five 4 N taps across the paper desk's top after 2 s of rest (the rounding tests)."""
    from hapticdesk.sim import Scene
    from hapticdesk.sim.actions import Idle, Tap

    taps = [
        Tap(point=(0.1 * i - 0.2, 0.05 * (i % 3) - 0.05), peak_n=4.0, duration_s=0.12, wait_s=0.5)
        for i in range(5)
    ]
    return Scene(actions=[Idle(duration_s=2.0), *taps])
