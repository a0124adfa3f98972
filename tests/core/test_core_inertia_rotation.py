"""Several accelerometers (issue 15 items 4 and 6): three, not on one line, measure the desk's
rotation as well as its translation, and the estimator removes its whole inertial wrench
M q̈ — what a press on an upright panel excites (the yaw one accelerometer cannot see)."""

from __future__ import annotations

import numpy as np
import pytest

from hapticdesk.bench.accuracy import measure_accuracy
from hapticdesk.errors import ConfigError
from hapticdesk.estimator import ContactEstimator, estimate
from hapticdesk.estimator.contacts import FLAG_NO_ACCEL, ContactBlock
from hapticdesk.estimator.inertia import InertiaSettings, InertiaStage, accelerometer_readings
from hapticdesk.files.profile_reader import load_profile
from hapticdesk.files.recording import accel_table
from hapticdesk.files.recording_io import read_recording, write_recording
from hapticdesk.sim import LongPress, Scene, Tap, simulate
from hapticdesk.sim.desk import DeskModel
from hapticdesk.sim.sensors import AccelerometerModel


@pytest.fixture(scope="module")
def three():
    return load_profile("kitamura2017-panel-accel")


def _motions(seed: int, k: int = 200) -> np.ndarray:
    """Random desk accelerations q̈ = [d̈; θ̈] (k, 6), m/s² and rad/s²."""
    return np.random.default_rng(seed).normal(scale=[0.5, 0.5, 0.1, 0.2, 0.2, 2.0], size=(k, 6))


def _readings(profile, qdd: np.ndarray) -> np.ndarray:
    """The simulator's noise-free readings of the desk's accelerometers for q̈ (desk level)."""
    return AccelerometerModel(profile).readings(
        qdd, np.zeros_like(qdd), noise_rng=None, saturation=False
    )


def _changed(profile, tmp_path, old: str, new: str):
    """``profile`` with ``old`` replaced by ``new`` in its YAML text."""
    text = profile.path.read_text()
    assert old in text
    path = tmp_path / "changed.yaml"
    path.write_text(text.replace(old, new))
    return load_profile(path)


def _assert_removes_the_whole_wrench(desk, n_axes: int, seed: int) -> None:
    """For random rigid motions, the gain times the readings less gravity is the simulator's
    own M q̈ (to 1e-9)."""
    settings = InertiaSettings.of(desk)
    assert settings is not None and settings.n_axes == n_axes
    qdd = _motions(seed)
    got = (_readings(desk, qdd) - settings.rest) @ settings.gain.T
    expected = qdd @ DeskModel(desk).mass_matrix.T
    np.testing.assert_allclose(got, expected, atol=1e-9 * np.abs(expected).max())


def test_three_accelerometers_give_the_desks_whole_inertial_wrench(three) -> None:
    """Any rigid motion, rotation included: the gain times the readings less gravity is the
    simulator's own M q̈ (its mass, centre of mass and box inertia are the estimator's)."""
    _assert_removes_the_whole_wrench(three, n_axes=9, seed=1)


def test_one_accelerometer_misses_the_yaw(three, tmp_path) -> None:
    """The reason for three: one accelerometer at the top's centre takes a yaw for no motion
    at all, and leaves the yaw's inertial moment in the wrench."""
    text = three.path.read_text()
    start, end = text.index("accelerometers:\n"), text.index("sensors:\n")
    path = tmp_path / "one.yaml"
    path.write_text(text[:start] + "accelerometer: {position: [0, 0, 0.71]}\n" + text[end:])
    one = load_profile(path)
    settings = InertiaSettings.of(one)
    assert settings is not None
    yaw = np.zeros((1, 6))
    yaw[0, 5] = 10.0  # rad/s²
    left = (_readings(one, yaw) - settings.rest) @ settings.gain.T - yaw @ DeskModel(
        one
    ).mass_matrix.T
    assert abs(left[0, 5]) > 1.0  # N·m of yaw moment left
    three_settings = InertiaSettings.of(three)
    assert three_settings is not None
    left = (_readings(three, yaw) - three_settings.rest) @ three_settings.gain.T
    np.testing.assert_allclose(left, yaw @ DeskModel(three).mass_matrix.T, atol=1e-9)


