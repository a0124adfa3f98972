"""Load cells in the simulator: legs on pins, raw channels, conversions, gain, creep, noise,
rounding and limits (hapticdesk.sim.desk, hapticdesk.sim.loadcells)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.profile_reader import load_profile, profile_from_mapping
from hapticdesk.files.recording_io import read_recording, write_recording
from hapticdesk.files.yamlfile import load_marked_yaml
from hapticdesk.sim import (
    DeskModel,
    DeskParameters,
    Idle,
    LiftObject,
    Press,
    PutObject,
    Scene,
    SimEffects,
    SimSource,
    Tap,
    simulate,
)
from hapticdesk.sim.desk import point_load
from hapticdesk.sim.loadcells import Conversions, LoadCellModel, LoadCellParameters

G = 9.80665
#: statics, no sensor error: the readings are the cells' exact share
IDEAL = SimEffects.ideal()


def cell_desk(cells: str, *, rate: float = 80, top: float = 0.733, extra: str = "") -> DeskProfile:
    """A load-cell desk with ``cells`` (YAML lines of its sensors)."""
    text = f"""name: cells
sample_rate_hz: {rate}
desk: {{mass_kg: 8.0, natural_frequency_hz: 6.0, center_of_mass_m: [0, 0, {top - 0.02}]}}
sensors:
{cells}
surfaces:
  - {{name: top, origin: [0, 0, {top}], normal: [0, 0, 1],
     polygon: [[-0.5, -0.35], [0.5, -0.35], [0.5, 0.35], [-0.5, 0.35]]}}
{extra}"""
    path = Path("cells.yaml")
    return profile_from_mapping(load_marked_yaml(path, text), path)


FOUR = """  - {name: a, kind: load_cell, position: [-0.4, -0.3, 0.7]}
  - {name: b, kind: load_cell, position: [0.4, -0.3, 0.7]}
  - {name: c, kind: load_cell, position: [-0.4, 0.3, 0.7]}
  - {name: d, kind: load_cell, position: [0.4, 0.3, 0.7]}"""
THREE_ODD = """\
  - {name: a, kind: load_cell, position: [-0.45, -0.3, 0], rotation_rpy_deg: [0, 0, 40]}
  - {name: b, kind: load_cell, position: [0.45, -0.3, 0], rotation_rpy_deg: [180, 0, 0]}
  - {name: c, kind: load_cell, position: [0.0, 0.32, 0], reports: load}"""
SIX = "\n".join(
    f"  - {{name: s{i}, kind: load_cell, position: [{x}, {y}, 0.69], "
    f"rotation_rpy_deg: [0, 0, {30 * i}]{', reports: load' if i % 2 else ''}}}"
    for i, (x, y) in enumerate(
        [(-0.45, -0.3), (0.0, -0.3), (0.45, -0.3), (-0.45, 0.3), (0.0, 0.3), (0.45, 0.3)]
    )
)


def located(profile: DeskProfile, channels: np.ndarray) -> np.ndarray:
    """(k, 2) the centre of pressure the channels give, fz alone (paper eq. 5, F_x = F_y = 0)."""
    w = profile.flat_channels(channels) @ profile.wrench_map().T
    return np.column_stack([-w[:, 4] / w[:, 2], w[:, 3] / w[:, 2]])


@pytest.mark.parametrize("cells", [FOUR, THREE_ODD, SIX], ids=["four", "three-odd", "six"])
def test_pinned_legs_locate_a_still_press_from_fz_alone(cells: str) -> None:
    """On pins the cells' axial forces carry every moment: fz alone gives the point, to 1e-9 m,
    for upright, turned, upside-down and load-reporting cells, three to six of them."""
    desk = cell_desk(cells)
    model = DeskModel(desk)
    assert model.pinned
    top = desk.surfaces[0].origin[2]
    points = np.array([[0.3, 0.2], [-0.41, -0.12], [0.0, 0.3], [0.05, -0.02]])
    force = np.tile([0.0, 0.0, -7.0], (4, 1))
    loads = point_load(force, np.column_stack([points, np.full(4, top)]))
    readings = model.static_readings(loads)
    assert np.abs(readings[:, :, [0, 1, 3, 4, 5]]).max() < 1e-9 * np.abs(readings).max() + 1e-12
    np.testing.assert_allclose(located(desk, readings[:, :, 2]), points, atol=1e-9)


def test_a_sideways_push_moves_the_centre_of_pressure_by_its_lever() -> None:
    """A push f along the top at its height h above the cells is no force to them, but its
    moment is: the centre of pressure moves by h·f/F_z, as on a real table."""
    desk = cell_desk(FOUR)
    model = DeskModel(desk)
    h = 0.733 - 0.7
    load = point_load(np.array([0.4, -0.2, -5.0]), np.array([0.1, 0.05, 0.733]))
    fz = model.static_readings(load)[:, :, 2]
    np.testing.assert_allclose(
        located(desk, fz)[0], [0.1 + h * 0.4 / 5.0, 0.05 - h * 0.2 / 5.0], atol=1e-9
    )


def test_clamped_legs_carry_moments_the_cells_miss() -> None:
    """The reason for the pins: legs that carry moments (the six-axis desk's springs) hide part
    of the moment from fz, and the point is centimetres off; a six-axis desk stays clamped."""
    desk = cell_desk(THREE_ODD)
    clamped = DeskModel(desk, DeskParameters(legs="clamped"))
    assert not clamped.pinned and not DeskModel(load_profile("kitamura2017")).pinned
    load = point_load(np.array([0.3, 0.0, -5.0]), np.array([0.2, 0.1, 0.733]))
    pinned_fz = DeskModel(desk).static_readings(load)[:, :, 2]
    clamped_fz = clamped.static_readings(load)[:, :, 2]
    lever = 0.733 * 0.3 / 5.0
    assert located(desk, pinned_fz)[0] == pytest.approx([0.2 + lever, 0.1], abs=1e-9)
    assert np.hypot(*(located(desk, clamped_fz)[0] - [0.2 + lever, 0.1])) > 0.005
    with pytest.raises(ValueError, match="legs must be one of"):
        DeskModel(desk, DeskParameters(legs="glued"))


def test_a_load_cell_recording_holds_the_raw_channels(tmp_path: Path) -> None:
    """(k, C), the profile's channel names, the truth beside them; a CSV reads back equal."""
    desk = load_profile("kitamura2017-loadcells-80hz")
    rec = simulate(desk, Scene([Tap((0.1, 0.05), peak_n=4.0)]), seed=2)
    assert rec.wrench.shape == (len(rec.t), 4)
    assert rec.channel_columns() == ["fl_fz", "fr_fz", "bl_fz", "br_fz"]
    assert np.allclose(np.diff(rec.t), 1 / 80)
    clean = simulate(desk, Scene([Tap((0.1, 0.05), peak_n=4.0)]), seed=2, noise=False)
    assert clean.wrench[:80].sum(axis=1).mean() == pytest.approx(6.5 * G, abs=1e-3)
    assert (rec.extra["true_fn"] > 0).any()
    path = tmp_path / "cells.csv"
    write_recording(path, rec)
    back = read_recording(path, desk.sensor_names, channel_names=desk.channel_names())
    np.testing.assert_allclose(back.channels, rec.channels, rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("sampling", ["simultaneous", "multiplexed", "independent"])
def test_any_split_into_blocks_gives_the_same_readings(sampling: str) -> None:
    """Over chunk borders (61 s at 80 Hz is two internal chunks), with creep, drift, noise:
    the source's blocks of 1, 7 and 1000 samples equal the recording."""
    desk = load_profile("kitamura2017-loadcells-80hz")
    cells = LoadCellParameters.hx711(80, sampling=sampling, creep=0.01, creep_time_s=20.0)
    scene = Scene([Press((0.1, 0.1), start_s=50.5), Idle(duration_s=9.0)], seed=3)
    whole = simulate(desk, scene, cells=cells)
    assert len(whole.t) > 4096
    for size in (1, 7, 1000):
        blocks = list(SimSource(desk, scene, block_size=size, cells=cells).blocks())
        np.testing.assert_array_equal(np.concatenate([b.wrench for b in blocks]), whole.wrench)
        np.testing.assert_array_equal(np.concatenate([b.t for b in blocks]), whole.t)


def test_conversions_average_their_own_period() -> None:
    """A ramp read by each kind of conversion: simultaneous readings lag half a period,
    multiplexed channel i (C − 1 − i)/C of a period more, independent ones their own clock's
    phase; each reading is the ramp at its conversion's middle."""
    points, channels = 16, 4
    fine = np.arange(2000.0)[:, None] * np.ones(channels)  # the ramp: value = fine index
    k = np.arange(10, 100)
    rng = np.random.default_rng(0)
    for sampling in ("simultaneous", "multiplexed", "independent"):
        conv = Conversions.of(sampling, channels, points, 0.01, rng)
        model = LoadCellModel.__new__(LoadCellModel)
        model.conversions = conv
        history = np.zeros((conv.history, channels))
        out = LoadCellModel.convert(model, fine, 0, history, k)
        middle = conv.ends(k) - (conv.lengths - 1) / 2
        np.testing.assert_allclose(out, middle, atol=1e-9)
        np.testing.assert_allclose(conv.times(k, 80.0), middle / (80.0 * points))
        lag = k[:, None] * points - middle  # fine points behind the reading's time
        if sampling == "simultaneous":
            np.testing.assert_allclose(lag, (points - 1) / 2)
        elif sampling == "multiplexed":
            np.testing.assert_allclose(lag[0], [13.5, 9.5, 5.5, 1.5])
        else:
            assert (lag >= 0).all() and (lag < 2 * points).all()
            assert np.ptp(lag[0]) > 1  # the converters are not in step


def test_gain_noise_rounding_and_range() -> None:
    """A cell's gain scales its reading; noise has its σ (scaled by the cell's rating), readings
    are whole steps of the LSB, and stop at the channel's range."""
    desk = cell_desk(FOUR.replace("0.7]}", "0.7], range: {force_n: 98.0665}}"), rate=80)
    quiet = SimEffects(dynamics=False, drift=False)
    cells = LoadCellParameters(noise_n=0.02, lsb_n=0.004, gains=(1.05, 1, 1, 1), rated_n=196.133)
    rec = simulate(desk, Scene([Idle(duration_s=30.0)]), seed=1, effects=quiet, cells=cells)
    exact = simulate(desk, Scene([Idle(duration_s=30.0)]), seed=1, effects=IDEAL)
    share = rec.channels.mean(axis=0) / exact.channels.mean(axis=0)
    np.testing.assert_allclose(share, [1.05, 1, 1, 1], atol=2e-4)
    # rated at half the 196 N the parameters are given for: half the noise and step
    assert np.std(rec.channels, axis=0) == pytest.approx(np.full(4, 0.01), rel=0.06)
    steps = rec.channels / 0.002
    np.testing.assert_allclose(steps, np.round(steps), atol=1e-6)
    heavy = Scene([PutObject("anvil", 30.0, (0.4, 0.3), duration_s=0.2, wait_s=0.5)], tail_s=2)
    loaded = simulate(desk, heavy, seed=1, effects=quiet, cells=cells)
    assert loaded.channels.max() == pytest.approx(98.0665, abs=1e-9)


def test_creep_follows_a_load_over_its_time_constant() -> None:
    """A weight held 60 s: the reading creeps on by creep·W·(1 − e^(−t/τ)), and back."""
    desk = cell_desk(FOUR)
    creep = LoadCellParameters(
        noise_n=0.0, lsb_n=0.0, offset_n=0.0, drift_n_per_min=0.0, creep=0.01, creep_time_s=20.0
    )
    effects = SimEffects(dynamics=False, noise=True, drift=True, quantisation=False)
    scene = Scene(
        [
            PutObject("w", 10.0, (0.0, 0.0), duration_s=0.0, start_s=2.0),
            LiftObject("w", duration_s=0.0, start_s=62.0),
        ],
        tail_s=60.0,
    )
    rec = simulate(desk, scene, seed=0, effects=effects, cells=creep)
    total = rec.channels.sum(axis=1)
    base = total[rec.t < 1.9].mean()
    weight = 10.0 * G
    for t_after in (1.0, 20.0, 59.0):
        at = np.searchsorted(rec.t, 2.0 + t_after)
        expected = weight * (1 + 0.01 * (1 - np.exp(-(rec.t[at] - 2.0) / 20.0)))
        assert total[at] - base == pytest.approx(expected, rel=2e-3)
    late = np.searchsorted(rec.t, 62.0 + 40.0)
    assert total[late] - base == pytest.approx(
        0.01 * weight * (1 - np.exp(-60 / 20)) * np.exp(-40 / 20), rel=0.05
    )


def test_desk_and_sensor_parameters_must_fit_the_desk() -> None:
    """Six-axis sensors take `sensors`, load cells `cells`; a gain per channel; bad numbers
    are named."""
    from hapticdesk.sim import SensorParameters

    cells = load_profile("kitamura2017-loadcells-80hz")
    scene = Scene([Idle(duration_s=1.0)])
    with pytest.raises(ValueError, match="not `sensors`"):
        simulate(cells, scene, sensors=SensorParameters())
    with pytest.raises(ValueError, match="not `cells`"):
        simulate(load_profile("kitamura2017"), scene, cells=LoadCellParameters())
    with pytest.raises(ValueError, match="one number per raw channel"):
        simulate(cells, scene, cells=LoadCellParameters(gains=(1.0, 1.0)))
    for bad in (
        {"noise_n": -1.0},
        {"sampling": "sometimes"},
        {"creep_time_s": 0.0},
        {"gains": (1.0, float("nan"))},
    ):
        with pytest.raises(ValueError):
            LoadCellParameters(**bad)  # type: ignore[arg-type]


def test_presets_follow_the_datasheets() -> None:
    """HX711: 90 nV at 80 Hz (50 nV at 10 Hz) through a 20 kg, 1 mV/V cell at 4.3 V, times the
    board margin; an ADS1256 above 80 Hz, its cells taken in turn."""
    hx = LoadCellParameters.for_rate(80)
    assert hx.sampling == "simultaneous"
    assert hx.noise_n == pytest.approx(2.5 * 90e-9 / (1e-3 * 4.3 / (20 * G)), rel=1e-9)
    assert LoadCellParameters.for_rate(10).noise_n == pytest.approx(hx.noise_n * 5 / 9)
    ads = LoadCellParameters.for_rate(1000)
    assert ads.sampling == "multiplexed" and ads.lsb_n > hx.lsb_n
    assert replace(ads, sampling="independent").sampling == "independent"


def test_a_total_noise_amplitude_is_shared_by_the_cells(tmp_path: Path) -> None:
    """`with_total_amplitude` and `simulate --noise-amplitude` on a load-cell desk: 3σ of the
    total F_z at rest is the amplitude asked, the cells' shares scaled by their ratings."""
    from hapticdesk.cli import main
    from hapticdesk.sim.loadcells import with_total_amplitude

    desk = load_profile("kitamura2017-loadcells-80hz")
    quiet = SimEffects(dynamics=False, drift=False, quantisation=False)
    cells = with_total_amplitude(desk, 0.3)
    rec = simulate(desk, Scene([Idle(duration_s=60.0)]), seed=5, effects=quiet, cells=cells)
    assert 3 * np.std(rec.channels @ desk.wrench_map()[2]) == pytest.approx(0.3, rel=0.05)
    scene = tmp_path / "idle.yaml"
    scene.write_text("timeline:\n  - idle: 30\n")
    out = tmp_path / "idle.csv"
    argv = ["simulate", str(scene), "--desk", desk.name, "-o", str(out)]
    assert main([*argv, "--noise-amplitude", "0.3"]) == 0
    got = read_recording(out, desk.sensor_names, channel_names=desk.channel_names())
    spread = np.std(np.diff(got.channels @ desk.wrench_map()[2])) / np.sqrt(2)  # drift aside
    assert 3 * spread == pytest.approx(0.3, rel=0.1)
