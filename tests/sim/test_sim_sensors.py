"""Sensor imperfections: noise amplitude, resolution, saturation, offset and drift."""

from __future__ import annotations

import numpy as np
import pytest

from hapticdesk.files.profile import DeskProfile
from hapticdesk.sim import (
    Idle,
    LiftObject,
    PutObject,
    Scene,
    SensorParameters,
    SimEffects,
    simulate,
)
from hapticdesk.sim.sensors import SensorModel

QUIET = SimEffects(dynamics=False, drift=False)


def total_fz(profile: DeskProfile, wrench: np.ndarray) -> np.ndarray:
    return (wrench.reshape(len(wrench), -1) @ profile.wrench_map().T)[:, 2]


def idle_scene(seconds: float) -> Scene:
    return Scene([Idle(duration_s=seconds)], quiet_s=0.0, tail_s=0.0)


def test_total_fz_noise_has_the_papers_amplitude(paper_desk: DeskProfile) -> None:
    """0.4 N amplitude read as 3σ of the total F_z at rest."""
    effects = SimEffects(dynamics=False, drift=False, quantisation=False)
    rec = simulate(paper_desk, idle_scene(30.0), seed=4, effects=effects)
    fz = total_fz(paper_desk, rec.wrench)
    assert 3.0 * np.std(fz) == pytest.approx(0.4, rel=0.03)
    assert abs(np.mean(fz) - 13.7 * 9.80665) < 0.01  # the desk's weight, offsets off


def test_noise_amplitude_includes_the_resolution(paper_desk: DeskProfile) -> None:
    """With 0.15 N steps the rounding error depends on where the true value sits between two
    steps, so the amplitude holds on average over the sensors' random zero offsets."""
    variances = []
    for seed in range(8):
        rec = simulate(
            paper_desk,
            idle_scene(10.0),
            seed=seed,
            effects=SimEffects(dynamics=False),
            sensors=SensorParameters(drift_n_per_min=0.0),
        )
        variances.append(np.var(total_fz(paper_desk, rec.wrench)))
    assert 3.0 * np.sqrt(np.mean(variances)) == pytest.approx(0.4, rel=0.04)


def test_noise_amplitude_is_a_parameter(paper_desk: DeskProfile) -> None:
    sensors = SensorParameters(noise_amplitude_n=1.2, noise_amplitude_sigmas=2.0)
    rec = simulate(paper_desk, idle_scene(20.0), seed=4, effects=QUIET, sensors=sensors)
    assert 2.0 * np.std(total_fz(paper_desk, rec.wrench)) == pytest.approx(1.2, rel=0.03)


def test_noise_calibrates_on_rotated_sensors(odd_desk: DeskProfile, octo_desk: DeskProfile) -> None:
    for desk in (odd_desk, octo_desk):
        rec = simulate(
            desk,
            idle_scene(30.0),
            seed=2,
            effects=SimEffects(dynamics=False, drift=False, quantisation=False),
        )
        assert 3.0 * np.std(total_fz(desk, rec.wrench)) == pytest.approx(0.4, rel=0.03)


def test_readings_are_whole_steps_of_the_resolution(paper_desk: DeskProfile) -> None:
    rec = simulate(paper_desk, idle_scene(2.0), seed=1)
    step = np.array([150, 150, 300, 4, 4, 4]) / 2000.0
    units = rec.wrench / step
    assert np.abs(units - np.round(units)).max() < 1e-6
    assert len(np.unique(rec.wrench[:, 0, 2])) > 1  # the noise flips between steps


def test_saturation_clips_at_the_rated_range(paper_desk: DeskProfile) -> None:
    """A 150 kg load on one corner saturates that leg's F_z at exactly its 300 N rating."""
    scene = Scene(
        [
            PutObject(name="anvil", mass_kg=150.0, point=(0.37, 0.24), duration_s=0.5),
            Idle(duration_s=1.0),
            LiftObject(name="anvil"),
        ],
        quiet_s=1.0,
    )
    rec = simulate(paper_desk, scene, seed=0, effects=SimEffects(dynamics=False))
    br = paper_desk.sensor_names.index("br")
    fz = rec.wrench[:, br, 2]
    assert fz.max() == 300.0
    assert np.count_nonzero(fz == 300.0) > 1000
    assert np.all(np.abs(rec.wrench) <= np.array([150, 150, 300, 4, 4, 4]))
    unclipped = simulate(
        paper_desk, scene, seed=0, effects=SimEffects(dynamics=False, saturation=False)
    )
    assert unclipped.wrench[:, br, 2].max() > 400.0


def test_offset_and_drift(paper_desk: DeskProfile) -> None:
    sensors = SensorParameters(offset_n=0.5, drift_n_per_min=2.0)
    effects = SimEffects(dynamics=False, noise=False, quantisation=False)
    rec = simulate(paper_desk, idle_scene(60.0), seed=7, effects=effects, sensors=sensors)
    ideal = simulate(paper_desk, idle_scene(60.0), seed=7, effects=SimEffects.ideal())
    error = rec.wrench - ideal.wrench  # (k, S, 6): offset + rate·t per channel
    t = rec.t
    slope = (error[-1] - error[0]) / (t[-1] - t[0])
    line = error[0] + slope * t[:, None, None]
    assert np.abs(error - line).max() < 1e-9  # straight lines
    assert np.std(slope[:, 2]) * 60 > 0.3  # per-sensor F_z rates of the order of 2 N/min
    assert np.abs(error[0, :, 2]).max() > 0.05  # zero offsets
    other = simulate(paper_desk, idle_scene(60.0), seed=8, effects=effects, sensors=sensors)
    assert not np.allclose(other.wrench, rec.wrench)  # drawn per seed


def test_switching_effects_off_gives_the_exact_static_split(paper_desk: DeskProfile) -> None:
    rec = simulate(paper_desk, idle_scene(1.0), seed=1, effects=SimEffects.ideal())
    assert np.all(rec.wrench == rec.wrench[0])
    np.testing.assert_allclose(rec.wrench[0, :, 2], 13.7 * 9.80665 / 4)


def test_unrated_sensors_are_neither_rounded_nor_clipped(tri_desk: DeskProfile) -> None:
    model = SensorModel(tri_desk)
    assert np.all(model.step == 0) and np.all(np.isinf(model.limits))
    readings = np.full((3, 3, 6), 1234.56789)
    out = model.apply(
        readings, np.zeros(3), noise_rng=None, drift=None, quantisation=True, saturation=True
    )
    np.testing.assert_array_equal(out, readings)