def _without_back_accelerometer(three, tmp_path):
    text = three.path.read_text()
    start = text.index("  - {position: [0.0, 0.20, 0.71]")
    end = text.index("sensors:\n")
    path = tmp_path / "two.yaml"
    path.write_text(text[:start] + text[end : text.index("can:\n")])
    return load_profile(path)


def test_two_accelerometers_see_translation_and_leave_what_they_cannot_see(three, tmp_path) -> None:
    """Documented, not hidden: a rotation about the line through two accelerometers moves
    neither, so the compensation cannot take it out; of the motions that fit their readings
    it takes the one with the least rotation, so a translation (the desk's sway) is right to
    1e-4 (a plain pseudo-inverse mixed 4-10 % of rotation into it)."""
    two = _without_back_accelerometer(three, tmp_path)
    settings = InertiaSettings.of(two)
    assert settings is not None and settings.n_axes == 6
    mass = DeskModel(two).mass_matrix
    a, b = (spec.position for spec in two.accelerometers)
    axis = (b - a) / np.linalg.norm(b - a)
    spin = np.concatenate([-np.cross(axis, a), axis])[None, :]  # about the line through a, b
    np.testing.assert_allclose(_readings(two, spin) - settings.rest, 0.0, atol=1e-12)
    assert np.abs(spin @ mass.T).max() > 0.1  # it has a wrench, which stays
    sway = np.zeros((3, 6))
    sway[:, :3] = np.eye(3)  # 1 m/s² along x, y, z
    got = (_readings(two, sway) - settings.rest) @ settings.gain.T
    np.testing.assert_allclose(got, sway @ mass.T, atol=1e-4 * 13.7)  # (the unseen weighted 1e-2)
    yaw = np.zeros((1, 6))
    yaw[0, 5] = 10.0  # seen by the front pair (their line is along x)
    got = (_readings(two, yaw) - settings.rest) @ settings.gain.T
    np.testing.assert_allclose(got, yaw @ mass.T, atol=1e-4 * np.abs(yaw @ mass.T).max())


def test_turned_mounts_with_fewer_axes_and_different_noise(three, tmp_path) -> None:
    """Turned accelerometers, one measuring only x and y, each with its own noise: the whole
    motion is still seen and removed exactly (the rows are weighted by 1/σ, which changes
    nothing where the readings agree)."""
    text = three.path.read_text()
    start, end = text.index("accelerometers:\n"), text.index("sensors:\n")
    turned = (
        "accelerometers:\n"
        "  - {position: [-0.3, -0.2, 0.71], rotation_rpy_deg: [0, 0, 90], noise_m_s2: 0.01}\n"
        "  - {position: [0.3, -0.2, 0.71], rotation_rpy_deg: [180, 0, 30], axes: [x, y],"
        " noise_m_s2: 0.002}\n"
        "  - {position: [0.0, 0.2, 0.65], rotation_rpy_deg: [10, -20, 0], noise_m_s2: 0.005}\n"
    )
    path = tmp_path / "turned.yaml"
    path.write_text(text[:start] + turned + text[end : text.index("can:\n")])
    desk = load_profile(path)
    assert desk.accelerometer_columns() == [
        "acc_x", "acc_y", "acc_z", "acc2_x", "acc2_y", "acc3_x", "acc3_y", "acc3_z"
    ]  # fmt: skip
    _assert_removes_the_whole_wrench(desk, n_axes=8, seed=4)


def test_each_accelerometer_has_its_own_range(three, tmp_path) -> None:
    desk = _changed(
        three,
        tmp_path,
        "{position: [0.30, -0.20, 0.71], noise_m_s2: 0.005, range_m_s2: 19.6}",
        "{position: [0.30, -0.20, 0.71], noise_m_s2: 0.005, range_m_s2: 39.2}",
    )
    settings = InertiaSettings.of(desk)
    assert settings is not None
    np.testing.assert_array_equal(settings.limit, [19.6] * 3 + [39.2] * 3 + [19.6] * 3)
    reading = np.tile(settings.rest, (2, 1))
    reading[0, 4] = 30.0  # within the second's ±4 g
    reading[1, 1] = 30.0  # beyond the first's ±2 g
    np.testing.assert_array_equal(InertiaStage(settings).usable(reading), [True, False])


