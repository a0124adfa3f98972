"""The sensors' resolution step, learned from the readings (estimator/resolution.py), and the
rounding error the noise measured at the tare lacks (a sensor quieter than its step)."""

from __future__ import annotations

import numpy as np
import pytest

from hapticdesk.estimator import ContactEstimator
from hapticdesk.estimator.candidates import Covariances
from hapticdesk.estimator.kernel_rounding import likeliest_noise
from hapticdesk.estimator.resolution import (
    CONFIRM_CHANGES,
    _count_means,
    bias_variance,
    moved_share,
    rest_variance,
    rounding_deficit,
    zero_rounding,
    zero_rounding_noise,
)
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


@pytest.mark.parametrize("rho", [0.0, 0.1, 0.2, 0.3])
def test_the_zero_keeps_the_rounding_bias_its_noise_does_not_dither_away(rho):
    """A still value anywhere between two steps, read 4,000 times through noise of ρ steps and
    rounded: the mean's error has the variance bias_variance(ρ) (1/12 step² when nothing
    dithers), and the readings the variance rest_variance(ρ)."""
    rng = np.random.default_rng(7)
    true = rng.uniform(0.0, 1.0, 2000)  # in steps
    readings = np.round(true[:, None] + rho * rng.standard_normal((2000, 4000)))
    bias = readings.mean(axis=1) - true
    assert np.mean(bias**2) == pytest.approx(bias_variance(rho), rel=0.1, abs=2e-4)
    assert np.mean(readings.var(axis=1)) == pytest.approx(rest_variance(rho), rel=0.05, abs=1e-4)


def test_the_zeros_rounding_offset_is_that_of_the_quiet_channels():
    """Channels that sat on one step at rest: the zero is off by up to half a step each
    (step²/12); channels whose noise dithers the rounding, or with no step: nothing."""
    m = np.random.default_rng(0).standard_normal((6, 24))
    step = np.full(24, 0.15)
    quiet = m @ np.diag(step**2 / 12) @ m.T
    assert zero_rounding(m, step, np.zeros(24), 2000) == pytest.approx(quiet, rel=1e-3)
    assert not zero_rounding(m, step, np.full(24, 0.5 * 0.15**2), 2000).any()  # dithered
    assert not zero_rounding(m, np.zeros(24), np.zeros(24), 2000).any()  # no step
    half = np.where(np.arange(24) < 12, 0.15, 0.0)  # half the channels rounded
    assert zero_rounding(m, half, np.zeros(24), 2000) == pytest.approx(
        m[:, :12] @ m[:, :12].T * 0.15**2 / 12, rel=1e-3
    )


@pytest.mark.parametrize("rho", [0.05, 0.124, 0.2])
def test_the_noise_is_told_from_many_channels_better_than_by_their_mean_variance(rho):
    """48 channels quieter than their step, each still somewhere between two steps, read
    2,000 times: the noise that makes their changes likeliest (zero_rounding_noise) lies
    within 0.02 step of the truth in 19 of 20 recordings and scatters less than the mean
    variance inverted through rest_variance, on which one channel near a step's middle
    weighs as much as ten near a step."""
    rng = np.random.default_rng(3)
    grid = np.linspace(0.0, 1.0, 1001)
    likeliest, by_mean = [], []
    for _ in range(20):
        true = rng.uniform(0.0, 1.0, 48)
        readings = np.round(true[:, None] + rho * rng.standard_normal((48, 2001)))
        rest_var = np.sum(np.diff(readings, axis=1) ** 2, axis=1) / (2 * 2000)
        likeliest.append(zero_rounding_noise(np.ones(48), rest_var, 2000)[0])
        by_mean.append(np.interp(np.mean(rest_var), rest_variance(grid), grid))
    off = np.abs(np.array(likeliest) - rho)
    assert np.sum(off < 0.02) >= 19
    assert np.std(likeliest) < np.std(by_mean)


def _likelihoods(counts: np.ndarray, rest_n: int) -> np.ndarray:
    """Every noise's log-likelihood of the channels' squared rest changes ``counts``, over the
    whole grid in plain numpy (the likelihood likeliest_noise's search maximises)."""
    mean, log_mean = _count_means(rest_n)
    terms = counts[:, None, None] * log_mean[None] - mean[None]  # (Q, R, P)
    top = terms.max(axis=2, keepdims=True)
    per_channel = top[..., 0] + np.log(np.mean(np.exp(terms - top), axis=2))
    return per_channel.sum(axis=0)


