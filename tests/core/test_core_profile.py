"""Desk profiles: the shipped paper desk and errors that name file, line and column."""

from pathlib import Path

import numpy as np
import pytest

from hapticdesk.errors import ConfigError
from hapticdesk.files.profile_reader import load_profile
from hapticdesk.files.rigid_body import rotation_matrix

GOOD = """\
name: bench
sample_rate_hz: 1000
sensors:
  - {name: a, position: [0, 0, 0]}
  - {name: b, position: [1, 0, 0], rotation_rpy_deg: [180, 0, 0], reports: load}
  - {name: c, position: [0, 1, 0], rotation_rpy_deg: [0, 0, 90]}
surfaces:
  - name: top
    origin: [0, 0, 0.7]
    normal: [0, 0, 1]
    polygon: [[0, 0], [1, 0], [1, 1], [0, 1]]
  - name: side
    origin: [1, 0, 0.3]
    normal: [1, 0, 0]
    u_axis: [0, 1, 0]
    polygon: [[0, -0.2], [1, -0.2], [1, 0.2], [0, 0.2]]
"""


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "desk.yaml"
    path.write_text(text)
    return path


def test_paper_desk_is_shipped_with_table_1_numbers(paper_desk):
    assert paper_desk.sample_rate_hz == 1200
    assert len(paper_desk.sensors) == 4
    top = paper_desk.surface("top")
    assert top.origin[2] == pytest.approx(0.733)
    assert np.ptp(top.polygon[:, 0]) == pytest.approx(0.75)  # half-length 0.375 m
    assert np.ptp(top.polygon[:, 1]) == pytest.approx(0.5)
    assert paper_desk.estimation.touch_threshold_n == 5.67
    assert paper_desk.estimation.release_threshold_n == 11.8
    assert paper_desk.mass_kg == 13.7


def test_any_orientation_and_sign(tmp_path):
    desk = load_profile(write(tmp_path, GOOD))
    assert desk.sensors[1].sign == -1.0
    side = desk.surface("side")
    assert np.allclose(side.v_axis, np.cross(side.normal, side.u_axis))
    # a reading along the sensor's x maps to R·x in the desk frame
    assert np.allclose(rotation_matrix(0, 0, 90) @ [1, 0, 0], [0, 1, 0])
    assert desk.wrench_map().shape == (6, 18)


@pytest.mark.parametrize(
    ("old", "new", "line", "needle"),
    [
        ("sample_rate_hz: 1000", "sample_rate_hz: fast", 2, "must be a number"),
        ("reports: load", "reports: upside", 5, "one of reaction, load"),
        ("    normal: [0, 0, 1]", "    normal: [0, 0]", 10, "3 numbers"),
        ("    origin: [1, 0, 0.3]", "    origin: [1, 0, 0.3]\n    colour: red", 14, "unknown key"),
        (
            "  - {name: a, position: [0, 0, 0]}\n  - {name: b, position: [1, 0, 0], "
            "rotation_rpy_deg: [180, 0, 0], reports: load}\n"
            "  - {name: c, position: [0, 1, 0], rotation_rpy_deg: [0, 0, 90]}\n",
            "  - {name: a, position: [0, 0, 0], kind: load_cell}\n"
            "  - {name: b, position: [1, 0, 0], kind: load_cell}\n",
            7,
            "cannot be located with these sensors (2, delivering fz)",
        ),
        (
            "  - {name: a, position: [0, 0, 0]}",
            "  - {name: a, position: [0, 0, 0], kind: cell}",
            4,
            "`kind` in sensor `a` must be one of six_axis, load_cell, three_axis",
        ),
        (
            "  - {name: a, position: [0, 0, 0]}",
            "  - {name: a, position: [0, 0, 0], channels: [fz1, fz2]}",
            4,
            "give its `calibration`, 6 rows",
        ),
        (
            "  - {name: a, position: [0, 0, 0]}",
            "  - {name: a, position: [0, 0, 0], channels: [u, v], calibration: [[1, 0]]}",
            4,
            "must be 6 rows (fx, fy, fz, mx, my, mz) of 2 numbers",
        ),
        (
            "  - {name: a, position: [0, 0, 0]}",
            "  - {name: a, position: [0, 0, 0], kind: load_cell, axes: [fz]}",
            4,
            "give one of `kind`, `axes` or `channels`",
        ),
        (  # (1e300 was read: cos and sin of it, a turn nobody measured)
            "rotation_rpy_deg: [0, 0, 90]}",
            "rotation_rpy_deg: [0, 0, 1e300]}",
            6,
            "must be angles in degrees from -360 to 360, found [0.0, 0.0, 1e+300]",
        ),
        # YAML 1.2 reads `on` as text (PyYAML's 1.1 read it as true): an unknown key
        ("name: bench", "name: bench\non: 1", 2, "unknown key `on`"),
        (
            "    normal: [1, 0, 0]\n    u_axis: [0, 1, 0]\n",
            "    normal: [1, 0, 0]\n",
            14,
            "not horizontal",
        ),
    ],
)
def test_errors_name_file_line_and_what_was_expected(tmp_path, old, new, line, needle):
    assert old in GOOD
    path = write(tmp_path, GOOD.replace(old, new))
    with pytest.raises(ConfigError) as info:
        load_profile(path)
    text = str(info.value)
    assert text.startswith(f"{path}:{line}:"), text
    assert needle in text