def test_streaming_sample_by_sample_equals_batch_with_three(three) -> None:
    """The stage is stateless: one sample at a time, or cut anywhere, gives the batch's
    output, with readings made unusable (NaN, at range, every axis lost) alike."""
    scene = Scene(actions=[Tap(point=(-0.25, 0.0), surface="front", peak_n=5.0)])
    rec = simulate(three, scene, seed=3)
    accel = accelerometer_readings(three, rec.extra)
    assert accel is not None and accel.shape == (len(rec.t), 9)
    accel = accel.copy()
    accel[1500, 4] = np.nan
    accel[1700, 8] = 19.6
    accel[1900] = np.nan
    batch = ContactEstimator(three).push(rec.t, rec.wrench, accel)
    # an axis lost: compensated from the others; every axis lost: flagged, uncompensated
    assert set(np.flatnonzero(batch.flags & FLAG_NO_ACCEL)) == {1900}
    one = ContactEstimator(three)
    parts = [one.push(rec.t[:1400], rec.wrench[:1400], accel[:1400]).copy()]
    parts += [
        one.push(rec.t[i : i + 1], rec.wrench[i : i + 1], accel[i : i + 1]).copy()
        for i in range(1400, len(rec.t))
    ]
    streamed = ContactBlock.concat(parts)
    np.testing.assert_array_equal(streamed.flags, batch.flags)
    np.testing.assert_array_equal(streamed.located, batch.located)
    np.testing.assert_allclose(streamed.x, batch.x, atol=1e-9)
    np.testing.assert_allclose(streamed.y, batch.y, atol=1e-9)


def test_a_lost_board_is_made_up_for_by_the_other_two(three) -> None:
    """One accelerometer's frames lost (a busy CAN bus) for a whole press on the panel: the
    other two still measure the sway and the yaw their line sees, so the press is placed
    nearly as with all three, unflagged; one accelerometer desk would drop the compensation.
    Each lost pattern's gain is computed once."""
    scene = Scene(actions=[Tap(point=(-0.25, 0.0), surface="front", peak_n=5.0)] * 3)
    rec = simulate(three, scene, seed=5)
    accel = accelerometer_readings(three, rec.extra)
    assert accel is not None
    full = ContactEstimator(three).push(rec.t, rec.wrench, accel)
    lost = accel.copy()
    lost[:, 6:9] = np.nan  # the back board silent throughout
    partial_est = ContactEstimator(three)
    partial = partial_est.push(rec.t, rec.wrench, lost)
    none = ContactEstimator(three).push(rec.t, rec.wrench)
    assert not (partial.flags & FLAG_NO_ACCEL).any()
    settings = partial_est.inertia_settings
    assert settings is not None and len(settings._partial) == 1
    found = {
        name: measure_accuracy(block, rec.extra).at_times["touch+50"]
        for name, block in (("full", full), ("partial", partial), ("none", none))
    }
    assert np.isfinite(found["partial"]).all()
    assert np.max(found["partial"]) < max(0.015, 1.5 * np.max(found["full"])), found
    assert not np.isfinite(found["none"]).all() or np.max(found["none"]) > np.max(
        found["partial"]
    ), found


def test_with_a_board_lost_single_pushes_stay_on_the_fast_path(three, monkeypatch) -> None:
    """A board silent for good must not send every single-sample push out of the compiled
    loop: the gain from the other two is kept for as long as the same readings are usable,
    with the same output as the batch."""
    scene = Scene(actions=[Tap(point=(-0.25, 0.0), surface="front", peak_n=5.0)])
    rec = simulate(three, scene, seed=6)
    accel = accelerometer_readings(three, rec.extra)
    assert accel is not None
    accel = accel.copy()
    accel[:, 3:6] = np.nan  # the front-right board silent throughout
    batch = ContactEstimator(three).push(rec.t, rec.wrench, accel)
    est = ContactEstimator(three)
    start = 3000
    parts = [est.push(rec.t[:start], rec.wrench[:start], accel[:start]).copy()]
    from hapticdesk.estimator import kernel_slots as slots

    general = []
    real_handle = est._handle
    monkeypatch.setattr(
        est, "_handle", lambda events, *a: general.append(events) or real_handle(events, *a)
    )
    parts += [
        est.push(rec.t[i : i + 1], rec.wrench[i : i + 1], accel[i : i + 1]).copy()
        for i in range(start, len(rec.t))
    ]
    assert len(general) < 0.01 * (len(rec.t) - start)  # (zero windows: rare)
    assert not any(events & slots.EV_PARTIAL_ACCEL for events in general)
    streamed = ContactBlock.concat(parts)
    np.testing.assert_array_equal(streamed.flags, batch.flags)
    np.testing.assert_array_equal(streamed.located, batch.located)
    np.testing.assert_allclose(streamed.x, batch.x, atol=1e-9)
    assert not (batch.flags & FLAG_NO_ACCEL).any()