@pytest.mark.parametrize("kind", ["alike", "unlike", "equal", "still"])
def test_the_noise_search_finds_the_likeliest_noise_of_the_whole_grid(kind):
    """The search (bounds, and chords of the convex channel terms, to leave noises out) picks
    the noise whose likelihood is the largest of the whole grid's, on channels of one noise,
    of unlike noises, all of one count, and still ones (counts of 0)."""
    rng = np.random.default_rng({"alike": 1, "unlike": 2, "equal": 3, "still": 4}[kind])
    for _ in range(12):
        rest_n = int(rng.choice([60, 600, 2400]))
        q = int(rng.integers(1, 40))
        rho = rng.uniform(0.0, 0.05 if kind == "still" else 0.7)
        readings = np.round(rng.uniform(0, 1, (q, 1)) + rho * rng.standard_normal((q, rest_n + 1)))
        counts = np.sum(np.diff(readings, axis=1) ** 2, axis=1)
        if kind == "unlike":
            counts = np.round(counts * rng.uniform(0.2, 3.0, q))
        elif kind == "equal":
            counts[:] = counts[0]
        found = likeliest_noise(
            counts, *_count_means(rest_n), np.empty((141, q + 1)), np.empty((6, q))
        )
        likelihood = _likelihoods(counts, rest_n)
        assert likelihood[found] == pytest.approx(likelihood.max(), rel=1e-12, abs=1e-9)


def _mean_bias(x: np.ndarray, noise: np.ndarray) -> np.ndarray:
    """The rounding's bias at values ``x`` (steps): the mean of their rounded readings
    through the ``noise`` (1, n) less the value."""
    return np.mean(np.round(x[:, None] + noise), axis=1) - x


def test_a_channel_the_press_does_not_move_keeps_none_of_the_zeros_rounding():
    """The tared reading errs by b(x0 + change) - b(x0), b the rounding's bias (the mean of
    the rounded readings less the value): nothing for a channel the press leaves on its
    step, the whole offset from a sixth of a step on; in between the variance over where x0
    lies, measured here through noise of 0 and 0.12 step (quadratic in a small change under
    noise: 12 |change| / step overstated it 5 times at a twentieth of a step)."""
    step = 0.15
    assert moved_share(0.0, step) == 0.0
    assert moved_share([step / 6, -step, 40 * step], step, 0.12) == pytest.approx(1.0)
    rng = np.random.default_rng(1)
    x0 = (np.arange(4000) + 0.5) / 4000  # in steps, evenly between two
    for rho in (0.0, 0.12):
        noise = rho * rng.standard_normal((1, 4000))

        whole = np.mean(_mean_bias(x0, noise) ** 2)
        for change in (0.01, 0.05, 0.1):
            moved = _mean_bias(x0 + change, noise) - _mean_bias(x0, noise)
            kept = np.mean(moved**2) / whole
            assert moved_share(change * step, step, rho) == pytest.approx(kept, rel=0.1, abs=5e-3)


def test_a_quiet_sensors_sigma_holds_its_error_and_an_unrounded_ones_is_unchanged(five_taps):
    """The located 1-σ holds the zero's rounding offset: on the paper desk with a sensor no
    noisier than its 1/2000 rounding, each 4 N tap's samples lie within 3 σ of where the finger
    was (most lay 3-10 σ off before); with unrounded readings the offset is nothing."""
    desk = load_profile("kitamura2017")
    scene = five_taps
    for resolution in (1 / 2000, 0.0):
        sensors = SensorParameters(noise_amplitude_n=0.1, resolution=resolution)
        run = simulate(desk, scene, seed=3, sensors=sensors)
        estimator = ContactEstimator(desk)
        block = estimator.push(run.t, run.wrench)
        assert estimator.covariances is not None
        offset = np.trace(estimator.covariances.rounding[0])
        if resolution == 0:
            assert offset == 0.0
            continue
        assert offset > 0
        located = block.located
        error = np.hypot(block.x - run.extra["true_x"], block.y - run.extra["true_y"])[located]
        assert located.sum() > 200
        assert np.quantile(error / block.sigma_m[located], 0.95) < 3.0