def test_missing_field_is_named(tmp_path):
    path = write(tmp_path, GOOD.replace("sample_rate_hz: 1000\n", ""))
    with pytest.raises(ConfigError, match="missing `sample_rate_hz`"):
        load_profile(path)


def test_one_sensor_without_surfaces_is_a_bench_sensor(tmp_path):
    path = write(
        tmp_path, "name: ft\nsample_rate_hz: 500\nsensors: [{name: ft, position: [0, 0, 0]}]\n"
    )
    desk = load_profile(path)
    assert desk.surfaces == () and len(desk.sensors) == 1


def test_unknown_profile_lists_the_shipped_ones():
    with pytest.raises(ConfigError, match="kitamura2017"):
        load_profile("no-such-desk")


def test_estimation_values_are_checked(tmp_path):
    path = write(tmp_path, GOOD + "estimation: {method: magic}\n")
    with pytest.raises(ConfigError, match="force, diff, switched, fused"):
        load_profile(path)
    path = write(tmp_path, GOOD + "estimation: {diff_window_s: -1}\n")
    with pytest.raises(ConfigError, match=r":17:.*must be > 0"):
        load_profile(path)


def _numeric_estimation_keys() -> list[str]:
    from dataclasses import fields

    from hapticdesk.files.profile import EstimationSettings

    return [f.name for f in fields(EstimationSettings) if isinstance(f.default, float)]


@pytest.mark.parametrize("key", _numeric_estimation_keys())
def test_every_estimation_number_has_an_upper_bound(tmp_path, key):
    """The fuzzing pass: `contact_force_n: 1e300` was accepted (no touch could ever start),
    as was any of a dozen settings with no upper bound. Every number in `estimation` now
    has one, refused at its place with the range expected."""
    path = write(tmp_path, GOOD + f"estimation:\n  {key}: 1.0e+300\n")
    with pytest.raises(ConfigError) as info:
        load_profile(path)
    text = str(info.value)
    assert text.startswith(f"{path}:{GOOD.count(chr(10)) + 2}:{len(key) + 5}:"), text
    assert "1e+300" in text
    assert "expected" in text or "below half the sample rate" in text, text


def test_a_force_threshold_says_the_range_it_expects(tmp_path):
    path = write(tmp_path, GOOD + "estimation: {contact_force_n: 1.0e+300}\n")
    with pytest.raises(ConfigError) as info:
        load_profile(path)
    assert str(info.value) == (
        f"{path}:{GOOD.count(chr(10)) + 1}:31: `contact_force_n` in `estimation` must be <= "
        "10000, found 1e+300; expected > 0 and <= 10000"
    )


@pytest.mark.parametrize(
    ("extra", "needle"),
    [
        (
            "accelerometer: {position: [0, 0, 0.7], noise_m_s2: 1.0e+300}",
            "`noise_m_s2` in `accelerometer` must be <= 1000",
        ),
        (
            "accelerometer: {position: [0, 0, 0.7], range_m_s2: 1.0e+300}",
            "`range_m_s2` in `accelerometer` must be <= 1e+06",
        ),
    ],
)
def test_accelerometer_numbers_have_upper_bounds(tmp_path, extra, needle):
    path = write(tmp_path, GOOD + extra + "\n")
    with pytest.raises(ConfigError) as info:
        load_profile(path)
    assert str(info.value).startswith(f"{path}:{GOOD.count(chr(10)) + 1}:")
    assert needle in str(info.value)