def test_the_columns_of_each_accelerometer_ride_in_recordings(three, tmp_path) -> None:
    """acc_*, acc2_*, acc3_*: written, read back from CSV and NPZ, and stacked in the
    profile's order by the replay source (``accel_table``); a bad cell of any of them is
    an error with file:line:column, not a column silently dropped."""
    rec = simulate(three, Scene(actions=[Tap(point=(0.0, 0.0), surface="front")]), seed=1)
    assert three.accelerometer_columns() == [
        f"{prefix}_{axis}" for prefix in ("acc", "acc2", "acc3") for axis in "xyz"
    ]
    expected = accelerometer_readings(three, rec.extra)
    for suffix in (".csv", ".npz"):
        path = tmp_path / f"three{suffix}"
        write_recording(path, rec)
        back = read_recording(path, three.sensor_names)
        shuffled = dict(reversed(list(back.extra.items())))  # order must not matter
        np.testing.assert_allclose(accel_table(shuffled), expected, atol=1e-6)
    path = tmp_path / "three.csv"
    lines = path.read_text().splitlines()
    column = lines[0].split(",").index("acc3_y")
    cells = lines[5].split(",")
    cells[column] = "oops"
    lines[5] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(ConfigError) as info:
        read_recording(path, three.sensor_names)
    assert str(info.value).startswith(f"{path}:6:{column + 1}:"), str(info.value)
    assert "acc3_y" in str(info.value)


def test_accel_table_orders_by_the_accelerometers_number() -> None:
    names = ["acc10_y", "acc2_x", "acc_z", "acc10_x", "acc_x", "acc1_x", "true_x", "acc3_y"]
    columns = {name: np.full(2, float(i)) for i, name in enumerate(names)}
    table = accel_table(columns)
    assert table is not None
    # acc, acc2, acc3, acc10 in turn, x before z; acc1_x is no accelerometer's column
    np.testing.assert_array_equal(table[0], [4.0, 2.0, 1.0, 7.0, 3.0, 0.0])


def test_a_replay_takes_the_profiles_columns(three, tmp_path) -> None:
    """A recording with more accelerometers than the desk (or fewer) replays: the desk's own
    columns are used, or none (its samples then flagged uncompensated), never an error."""
    from hapticdesk.plugins.replay import open_replay

    rec = simulate(three, Scene(actions=[Tap(point=(0.0, 0.0), surface="front")]), seed=1)
    path = tmp_path / "three.csv"
    write_recording(path, rec)
    text = three.path.read_text()
    start, end = text.index("accelerometers:\n"), text.index("sensors:\n")
    one_path = tmp_path / "one.yaml"
    one_path.write_text(
        text[:start] + "accelerometer: {position: [-0.30, -0.20, 0.71]}\n" + text[end:]
    )
    one = load_profile(one_path)
    source = open_replay(str(path), one, speed=0)
    got = np.concatenate([b.accel for b in source.blocks()])
    source.close()
    expected = accelerometer_readings(one, read_recording(path, one.sensor_names).extra)
    np.testing.assert_array_equal(got, expected)
    assert got.shape == (len(rec.t), 3)
    short = tmp_path / "one.csv"
    write_recording(short, type(rec)(rec.t, rec.wrench, rec.sensor_names, {
        c: v for c, v in rec.extra.items() if not c.startswith(("acc2", "acc3"))
    }))  # fmt: skip
    source = open_replay(str(short), three, speed=0)
    assert all(b.accel is None for b in source.blocks())
    source.close()


