"""The desk's physics: statics, modes, exact integration of stiff modes, inertia, frames."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.linalg

from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.profile_reader import load_profile
from hapticdesk.sim.desk import DeskModel, DeskParameters, point_load

TOP = 0.733


def resultant(profile: DeskProfile, readings: np.ndarray) -> np.ndarray:
    """[F_o; M_o] (k, 6) of the supports, from readings (k, S, 6) via the profile's map."""
    return readings.reshape(len(readings), -1) @ profile.wrench_map().T


def test_static_split_balances_any_load(any_desk: DeskProfile) -> None:
    model = DeskModel(any_desk)
    rng = np.random.default_rng(1)
    loads = rng.normal(0.0, [5, 5, 30, 2, 2, 1], size=(50, 6))
    readings = model.static_readings(loads)
    # paper eqs. (1)-(2): the supports' resultant cancels the load exactly
    np.testing.assert_allclose(resultant(any_desk, readings), -loads, atol=1e-9)


def test_a_vertical_press_splits_unevenly_between_four_legs(paper_desk: DeskProfile) -> None:
    model = DeskModel(paper_desk)
    load = point_load(np.array([0.0, 0.0, -20.0]), np.array([0.2, 0.1, TOP]))
    fz = model.static_readings(load[None])[0, :, 2]
    # the leg nearest the press (br at +x, +y) carries most, the farthest one least
    assert np.argmax(fz) == paper_desk.sensor_names.index("br")
    assert np.argmin(fz) == paper_desk.sensor_names.index("fl")
    assert fz.sum() == pytest.approx(20.0, abs=1e-9)


def test_sensors_carry_their_own_moments(paper_desk: DeskProfile) -> None:
    """A sideways push reaches each sensor as a shear *and* a moment of its own; leaving the
    sensors' own moments out breaks the balance (why the readout includes them)."""
    model = DeskModel(paper_desk)
    load = point_load(np.array([4.0, 0.0, 0.0]), np.array([0.0, 0.0, TOP]))
    readings = model.static_readings(load[None])
    my = readings[0, :, 4]
    assert np.all(np.abs(my) > 0.1)  # N·m, a shear of ≈1 N at a spring point ≈0.37 m up
    without = readings.copy()
    without[:, :, 3:] = 0.0
    error = resultant(paper_desk, without)[0] + load
    assert np.abs(error[3:]).max() > 0.3


@pytest.mark.parametrize("sway_hz", [5.9, 8.0, 3.0])
def test_lowest_mode_is_the_desks_natural_frequency(sway_hz: float) -> None:
    model = DeskModel(load_profile("kitamura2017"), DeskParameters(sway_frequency_hz=sway_hz))
    freqs = model.natural_frequencies_hz()
    assert freqs[0] == pytest.approx(sway_hz, rel=1e-9)
    # the vertical bounce of the symmetric desk sits exactly where it was put
    assert np.min(np.abs(freqs - 3000.0)) < 1e-6 * 3000.0


def test_profile_sets_mass_and_frequency(tri_desk: DeskProfile, octo_desk: DeskProfile) -> None:
    for desk, mass, hz in ((tri_desk, 9.0, 7.5), (octo_desk, 40.0, 4.2)):
        model = DeskModel(desk)
        assert model.mass_kg == mass
        assert model.natural_frequencies_hz()[0] == pytest.approx(hz, rel=1e-9)
        weight = model.static_readings(model.weight()[None])
        assert resultant(desk, weight)[0, 2] == pytest.approx(mass * 9.80665)


def test_free_sway_rings_at_the_natural_frequency(paper_desk: DeskProfile) -> None:
    """A sideways knock on the top board: the summed F_x rings at 5.9 Hz and decays."""
    model = DeskModel(paper_desk)
    fs = paper_desk.sample_rate_hz
    desk = model.discretize(1.0 / fs)
    n = int(20 * fs)
    loads = np.zeros((n, 6))
    loads[:6] = point_load(np.array([50.0, 0.0, 0.0]), np.array([0.0, 0.0, TOP]))  # 5 ms knock
    readings, _ = desk.run(loads, desk.initial_state(np.zeros(6)))
    fx = resultant(paper_desk, readings)[:, 0]
    spectrum = np.abs(np.fft.rfft(fx[12:] * np.hanning(n - 12)))
    freq = np.fft.rfftfreq(n - 12, 1.0 / fs)
    assert freq[np.argmax(spectrum)] == pytest.approx(5.9, abs=0.06)
    early, late = np.abs(fx[12 : int(fs)]).max(), np.abs(fx[-int(fs) :]).max()
    assert late < 1e-3 * early  # ζ = 0.03 damps it within seconds
    assert early > 1.0  # the knock did excite the sway


