"""Noise, natural frequencies, cut-off and drift recovered from simulated desks whose truth
is known (the simulator's DeskParameters and SensorParameters)."""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml

from hapticdesk.analysis.characterize import CUTOFF_RATIO, characterize
from hapticdesk.cli import main
from hapticdesk.errors import ConfigError
from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.profile_reader import load_profile
from hapticdesk.files.recording import Recording
from hapticdesk.files.recording_io import write_recording
from hapticdesk.sim import (
    DeskParameters,
    Idle,
    Scene,
    SensorParameters,
    SimEffects,
    simulate,
)

from .conftest import knock_scene

PAPER_NOISE_N = 0.4  # SensorParameters' default: 3σ of the total F_z at rest


def true_drift_per_min(profile: DeskProfile, seed: int, sensors: SensorParameters) -> np.ndarray:
    """Each channel's drift rate as the simulator drew it: a run with nothing but offset and
    drift (drawn from the seed alone, whatever the scene), so the readings change linearly."""
    run = simulate(
        profile,
        Scene([Idle(duration_s=2.0)], quiet_s=0.0, tail_s=0.0),
        seed=seed,
        sensors=sensors,
        effects=SimEffects(noise=False, quantisation=False, dynamics=False),
    )
    w = run.wrench.reshape(len(run.t), -1)
    return (w[-1] - w[0]) / (run.t[-1] - run.t[0]) * 60.0


def drift_tolerance(
    truth: np.ndarray, stderr: np.ndarray, n_sensors: int, sigma: float
) -> np.ndarray:
    """5 standard errors, 5 % of the rate, or 2 % of the channel's drift scale (the resolution
    rounds a slowly drifting value in steps, which bends the slope of a quiet channel)."""
    scale = np.tile(np.array([150.0, 150.0, 300.0, 4.0, 4.0, 4.0]) / 300.0 * sigma, n_sensors)
    return np.maximum.reduce([5 * stderr, 0.05 * np.abs(truth), 0.02 * scale])


def test_natural_frequency_noise_and_cutoff_of_the_paper_desk(
    desk: DeskProfile, knock_recording: Recording
) -> None:
    c = characterize(desk, knock_recording)
    assert c.segments >= 4  # five knocks
    assert c.lowest_mode_hz == pytest.approx(5.9, abs=0.3)  # measured 5.90
    assert c.suggested_cutoff_hz == pytest.approx(CUTOFF_RATIO * c.lowest_mode_hz, abs=0.006)
    assert c.suggested_cutoff_hz == pytest.approx(4.77, abs=0.3)  # the paper's cut-off
    amplitude = c.noise_of("total_fz").amplitude
    assert amplitude == pytest.approx(PAPER_NOISE_N, rel=0.15)  # measured 0.419
    # the sensors' own channels: F_x, F_y rated 150 N are half as noisy as F_z (300 N)
    fz = np.mean([c.noise_of(f"{s}_fz").sigma for s in desk.sensor_names])
    fx = np.mean([c.noise_of(f"{s}_fx").sigma for s in desk.sensor_names])
    assert fx / fz == pytest.approx(0.5, rel=0.2)
    assert c.quiet_s >= 25.0  # the first 30 s are quiet
    assert c.quiet_s <= knock_recording.t[-1] - 5 * 1.0  # the knocks are not


@pytest.mark.parametrize(("sway_hz", "noise_n"), [(8.0, 0.8), (4.0, 0.6)])
def test_other_desks_and_sensors_are_recovered(
    desk: DeskProfile, sway_hz: float, noise_n: float
) -> None:
    rec = simulate(
        desk,
        knock_scene(quiet_s=15.0, knocks=4),
        seed=7,
        desk=DeskParameters(sway_frequency_hz=sway_hz),
        sensors=SensorParameters(noise_amplitude_n=noise_n),
    )
    c = characterize(desk, rec)
    assert c.lowest_mode_hz == pytest.approx(sway_hz, abs=0.3)
    assert c.noise_of("total_fz").amplitude == pytest.approx(noise_n, rel=0.15)


def test_noise_is_measured_between_presses(desk: DeskProfile, paper_recording: Recording) -> None:
    """The paper experiment leaves little quiet time; presses must not count as noise."""
    c = characterize(desk, paper_recording)
    assert c.noise_of("total_fz").amplitude == pytest.approx(PAPER_NOISE_N, rel=0.15)
    assert c.lowest_mode_hz == pytest.approx(5.9, abs=0.3)  # rings after each release


def test_drift_rate_per_channel(desk: DeskProfile) -> None:
    sensors = SensorParameters(drift_n_per_min=0.5)
    rec = simulate(desk, knock_scene(), seed=5, sensors=sensors)
    c = characterize(desk, rec)
    truth = true_drift_per_min(desk, 5, sensors)
    measured = np.array([d.rate_per_min for d in c.drift])
    stderr = np.array([d.stderr_per_min for d in c.drift])
    assert [d.channel for d in c.drift] == desk.channel_names()
    # measured: within 0.002 N/min of rates of 0.1–1 N/min
    assert np.all(np.abs(measured - truth) <= drift_tolerance(truth, stderr, 4, 0.5))
    force = np.array([d.unit == "N" for d in c.drift])
    rms = float(np.sqrt(np.mean(measured[force] ** 2)))
    assert rms == pytest.approx(float(np.sqrt(np.mean(truth[force] ** 2))), rel=0.1)
    assert c.profile_values()["estimation"]["drift_force_n_per_min"] == pytest.approx(rms, rel=0.01)