@pytest.mark.parametrize(
    ("extra", "needle"),
    [
        ("desk: {natural_frequency_hz: 1.0e-300}", "must be at least 0.5 Hz"),
        ("desk: {natural_frequency_hz: 2999}", "must be below half the sample rate"),
        ("desk: {mass_kg: 1.0e+6}", "must be <= 10000"),
        ("desk: {inertia_kg_m2: [1.0e-308, 1.0e-308, 1.0e-308]}", "1e-06 to 1e+06"),
        ("estimation: {noise_force_n: 1.0e+160}", "must be <= 1000"),
    ],
)
def test_values_no_desk_has_are_refused_where_they_stand(tmp_path, extra, needle):
    """The fuzzing pass: these passed `check` and then failed deep inside (a division by
    zero in the sway model, the simulator's modes, an eigendecomposition) as "an unexpected
    error" with no place. Now the profile says where, and what a desk has."""
    path = write(tmp_path, GOOD + extra + "\n")
    with pytest.raises(ConfigError) as info:
        load_profile(path)
    text = str(info.value)
    assert text.startswith(f"{path}:{GOOD.count(chr(10)) + 1}:"), text  # (the added line)
    assert needle in text


LOAD_CELLS = """\
name: cells
sample_rate_hz: 80
sensors:
  - {name: fl, kind: load_cell, position: [-0.3, -0.2, 0], range: {force_n: 500}}
  - {name: fr, axes: [fz], position: [0.3, -0.2, 0]}
  - {name: bl, channels: [fz], position: [-0.3, 0.2, 0], reports: load}
  - {name: br, kind: three_axis, position: [0.3, 0.2, 0]}
surfaces:
  - name: top
    origin: [0, 0, 0.7]
    normal: [0, 0, 1]
    polygon: [[-0.4, -0.3], [0.4, -0.3], [0.4, 0.3], [-0.4, 0.3]]
"""


def test_load_cells_deliver_fz_and_map_to_fz_mx_my(tmp_path):
    """A load cell's one channel is its F_z: the map's rows of the unseen components are
    zero, and a press's centre of pressure comes out of the seen ones (paper eq. 5 with
    F_x = F_y = 0)."""
    from hapticdesk.files.sensing import sensing_of

    desk = load_profile(write(tmp_path, LOAD_CELLS))
    assert desk.channel_names() == ["fl_fz", "fr_fz", "bl_fz", "br_fx", "br_fy", "br_fz"]
    assert desk.channel_count == 6 and not desk.six_axis_only
    limits = desk.channel_limits()
    assert limits is not None and limits[0] == 500 and np.isinf(limits[1:]).all()
    a = desk.wrench_map()
    assert a.shape == (6, 6)
    # 10 N pressed at (0.1, 0.05): each cell's reaction by the lever rule, summed moments
    x, y, f = 0.1, 0.05, 10.0
    weights = np.array(
        [(0.3 - x) * (0.2 - y), (0.3 + x) * (0.2 - y), (0.3 - x) * (0.2 + y), (0.3 + x) * (0.2 + y)]
    ) / (0.6 * 0.4)
    cells = f * weights
    readings = np.array([cells[0], cells[1], -cells[2], 0.0, 0.0, cells[3]])  # bl reports load
    fo, mo = (a @ readings)[:3], (a @ readings)[3:]
    assert fo == pytest.approx([0, 0, f])
    assert -mo[1] / fo[2] == pytest.approx(x) and mo[0] / fo[2] == pytest.approx(y)
    # one three-axis cell's shear cannot be told from a twist (F_x and M_z share it) ...
    assert sensing_of(desk).seen == ("Fz", "Mx", "My")
    # ... two of them see it all
    two = load_profile(write(tmp_path, LOAD_CELLS.replace("kind: load_cell", "kind: three_axis")))
    assert sensing_of(two).seen == ("Fx", "Fy", "Fz", "Mx", "My", "Mz")
    assert sensing_of(two).shear_seen == {"top": True}
    only_cells = load_profile(
        write(tmp_path, LOAD_CELLS.replace("kind: three_axis", "kind: load_cell"))
    )
    lines = sensing_of(only_cells).lines()
    assert "not Fx, Fy, Mz" in lines[0] and "taken as vertical" in lines[0]
    assert "no shear" in lines[1]