def test_mode_far_above_the_sample_rate_is_exact_and_stable(paper_desk: DeskProfile) -> None:
    """A 10 kHz leg mode sampled at 1.2 kHz: no blow-up, no smaller step needed — the result
    equals a run with a 32 times finer step (same held input), and the steady state is the
    static split."""
    params = DeskParameters(vertical_frequency_hz=10_000.0, vertical_damping=0.02)
    model = DeskModel(paper_desk, params)
    assert model.natural_frequencies_hz().max() > 10_000.0
    fs = 1200.0
    coarse = model.discretize(1.0 / fs)
    fine = model.discretize(1.0 / (32 * fs))
    rng = np.random.default_rng(3)
    n = 3000
    loads = np.zeros((n, 6))
    steps = np.cumsum(rng.normal(0.0, 1.0, (n, 3)) * (rng.random((n, 1)) < 0.01), axis=0)
    forces = np.column_stack([0.2 * steps[:, :2], -5.0 * np.abs(steps[:, 2]) - 10.0])
    loads = point_load(forces, np.array([0.1, -0.05, TOP]))
    start = loads[0]
    y_coarse, state = coarse.run(loads, coarse.initial_state(start))
    # each load is held over the interval that ends at its sample: on the fine grid, the 32
    # steps up to coarse sample k carry load k
    fine_loads = np.concatenate([loads[:1], np.repeat(loads[1:], 32, axis=0)])
    y_fine, _ = fine.run(fine_loads, fine.initial_state(start))
    assert np.isfinite(y_coarse).all()
    scale = np.abs(y_coarse).max()
    assert np.abs(y_coarse - y_fine[::32]).max() < 1e-9 * scale
    # explicit Euler at this step would be unstable: |1 + λ·dt| > 1 for the stiff mode
    lam = np.linalg.eigvals(model.state_matrices()[0])
    assert np.abs(1.0 + lam / fs).max() > 10.0
    # hold the last load for 30 s: the readings settle on the static split
    y_hold, _ = coarse.run(np.tile(loads[-1], (int(30 * fs), 1)), state)
    static = model.static_readings(loads[-1:])[0]
    assert np.abs(y_hold[-1] - static).max() < 1e-9 * scale


def test_discrete_model_matches_the_analytic_exponential(paper_desk: DeskProfile) -> None:
    model = DeskModel(paper_desk, DeskParameters(vertical_frequency_hz=10_000.0))
    dt = 1.0 / 1200.0
    desk = model.discretize(dt)
    a, b = model.state_matrices()
    lam, vec = np.linalg.eig(a)
    ad = (vec @ np.diag(np.exp(lam * dt)) @ np.linalg.inv(vec)).real
    bd = (vec @ np.diag((np.exp(lam * dt) - 1.0) / lam) @ np.linalg.inv(vec) @ b).real
    scale = np.concatenate([np.ones(6), np.full(6, desk._scale[-1])])
    # the discrete model works on x̃ = x / scale
    np.testing.assert_allclose(
        desk.ad, ad * scale[None, :] / scale[:, None], atol=1e-8 * np.abs(desk.ad).max()
    )
    np.testing.assert_allclose(desk.bd, bd / scale[:, None], atol=1e-8 * np.abs(desk.bd).max())
    assert np.all(np.abs(desk.poles) < 1.0)


def test_initial_state_is_at_rest(any_desk: DeskProfile) -> None:
    model = DeskModel(any_desk)
    desk = model.discretize(1.0 / any_desk.sample_rate_hz)
    load = model.weight() + point_load(np.array([0.5, -0.2, -8.0]), np.array([0.05, 0.02, 0.7]))
    readings, _ = desk.run(np.tile(load, (500, 1)), desk.initial_state(load))
    static = model.static_readings(load[None])[0]
    assert np.abs(readings - static).max() < 1e-9 * np.abs(static).max()


