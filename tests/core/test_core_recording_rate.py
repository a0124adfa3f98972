"""A recording at another rate than its desk profile's, or with its times in milliseconds, is
refused with what was measured and what to do; ``record`` keeps the samples before a bad line.
Before, a millisecond time column turned every sample into a gap (88,000 tare warnings, no
contact) and a 600 Hz recording ran silently through filters made for 1200 Hz."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hapticdesk.cli import main
from hapticdesk.errors import ConfigError
from hapticdesk.files.profile_reader import load_profile
from hapticdesk.files.recording import Recording
from hapticdesk.files.recording_io import read_recording, write_recording
from hapticdesk.plugins.replay import open_replay
from hapticdesk.recordings import check_sample_rate, read_any_recording


@pytest.fixture(scope="module")
def desk():
    return load_profile("kitamura2017")


def quiet(desk, seconds: float = 2.0, interval_s: float | None = None) -> Recording:
    k = int(seconds * desk.sample_rate_hz)
    step = 1.0 / desk.sample_rate_hz if interval_s is None else interval_s
    rng = np.random.default_rng(0)
    wrench = rng.normal(0.0, 0.02, (k, len(desk.sensors), 6))
    wrench[:, :, 2] += 33.0
    return Recording(np.arange(k) * step, wrench, desk.sensor_names)


@pytest.mark.parametrize(
    ("factor", "said"),
    [
        (1e3, "the time column t looks like milliseconds; it must be seconds"),
        (1e6, "the time column t looks like microseconds; it must be seconds"),
        (2.0, "record at 1200 Hz, or give the desk a profile with sample_rate_hz: 600"),
        (0.5, "record at 1200 Hz, or give the desk a profile with sample_rate_hz: 2400"),
    ],
)
def test_a_recording_off_the_profile_rate_is_refused_with_what_to_do(
    desk, tmp_path: Path, capsys, factor: float, said: str
) -> None:
    path = tmp_path / "rec.csv"
    write_recording(path, quiet(desk, interval_s=factor / desk.sample_rate_hz))
    with pytest.raises(ConfigError) as err:
        read_any_recording(path, desk)
    assert err.value.where == str(path)
    assert "but desk 'kitamura2017' samples at 1200 Hz" in err.value.message
    assert err.value.message.endswith(said)
    # through a command: one line, exit 2, nothing estimated
    assert main(["contacts", str(path), "--desk", "kitamura2017", "-o", "-"]) == 2
    out = capsys.readouterr()
    assert out.out == ""
    assert out.err.strip().splitlines() == [
        f"hapticdesk contacts: error: {path}: {err.value.message}"
    ]
    # and a replay refuses it before it runs
    with pytest.raises(ConfigError, match="samples come every"):
        open_replay(str(path), desk, speed=0)


@pytest.mark.parametrize("factor", [0.95, 1.05])
def test_a_clock_a_few_percent_off_and_jittered_times_are_accepted(desk, factor: float) -> None:
    rec = quiet(desk, interval_s=factor / desk.sample_rate_hz)
    jitter = np.random.default_rng(1).uniform(-0.3, 0.3, len(rec.t)) / desk.sample_rate_hz
    t = rec.t + jitter
    t[1000:1200] += 5.0  # a gap: the median does not see it
    check_sample_rate(np.sort(t), desk, "rec.csv")


def test_too_few_samples_say_nothing_about_the_rate(desk) -> None:
    check_sample_rate(np.array([0.0, 1.0, 2.0]), desk, "rec.csv")
    check_sample_rate(np.zeros(0), desk, "rec.csv")


def test_characterize_measures_the_rate_itself(desk, tmp_path: Path) -> None:
    path = tmp_path / "rec.csv"
    write_recording(path, quiet(desk, interval_s=1 / 1000))
    rec = read_any_recording(path, desk, at_profile_rate=False)
    assert len(rec) == 2400


def test_record_keeps_the_samples_before_a_bad_line(desk, tmp_path: Path, capsys) -> None:
    source, output = tmp_path / "rec.csv", tmp_path / "out.csv"
    write_recording(source, quiet(desk, seconds=4.0))
    lines = source.read_text(encoding="utf-8").splitlines()
    bad = 3001  # the file's line number (the header is line 1)
    lines[bad - 1] = lines[bad - 1].replace(",", ",x", 1)
    source.write_text("\n".join(lines) + "\n", encoding="utf-8")
    code = main(
        ["record", "--desk", "kitamura2017", "--source", f"replay:{source}", "-o", str(output)]
    )
    err = capsys.readouterr().err
    assert code == 1
    assert f"stopped at a bad line: {source}:{bad}:" in err
    assert "Traceback" not in err
    kept = read_recording(output, desk.sensor_names)
    # every sample before the bad line
    assert len(kept) == bad - 2
    original = quiet(desk, seconds=4.0)
    np.testing.assert_allclose(kept.wrench, original.wrench[: bad - 2], atol=1e-9)


def test_record_refuses_a_file_bad_from_its_first_sample(desk, tmp_path: Path, capsys) -> None:
    source, output = tmp_path / "rec.csv", tmp_path / "out.csv"
    write_recording(source, quiet(desk))
    lines = source.read_text(encoding="utf-8").splitlines()
    lines[1] = lines[1].replace(",", ",x", 1)
    source.write_text("\n".join(lines) + "\n", encoding="utf-8")
    code = main(
        ["record", "--desk", "kitamura2017", "--source", f"replay:{source}", "-o", str(output)]
    )
    assert code == 2
    assert f"{source}:2:" in capsys.readouterr().err
    assert not output.exists()