def test_a_calibrated_plate_maps_its_raw_channels(tmp_path):
    """A force plate's amplifier channels through its calibration matrix: one sensor that
    sees all six components locates a touch on its own."""
    plate = """\
name: plate
sample_rate_hz: 1000
sensors:
  - name: plate
    position: [0, 0, 0]
    channels: [a, b, c, d, e, f]
    calibration: [[2, 0, 0, 0, 0, 0], [0, 2, 0, 0, 0, 0], [0, 0, 4, 0, 0, 0],
                  [0, 0, 0, 0.5, 0, 0], [0, 0, 0, 0, 0.5, 0], [0, 0, 0, 0, 0, 0.5]]
    range: {channels: 10}
surfaces:
  - name: top
    origin: [0, 0, 0.05]
    normal: [0, 0, 1]
    polygon: [[-0.2, -0.3], [0.2, -0.3], [0.2, 0.3], [-0.2, 0.3]]
"""
    desk = load_profile(write(tmp_path, plate))
    assert desk.channel_names() == [f"plate_{c}" for c in "abcdef"]
    assert np.allclose(np.diag(desk.wrench_map()), [2, 2, 4, 0.5, 0.5, 0.5])
    assert np.allclose(desk.channel_limits(), 10)


def test_two_six_axis_sensors_locate_a_touch(tmp_path):
    """Two six-axis sensors see the whole wrench: the desk is accepted (it was refused for
    having fewer than three sensors)."""
    two = GOOD.replace("  - {name: c, position: [0, 1, 0], rotation_rpy_deg: [0, 0, 90]}\n", "")
    assert len(load_profile(write(tmp_path, two)).sensors) == 2


def test_a_load_cell_recording_has_one_column_per_cell(tmp_path):
    from hapticdesk.files.recording import Recording
    from hapticdesk.files.recording_io import read_recording, write_recording

    desk = load_profile(write(tmp_path, LOAD_CELLS))
    k = 5
    readings = np.arange(k * 6, dtype=float).reshape(k, 6)
    rec = Recording(np.arange(k) / 80.0, readings, desk.sensor_names, {}, desk.channel_names())
    assert rec.columns()[1:] == desk.channel_names()
    for suffix in (".csv", ".npz"):
        path = tmp_path / f"cells{suffix}"
        write_recording(path, rec)
        back = read_recording(path, desk.sensor_names, channel_names=desk.channel_names())
        assert back.wrench.shape == (k, 6) and np.array_equal(back.channels, readings)
    with pytest.raises(ConfigError, match="missing column"):
        read_recording(tmp_path / "cells.csv", desk.sensor_names)  # six-axis columns expected


def test_a_top_close_to_its_sensors_is_its_own_height():
    """The top's height above the sensors, however close: the balance board's top is 4 cm
    over its cells (it had read 0.7 m, a floor of 5 cm taking it for no top, so its default
    inertia was a 0.7 m tall box and its centre of mass 60 cm above the board); a desk of
    ordinary height reads its own; a profile with no surface keeps the 0.7 m default."""
    from dataclasses import replace

    board = load_profile("balance-board")
    cells_z = np.mean([s.position[2] for s in board.sensors])
    assert board.top_height_m() == pytest.approx(board.surfaces[0].origin[2] - cells_z)
    assert board.top_height_m() == pytest.approx(0.04)
    plain = replace(board, center_of_mass_m=None, inertia_kg_m2=None)
    assert plain.center_of_mass()[2] < board.surfaces[0].origin[2]  # inside the board
    lx, ly = plain.footprint_m()
    ixx = np.diag(plain.inertia_about_com())[0]
    assert ixx == pytest.approx(3.5 / 12 * (ly**2 + 0.04**2))  # a 4 cm plate, not a 0.7 m box
    assert load_profile("kitamura2017").top_height_m() == pytest.approx(0.733)
    cells = load_profile("kitamura2017-loadcells-80hz")  # cells 3 cm under the top
    assert cells.top_height_m() == pytest.approx(0.03)
    assert replace(board, surfaces=()).top_height_m() == pytest.approx(0.7)