def test_default_drift_has_the_simulators_order_of_magnitude(
    desk: DeskProfile, knock_recording: Recording
) -> None:
    c = characterize(desk, knock_recording)
    rms = c.profile_values()["estimation"]["drift_force_n_per_min"]
    assert 0.05 / 3 < rms < 0.05 * 3  # SensorParameters.drift_n_per_min = 0.05 (σ per channel)


def test_a_bench_sensor_without_surfaces(bench_sensor: DeskProfile) -> None:
    sensors = SensorParameters(drift_n_per_min=0.5)
    rec = simulate(bench_sensor, Scene([Idle(duration_s=30.0)]), seed=2, sensors=sensors)
    c = characterize(bench_sensor, rec)
    assert c.noise_of("ft_fz").amplitude == pytest.approx(PAPER_NOISE_N, rel=0.15)
    truth = true_drift_per_min(bench_sensor, 2, sensors)
    measured = np.array([d.rate_per_min for d in c.drift])
    stderr = np.array([d.stderr_per_min for d in c.drift])
    assert np.all(np.abs(measured - truth) <= drift_tolerance(truth, stderr, 1, 0.5))
    assert c.modes == [] and "no free decay" in c.modes_reason
    values = c.profile_values()
    assert "desk" not in values and "noise_force_n" in values["estimation"]
    assert yaml.safe_load(c.snippet()) == values


def test_noise_below_the_resolution_is_noted(desk: DeskProfile) -> None:
    rec = simulate(
        desk,
        Scene([Idle(duration_s=12.0)]),
        seed=4,
        sensors=SensorParameters(noise_amplitude_n=0.05),
    )
    c = characterize(desk, rec)
    assert any("below their resolution" in n for n in c.notes)
    assert c.drift_reason == "" or "span" in c.drift_reason


def test_too_short_a_recording_is_refused(desk: DeskProfile, knock_recording, tmp_path, capsys):
    short = Recording(knock_recording.t[:500], knock_recording.wrench[:500], desk.sensor_names)
    with pytest.raises(ConfigError, match="too short"):
        characterize(desk, short)
    path = tmp_path / "short.csv"
    write_recording(path, short)
    assert main(["characterize", str(path), "--desk", "kitamura2017"]) == 2
    assert "too short" in capsys.readouterr().err


def test_nan_samples_are_left_out(desk: DeskProfile, knock_recording: Recording) -> None:
    wrench = knock_recording.wrench.copy()
    wrench[5000:5100, 1, 2] = np.nan
    broken = Recording(knock_recording.t, wrench, desk.sensor_names)
    c = characterize(desk, broken)
    assert any("100 samples with NaN" in n for n in c.notes)
    assert c.lowest_mode_hz == pytest.approx(5.9, abs=0.3)
    info = c.to_dict()
    json.dumps(info, allow_nan=False)  # no NaN anywhere


def test_cli_text_and_json(tmp_path, knock_recording, capsys) -> None:
    path = tmp_path / "knocks.npz"
    write_recording(path, knock_recording)
    assert main(["characterize", str(path), "--desk", "kitamura2017"]) == 0
    out = capsys.readouterr().out
    assert "total_fz" in out and "suggested low-pass cut-off: 4.77 Hz" in out
    assert "desk: {natural_frequency_hz: 5.9}" in out
    assert main(["characterize", str(path), "--desk", "kitamura2017", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["desk"] == "kitamura2017"
    assert info["profile"]["desk"]["natural_frequency_hz"] == pytest.approx(5.9, abs=0.3)
    assert len(info["noise"]) == 24 and len(info["total_noise"]) == 6


def test_cli_errors_exit_2(tmp_path, capsys) -> None:
    missing = tmp_path / "missing.npz"
    assert main(["characterize", str(missing), "--desk", "kitamura2017"]) == 2
    assert "missing.npz" in capsys.readouterr().err
    assert main(["characterize", str(missing), "--desk", str(tmp_path / "desk.yaml")]) == 2
    assert "no such desk profile" in capsys.readouterr().err


def test_the_pasted_snippet_sets_the_estimators_filters(desk, knock_recording, tmp_path) -> None:
    c = characterize(desk, knock_recording)
    assert desk.path is not None
    doc = yaml.safe_load(desk.path.read_text(encoding="utf-8"))
    for section, values in yaml.safe_load(c.snippet()).items():
        doc.setdefault(section, {}).update(values)
    path = tmp_path / "desk.yaml"
    path.write_text(yaml.safe_dump(doc, allow_unicode=True), encoding="utf-8")
    pasted = load_profile(path)
    assert pasted.natural_frequency_hz == pytest.approx(c.lowest_mode_hz, abs=0.006)
    assert pasted.estimation.force_lowpass_hz == c.suggested_cutoff_hz
    assert pasted.estimation.diff_lowpass_hz == c.suggested_cutoff_hz
    assert pasted.estimation.noise_force_n == pytest.approx(
        np.sqrt(np.mean([n.sigma**2 for n in c.noise if n.unit == "N"])), rel=0.01
    )


def test_a_load_cell_desk_is_characterized_per_cell() -> None:
    """One channel a cell, named as its recording's columns; its noise is the converter's
    (an HX711 at 80 Hz on a 490 N cell: 0.026 N a reading)."""
    from hapticdesk.sim.loadcells import LoadCellParameters

    cells = load_profile("kitamura2017-loadcells-80hz")
    rec = simulate(cells, Scene([Idle(duration_s=30.0)]), seed=3)
    c = characterize(cells, rec)
    expected = LoadCellParameters.for_rate(80).noise_n * 490 / LoadCellParameters().rated_n
    for name in cells.channel_names():
        assert c.noise_of(name).unit == "N"
        assert c.noise_of(name).sigma == pytest.approx(expected, rel=0.15)
