"""Hostile recordings and arguments for `characterize` and `thresholds`: each is a clear
error naming the file (or the flag) and what was expected — no traceback, no numpy warning."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from hapticdesk.analysis.characterize import MAX_READING, characterize
from hapticdesk.analysis.thresholds import MAX_SLOPE_WINDOW_S, derive_thresholds
from hapticdesk.cli import main
from hapticdesk.errors import ConfigError
from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.recording import Recording
from hapticdesk.files.recording_io import write_recording


def quiet_recording(desk: DeskProfile, seconds: float = 2.0, step_s: float | None = None):
    rate = desk.sample_rate_hz
    k = int(seconds * rate)
    t = np.arange(k) * (step_s if step_s is not None else 1.0 / rate)
    rng = np.random.default_rng(0)
    wrench = rng.normal(0.0, 0.02, (k, len(desk.sensors), 6))
    wrench[:, :, 2] += 33.0  # the desk's weight
    return Recording(t, wrench, desk.sensor_names)


def cli_error(capsys, tmp_path, recording: Recording | None, *extra: str, command="characterize"):
    """Run the command on ``recording`` written to CSV; its exit code and its one line."""
    path = tmp_path / "rec.csv"
    if recording is not None:
        write_recording(path, recording)
    code = main([command, str(path), "--desk", "kitamura2017", *extra])
    err = capsys.readouterr().err
    assert "Traceback" not in err and "Warning" not in err, err
    return code, err.strip()


def test_a_header_without_samples(desk, tmp_path, capsys):
    path = tmp_path / "rec.csv"
    write_recording(path, quiet_recording(desk))
    header = path.read_text(encoding="utf-8").splitlines()[0]
    path.write_text(header + "\n", encoding="utf-8")
    code, err = cli_error(capsys, tmp_path, None)
    assert code == 2
    assert err == (
        f"hapticdesk characterize: error: {path}: 0 sample(s): too short, characterize needs "
        "at least 1 s"
    )


@pytest.mark.parametrize(
    ("times", "expected"),
    [
        ("reversed", "no sample time is after the one before it"),
        ("same", "no sample time is after the one before it"),
        # (a time beyond year 9999 is refused where it is read: test_core_recording.py)
        ("huge", "the sample times are 1e+06 s apart (median): 1e-06 Hz; characterize "
         "expects 10 Hz to 100000 Hz (the profile says 1200 Hz; are the times in seconds?)"),
    ],
)  # fmt: skip
def test_unusable_sample_times_name_the_file(desk, tmp_path, capsys, times, expected):
    rec = quiet_recording(desk)
    t = {"reversed": rec.t[::-1], "same": np.zeros_like(rec.t), "huge": rec.t * 1200 * 1e6}
    code, err = cli_error(capsys, tmp_path, Recording(t[times], rec.wrench, rec.sensor_names))
    assert code == 2
    assert err.startswith(f"hapticdesk characterize: error: {tmp_path / 'rec.csv'}: {expected}")


def test_values_beyond_any_sensor_are_left_out_without_warnings(desk, tmp_path, capsys):
    rec = quiet_recording(desk)
    huge = rec.wrench.copy()
    huge[:] = 1e308
    code, err = cli_error(capsys, tmp_path, Recording(rec.t, huge, rec.sensor_names))
    assert code == 2 and "no sample has usable forces and moments" in err
    # some of them: left out, named in a note, no numpy warning either
    some = rec.wrench.copy()
    some[100:160] = 1e308
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        result = characterize(desk, Recording(rec.t, some, rec.sensor_names))
    assert f"60 samples with NaN, inf or a value beyond {MAX_READING:g}" in " ".join(result.notes)


def test_the_where_defaults_to_recording(desk):
    """A caller that has no file (the set-up check of the UI) still gets a clear error."""
    with pytest.raises(ConfigError, match=r"^recording: 1 sample\(s\): too short"):
        characterize(desk, Recording(np.zeros(1), np.zeros((1, 4, 6)), desk.sensor_names))


def test_a_slope_window_past_any_press_is_refused(desk, tmp_path, capsys):
    code, err = cli_error(capsys, tmp_path, None, "--slope-window", "1e300", command="thresholds")
    assert code == 2
    assert err == (
        "hapticdesk thresholds: error: --slope-window: must be at most 10 s (a touch lasts "
        "about half a second), found 1e+300"
    )
    with pytest.raises(ValueError, match="at most 10 s"):
        derive_thresholds(desk, quiet_recording(desk), slope_window_s=MAX_SLOPE_WINDOW_S * 2)
