"""The sensors' resolution step, learned from the readings (estimator/resolution.py), and the
rounding error the noise measured at the tare lacks (a sensor quieter than its step)."""

from __future__ import annotations

import numpy as np
import pytest

from hapticdesk.estimator import ContactEstimator
from hapticdesk.estimator.candidates import Covariances
from hapticdesk.estimator.resolution import CONFIRM_CHANGES, rounding_deficit
from hapticdesk.files.profile_reader import load_profile
from hapticdesk.sim import Scene, simulate
from hapticdesk.sim.actions import Idle, Tap
from hapticdesk.sim.sensors import SensorParameters


def taps_on(desk, noise: float, resolution: float = 1 / 2000) -> ContactEstimator:
    scene = Scene(
        actions=[Idle(duration_s=2.0)]
        + [
            Tap(point=(0.1 * i - 0.2, 0.05), peak_n=4.0, duration_s=0.12, wait_s=0.5)
            for i in range(5)
        ]
    )
    sensors = SensorParameters(noise_amplitude_n=noise, resolution=resolution)
    run = simulate(desk, scene, seed=3, sensors=sensors)
    estimator = ContactEstimator(desk)
    estimator.push(run.t, run.wrench)
    return estimator


@pytest.mark.parametrize("noise", [0.4, 0.1])
def test_the_step_is_learned_exactly_dithered_or_not(noise):
    """With the paper's noise every channel changes at rest; with a quiet sensor only the
    taps move them: either way each channel's step is its rating/2000 (paper Table 2)."""
    desk = load_profile("kitamura2017")
    estimator = taps_on(desk, noise)
    learned = estimator.resolution_step
    rating = estimator.stage_settings.range_flat
    assert learned == pytest.approx(rating / 2000, rel=1e-9)
    # and the estimator's covariances hold the rounding the tare did not see: all of it for
    # the quiet sensor (its tare saw almost no noise), none of note for the paper's
    measured = estimator.zeroing.state.noise
    assert measured is not None
    settings = estimator.stage_settings
    with_steps = Covariances.of(settings, measured, learned).lp[0]
    plain = Covariances.of(settings, measured).lp[0]
    grown = np.trace(with_steps) / np.trace(plain)
    assert estimator.covariances is not None
    assert np.trace(estimator.covariances.lp[0]) == pytest.approx(np.trace(with_steps))
    quiet = noise < 0.26  # below it, the simulator's 1/2000 rounding is not dithered
    assert grown > 100 if quiet else grown < 1.05


def test_readings_off_a_grid_add_nothing():
    """Unrounded readings: the smallest change is far below the noise, and the covariances
    are those of the measured noise alone."""
    desk = load_profile("kitamura2017")
    estimator = taps_on(desk, 0.4, resolution=0.0)
    step = estimator.resolution_step
    noise = estimator.zeroing.state.noise
    assert noise is not None
    measured_sd = np.sqrt(np.diag(noise)).min()
    # (the smallest of a channel's first CONFIRM_CHANGES changes: 6 % of the noise here)
    assert 0 < step.max() < 0.1 * measured_sd
    settings = estimator.stage_settings
    with_steps = Covariances.of(settings, noise, step)
    without = Covariances.of(settings, noise)
    for a, b in zip(with_steps.lp + with_steps.diff, without.lp + without.diff, strict=True):
        assert a == pytest.approx(b, rel=1e-6, abs=1e-15)


def test_the_deficit_is_the_rounding_a_quiet_tare_did_not_see():
    m = np.random.default_rng(0).standard_normal((6, 24))
    step = np.full(24, 0.15)
    rounding = m @ np.diag(step**2 / 12) @ m.T
    assert rounding_deficit(m, step, np.zeros((6, 6))) == pytest.approx(rounding)
    assert np.abs(rounding_deficit(m, step, 2 * rounding)).max() < 1e-12  # dithered
    part = rounding_deficit(m, step, 0.5 * rounding)  # half of it seen: half lacking
    assert part == pytest.approx(0.5 * rounding)
    assert np.linalg.eigvalsh(rounding_deficit(m, step, np.diag(np.arange(6.0)))).min() > -1e-12


def test_a_channel_stops_learning_once_its_step_is_confirmed():
    """A channel on a 0.1 grid learns 0.1 and, once CONFIRM_CHANGES changes confirm it, no
    smaller change; a channel that never changed has no step and learns the first change."""
    desk = load_profile("kitamura2017")
    n = 3 * CONFIRM_CHANGES
    rng = np.random.default_rng(1)
    readings = np.zeros((n + 3, len(desk.sensors), 6))
    readings[:, :, 2] = 34.0  # the desk's weight, on its four legs
    readings[:n, 0, 0] = np.round(rng.normal(0, 0.3, n) / 0.1) * 0.1
    readings[:, :, 3:] = rng.normal(0, 0.01, (n + 3, len(desk.sensors), 3))  # (not stuck)
    readings[n:, 0, 0] = readings[n - 1, 0, 0] + np.array([0.02, 0.0, 0.02])
    readings[n + 1 :, 1, 1] = [0.02, 0.06]
    t = np.arange(n + 3) / desk.sample_rate_hz
    estimator = ContactEstimator(desk)
    estimator.push(t[:10], readings[:10])
    assert estimator.resolution_step[0] >= 0.1 - 1e-12
    for i in range(10, n):  # one by one: the same as in a block
        estimator.push(t[i : i + 1], readings[i : i + 1])
    step = estimator.resolution_step
    assert step[0] == pytest.approx(0.1)
    assert step[7] == 0.0  # never changed: no step, still learning
    estimator.push(t[n:], readings[n:])
    step = estimator.resolution_step
    assert step[0] == pytest.approx(0.1)  # confirmed: the smaller change does not count
    assert step[7] == pytest.approx(0.02)
