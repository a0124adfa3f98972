"""The sensors' resolution step, learned from the readings (estimator/resolution.py), and the
rounding error the noise measured at the tare lacks (a sensor quieter than its step)."""

from __future__ import annotations

import numpy as np
import pytest

from hapticdesk.estimator import ContactEstimator
from hapticdesk.estimator.candidates import Covariances
from hapticdesk.estimator.resolution import CONFIRM_CHANGES, Resolution, rounding_deficit
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
    learned = estimator.samples.resolution.step
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
    assert estimator.candidates.covs is not None
    assert np.trace(estimator.candidates.covs.lp[0]) == pytest.approx(np.trace(with_steps))
    quiet = noise < 0.26  # below it, the simulator's 1/2000 rounding is not dithered
    assert grown > 100 if quiet else grown < 1.05


def test_readings_off_a_grid_add_nothing():
    """Unrounded readings: the smallest change is far below the noise, and the covariances
    are those of the measured noise alone."""
    desk = load_profile("kitamura2017")
    estimator = taps_on(desk, 0.4, resolution=0.0)
    resolution = estimator.samples.resolution
    noise = estimator.zeroing.state.noise
    assert noise is not None
    measured_sd = np.sqrt(np.diag(noise)).min()
    assert 0 < resolution.step.max() < 0.05 * measured_sd
    settings = estimator.stage_settings
    with_steps = Covariances.of(settings, noise, resolution.step)
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
    resolution = Resolution(2)
    rng = np.random.default_rng(1)
    rows = np.column_stack(
        [
            np.round(rng.normal(0, 0.3, 3 * CONFIRM_CHANGES) / 0.1) * 0.1,
            np.zeros(3 * CONFIRM_CHANGES),
        ]
    )
    resolution.observe(rows[:10])
    assert resolution.changed() and resolution.used[0] >= 0.1 - 1e-12
    for row in rows[10:]:
        resolution.observe_one(row)
    assert resolution.step[0] == pytest.approx(0.1)
    assert resolution.step[1] == 0.0  # never changed: no step, still learning
    assert list(resolution.learning) == [1]
    resolution.observe(np.array([[0.0, 0.0], [0.0, 0.02], [0.0, 0.06]]))
    assert resolution.step[1] == pytest.approx(0.02)
    assert resolution.changed() and not resolution.changed()