def test_a_press_on_the_panel_is_placed_at_once_with_three(three) -> None:
    """End to end (simulator → estimator): long presses and taps off the panel's middle, where
    the desk's yaw is largest. Without the readings the first points are centimetres off or
    missing; with the three accelerometers every press is within 15 mm at +50 and +100 ms."""
    scene = Scene(
        actions=[
            LongPress(point=(-0.28, 0.05), surface="front", hold_s=1.0),
            Tap(point=(0.28, -0.05), surface="front", peak_n=5.0, wait_s=1.5),
            LongPress(point=(0.25, 0.0), surface="front", hold_s=1.0, wait_s=1.5),
        ]
    )
    rec = simulate(three, scene, seed=2)
    worst = {}
    for name, block in (
        ("with", estimate(three, rec)),
        ("without", ContactEstimator(three).push(rec.t, rec.wrench)),
    ):
        found = measure_accuracy(block, rec.extra).at_times
        assert len(found["touch+50"]) == 3
        worst[name] = max(float(np.max(found[f"touch+{ms}"])) for ms in (50, 100))
    assert worst["with"] < 0.015, worst
    assert worst["without"] > 2 * worst["with"], worst


@pytest.mark.parametrize(
    ("text", "line", "needle"),
    [
        ("accelerometers: []\n", 3, "must be a list of accelerometers"),
        (
            "accelerometers:\n  - {position: [0, 0, 0.7]}\n  - {position: [0, 0.7]}\n",
            5,
            "accelerometer 2 of `accelerometers`",
        ),
        (
            "accelerometer: {position: [0, 0, 0.7]}\naccelerometers: [{position: [0, 0, 0.7]}]\n",
            4,
            "not both",
        ),
    ],
)
def test_accelerometers_errors_name_file_line_and_what_was_expected(
    tmp_path, text, line, needle
) -> None:
    path = tmp_path / "acc.yaml"
    path.write_text(
        "name: acc\nsample_rate_hz: 1000\n"
        + text
        + "desk: {mass_kg: 10}\nsensors:\n  - {name: a, position: [0, 0, 0]}\n"
    )
    with pytest.raises(ConfigError) as info:
        load_profile(path)
    assert str(info.value).startswith(f"{path}:{line}:"), str(info.value)
    assert needle in str(info.value)


@pytest.mark.parametrize("value", ["[1, 2]", "[1, 0, 2]", "[1, .nan, 2]", "[0.1, 0.1, 5]"])
def test_a_bad_inertia_is_refused(tmp_path, value) -> None:
    path = tmp_path / "desk.yaml"
    path.write_text(
        "name: d\nsample_rate_hz: 1000\n"
        f"desk:\n  mass_kg: 10\n  inertia_kg_m2: {value}\n"
        "sensors:\n  - {name: a, position: [0, 0, 0]}\n"
    )
    with pytest.raises(ConfigError) as info:
        load_profile(path)
    assert str(info.value).startswith(f"{path}:5:"), str(info.value)


def test_hand_made_accelerometers_need_their_own_columns(three) -> None:
    from dataclasses import replace

    spec = three.accelerometers[0]
    with pytest.raises(ValueError, match="columns must differ"):
        replace(three, accelerometers=(spec, replace(spec, position=spec.position + 0.1)))


def test_a_given_inertia_is_used_by_the_estimator_and_the_simulator(three, tmp_path) -> None:
    given = _changed(
        three,
        tmp_path,
        "desk: {mass_kg: 13.7, natural_frequency_hz: 5.9}",
        "desk: {mass_kg: 13.7, natural_frequency_hz: 5.9, inertia_kg_m2: [0.5, 0.7, 1.1]}",
    )
    np.testing.assert_allclose(given.inertia_about_com(), np.diag([0.5, 0.7, 1.1]))
    settings = InertiaSettings.of(given)
    assert settings is not None
    qdd = _motions(2, 20)
    got = (_readings(given, qdd) - settings.rest) @ settings.gain.T
    np.testing.assert_allclose(got, qdd @ DeskModel(given).mass_matrix.T, atol=1e-9)