def test_running_in_blocks_equals_one_run(paper_desk: DeskProfile) -> None:
    model = DeskModel(paper_desk)
    desk = model.discretize(1.0 / 1200.0)
    rng = np.random.default_rng(5)
    loads = rng.normal(0.0, 3.0, (1000, 6))
    state = desk.initial_state(loads[0])
    whole, _ = desk.run(loads, state)
    parts, s = [], state
    for a, b in ((0, 1), (1, 13), (13, 500), (500, 1000)):
        y, s = desk.run(loads[a:b], s)
        parts.append(y)
    np.testing.assert_allclose(np.concatenate(parts), whole, rtol=0, atol=1e-12)


def test_supports_balance_load_plus_inertial_term(paper_desk: DeskProfile) -> None:
    """Σ support wrench (from the readings, desk frame) = M·q̈ − load: the inertial force the
    sensors feel while the desk moves. q̈ comes from differentiating the simulated velocity,
    at a rate high enough to resolve every mode (vertical mode put at 60 Hz)."""
    model = DeskModel(paper_desk, DeskParameters(vertical_frequency_hz=60.0))
    fs = 20_000.0
    desk = model.discretize(1.0 / fs)
    t = np.arange(int(2.0 * fs)) / fs
    push = 0.5 - 0.5 * np.cos(2 * math.pi * np.clip(t / 0.15, 0, 1))  # a smooth 0.15 s rise
    forces = np.column_stack([3.0 * push, -1.0 * push, -20.0 * push])
    loads = point_load(forces, np.array([0.2, 0.1, TOP])) + model.weight()
    state = desk.initial_state(loads[0])
    readings, _ = desk.run(loads, state)
    motion = desk.motion(loads, state)
    qdd = (motion[2:, 6:] - motion[:-2, 6:]) * (fs / 2.0)
    inertial = qdd @ model.mass_matrix.T
    held = 0.5 * (loads[1:-1] + loads[2:])  # the load held before and after each sample
    supports = resultant(paper_desk, readings)[1:-1]
    assert np.abs(inertial).max() > 1.0  # the desk really sways
    error = supports - (inertial - held)
    assert np.abs(error).max() < 2e-3 * np.abs(inertial).max()
    assert np.abs(supports + held).max() > 0.5 * np.abs(inertial).max()  # statics alone fail


def test_rotated_and_load_sensors_read_in_their_own_frames(
    paper_desk: DeskProfile, odd_desk: DeskProfile
) -> None:
    """Same geometry, different mountings: each odd sensor reads ±Rᵀ of the upright one."""
    load = point_load(np.array([1.0, -2.0, -15.0]), np.array([0.02, -0.01, TOP]))
    upright = DeskModel(paper_desk).static_readings(load[None])[0]
    odd = DeskModel(odd_desk).static_readings(load[None])[0]
    for i, s in enumerate(odd_desk.sensors):
        expect = s.sign * np.concatenate(
            [s.rotation.T @ upright[i, :3], s.rotation.T @ upright[i, 3:]]
        )
        np.testing.assert_allclose(odd[i], expect, atol=1e-9)
    fr = odd_desk.sensor_names.index("fr")  # upside down: pressing reads negative F_z
    bl = odd_desk.sensor_names.index("bl")  # reports the load: negative too
    assert odd[fr, 2] < -1.0 and odd[bl, 2] < -1.0
    np.testing.assert_allclose(resultant(odd_desk, odd[None])[0], -load, atol=1e-9)


def test_bad_parameters_are_refused(paper_desk: DeskProfile) -> None:
    with pytest.raises(ValueError, match="vertical_frequency_hz"):
        DeskModel(paper_desk, DeskParameters(vertical_frequency_hz=3.0))
    with pytest.raises(ValueError, match="mass_kg"):
        DeskModel(paper_desk, DeskParameters(mass_kg=-1.0))
    with pytest.raises(ValueError, match="sample time"):
        DeskModel(paper_desk).discretize(0.0)


def test_mass_matrix_is_the_rigid_body_inertia(paper_desk: DeskProfile) -> None:
    model = DeskModel(paper_desk)
    m = model.mass_matrix
    assert np.allclose(m, m.T)
    assert np.all(scipy.linalg.eigvalsh(m) > 0)
    # a pure translation has momentum m·v and angular momentum c × m·v about the origin
    v = np.array([0.3, -0.1, 0.2])
    momentum = m @ np.concatenate([v, np.zeros(3)])
    np.testing.assert_allclose(momentum[:3], model.mass_kg * v)
    np.testing.assert_allclose(momentum[3:], np.cross(model.center_of_mass, model.mass_kg * v))