@pytest.mark.parametrize(
    ("rate", "gap_s", "flagged"),
    [(1000.0, 0.06, True), (20.0, 0.1, False), (20.0, 0.15, True)],
)
def test_the_gap_follows_the_sample_rate_where_the_profile_does_not_set_it(
    tmp_path, rate, gap_s, flagged
):
    """``max_gap_s`` unset: max(0.05 s, 2.5 sample intervals), so a 1 kHz desk restarts its
    filters after 60 ms without samples and a 20 Hz one (a slow converter, one sample each
    50 ms) does not after 100 ms (two samples missed), but does after 150 ms; given, it
    stands."""
    from hapticdesk.estimator import ContactEstimator
    from hapticdesk.estimator.contacts import FLAG_GAP

    desk = load_profile(write(tmp_path, GOOD.replace("1000", f"{rate:g}")))
    assert desk.estimation.max_gap_s == pytest.approx(max(0.05, 2.5 / rate))
    t = np.arange(int(4 * rate)) / rate
    t[len(t) // 2 :] += gap_s - 1 / rate  # one step of gap_s in the middle
    rng = np.random.default_rng(0)
    channels = rng.normal(0.0, 0.01, (len(t), desk.channel_count)) + 1.0
    flags = ContactEstimator(desk).push(t, channels).flags
    assert bool(flags[len(t) // 2] & FLAG_GAP) == flagged
    assert not (np.delete(flags, len(t) // 2) & FLAG_GAP).any()
    given = GOOD.replace("1000", f"{rate:g}") + "estimation:\n  max_gap_s: 0.05\n"
    assert load_profile(write(tmp_path, given)).estimation.max_gap_s == 0.05


THREE_CELLS = """\
name: cells
sample_rate_hz: 80
sensors:
  - {{name: a, kind: {kind}, position: [-0.34, 0.0, 0.0]}}
  - {{name: b, kind: {kind}, position: [0.34, 0.0, 0.0]}}
  - {{name: c, kind: {kind}, position: [0.0, {off}, 0.0]}}
surfaces:
  - name: top
    origin: [0, 0, 0.7]
    normal: [0, 0, 1]
    polygon: [[-0.4, -0.3], [0.4, -0.3], [0.4, 0.3], [-0.4, 0.3]]
"""


@pytest.mark.parametrize("off_mm", [1, 3, 5, -5])
def test_legs_nearly_on_one_line_are_refused_at_the_leg_off_it(tmp_path, off_mm):
    """The fuzzing pass: load cells 1-5 mm off one line were taken, and a touch beside the
    line was located by moments their forces barely make (a millimetre's error in a leg's
    place moved it by centimetres). Refused at the `position` of the leg off the line."""
    path = write(tmp_path, THREE_CELLS.format(kind="load_cell", off=off_mm / 1000))
    with pytest.raises(ConfigError) as info:
        load_profile(path)
    text = str(info.value)
    assert text.startswith(f"{path}:6:42: the sensors under surface `top` stand nearly on "), text
    assert f"footprint is {abs(off_mm)} mm wide and 0.68 m long" in text
    assert "sensor `c` the farthest off it" in text
    assert "at least 5% of its length (34 mm here)" in text


def test_legs_a_few_percent_off_one_line_and_six_axis_sensors_on_one_are_taken(tmp_path):
    """A triangle of load cells 3.5 cm deep (5 % of its 0.68 m) is a desk; six-axis sensors
    measure the moments themselves, so even two of them on one line locate a touch."""
    load_profile(write(tmp_path, THREE_CELLS.format(kind="load_cell", off=0.035)))
    load_profile(write(tmp_path, THREE_CELLS.format(kind="six_axis", off=0.001)))
    load_profile(write(tmp_path, THREE_CELLS.format(kind="six_axis", off=0.0)))


def test_four_legs_scattered_a_few_mm_about_one_line_are_refused(tmp_path):
    text = THREE_CELLS.format(kind="load_cell", off=0.004).replace(
        "[-0.34, 0.0, 0.0]", "[-0.34, 0.001, 0.0]"
    )
    text = text.replace(
        "surfaces:", "  - {name: d, kind: load_cell, position: [0.2, -0.002, 0]}\nsurfaces:"
    )
    path = write(tmp_path, text)
    with pytest.raises(ConfigError, match=r":6:42: .* footprint is 4.89 mm wide and 0.68 m long"):
        load_profile(path)
