"""Desk profiles: the shipped paper desk and errors that name file, line and column."""

from pathlib import Path

import numpy as np
import pytest

from hapticdesk.files.profile import load_profile, rotation_matrix
from hapticdesk.files.yamlfile import ConfigError

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
            "  - {name: c, position: [0, 1, 0], rotation_rpy_deg: [0, 0, 90]}\n",
            "",
            4,
            "3 or more sensors",
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
