"""CAN logs: round trips through every format, candump text with and without times, errors."""

from __future__ import annotations

import gzip
import logging

import numpy as np
import pytest

from hapticdesk.canbus.frame_encoder import FrameEncoder
from hapticdesk.canbus.frames import FrameArray
from hapticdesk.canbus.logs.desk_samples import decode_can_log, open_can_log, read_can_log
from hapticdesk.canbus.logs.formats import is_can_log, read_frames
from hapticdesk.canbus.logs.writer import write_frames
from hapticdesk.errors import ConfigError

T0 = 1_700_000_000.0  # logs carry absolute times


def candump_text(frames: FrameArray, style: str, channel: str = "can0") -> str:
    """What candump prints: ``plain`` (no times), ``tz`` (relative), ``ta`` (absolute), ``td``."""
    lines = []
    prev = frames.t[0] if len(frames) else 0.0
    for i in range(len(frames)):
        ident = int(frames.ident[i])
        shown = f"{ident & 0x1FFFFFFF:08X}" if ident & 0x8000_0000 else f"{ident:03X}"
        data = " ".join(f"{b:02X}" for b in frames.data[i, : frames.dlc[i]])
        body = f"{channel}  {shown}   [{frames.dlc[i]}]  {data}".rstrip()
        t = frames.t[i]
        stamp = {
            "plain": "",
            "tz": f"({t - frames.t[0]:010.6f})  ",
            "ta": f"({t:.6f})  ",
            "td": f"({t - prev:010.6f})  ",
        }[style]
        prev = t
        lines.append(f" {stamp}{body}")
    return "\n".join(lines) + "\n"


@pytest.fixture
def dbc_log_frames(dbc_frames, canopen_traffic):
    t, wrench, frames = dbc_frames(700)
    frames.t = frames.t + T0 + np.tile(np.arange(8) * 20e-6, 700)
    both = FrameArray.concat([frames, canopen_traffic(400, t[-1], seed=9, t0=T0)])
    return t, wrench, both.take(np.argsort(both.t, kind="stable"))


@pytest.fixture
def ati_log_frames(ati_desk, make_samples):
    profile, config = ati_desk
    encoder = FrameEncoder(config, profile)
    t, wrench = make_samples(500, 4, seed=3)
    body = encoder.encode(T0 + 0.05 + t, wrench, polls=True)
    # a fast bus: the replies come a little after the polls, in order
    body.t = body.t + np.tile(np.arange(12) * 30e-6, 500)
    frames = FrameArray.concat([encoder.calibration_frames(T0), body])
    return profile, config, t, wrench, frames


@pytest.mark.parametrize("suffix", [".asc", ".blf", ".log", ".trc", ".asc.gz"])
def test_round_trip_dbc_desk(tmp_path, can_desk, dbc_log_frames, suffix, dbc_tolerance):
    t, wrench, frames = dbc_log_frames
    path = tmp_path / f"desk{suffix}"
    assert write_frames(path, [frames]) == len(frames)
    assert is_can_log(path)
    back = FrameArray.concat(list(read_frames(path)))
    np.testing.assert_array_equal(back.ident, frames.ident)
    np.testing.assert_array_equal(back.data, frames.data)
    rec = read_can_log(path, can_desk)
    assert rec.sensor_names == can_desk.sensor_names
    np.testing.assert_allclose(rec.t, t, atol=1e-9)
    assert (np.abs(rec.wrench - wrench) <= dbc_tolerance).all()


@pytest.mark.parametrize("suffix", [".asc", ".blf", ".log", ".trc"])
def test_round_trip_ati_capture_with_its_calibration(tmp_path, ati_log_frames, suffix):
    profile, config, t, wrench, frames = ati_log_frames
    path = tmp_path / f"ati{suffix}"
    write_frames(path, [frames])
    result = decode_can_log(path, profile)
    rec = result.recording
    assert len(rec) == 500 and not np.isnan(rec.wrench).any()
    np.testing.assert_allclose(rec.wrench, wrench, atol=0.1)
    np.testing.assert_allclose(rec.t, t, atol=2e-4)  # the polls' times, to the µs the log keeps
    assert result.stats.requests == 2000 and result.stats.protocol > 0


@pytest.mark.parametrize("style", ["plain", "tz", "ta", "td"])
def test_candump_text(tmp_path, can_desk, dbc_log_frames, style, dbc_tolerance):
    t, wrench, frames = dbc_log_frames
    path = tmp_path / "dump.txt"
    path.write_text(candump_text(frames, style))
    back = FrameArray.concat(list(read_frames(path)))
    np.testing.assert_array_equal(back.data, frames.data)
    if style == "plain":
        assert np.isnan(back.t).all()
    else:
        # candump prints µs; -td's rounded deltas add up over the log
        atol = 1e-4 if style == "td" else 2e-6
        np.testing.assert_allclose(back.t - back.t[0], frames.t - frames.t[0], atol=atol)
    rec = read_can_log(path, can_desk)
    np.testing.assert_allclose(rec.t, t, atol=1e-9)  # by counter: sensor clock either way
    assert (np.abs(rec.wrench - wrench) <= dbc_tolerance).all()


def test_candump_without_times_or_counters_uses_the_sample_rate(
    tmp_path, uncounted_desk, dbc_frames, dbc_tolerance
):
    t, wrench, frames = dbc_frames(300)
    path = tmp_path / "plain.txt"
    path.write_text(candump_text(frames, "plain"))
    rec = read_can_log(path, uncounted_desk)
    np.testing.assert_allclose(rec.t, np.arange(300) / uncounted_desk.sample_rate_hz, atol=1e-12)
    assert (np.abs(rec.wrench - wrench) <= dbc_tolerance).all()


def test_candump_l_file_and_junk_lines(tmp_path, can_desk, dbc_log_frames, caplog, dbc_tolerance):
    t, wrench, frames = dbc_log_frames
    text = candump_text(frames, "ta").splitlines()
    text.insert(5, "this is not a frame")
    text.insert(90, "   (1.5) can0 12X [2] zz")
    path = tmp_path / "dump.candump"
    path.write_text("\n".join(text) + "\n")
    with caplog.at_level(logging.WARNING):
        rec = read_can_log(path, can_desk)
    assert (np.abs(rec.wrench - wrench) <= dbc_tolerance).all()
    assert f"{path}:6" in caplog.text and f"{path}:91" in caplog.text


def test_open_can_log_streams_the_same(tmp_path, can_desk, dbc_log_frames):
    _, _, frames = dbc_log_frames
    path = tmp_path / "desk.blf"
    write_frames(path, [frames])
    whole = read_can_log(path, can_desk)
    with open_can_log(path, can_desk) as source:
        assert source.sensor_names == can_desk.sensor_names
        blocks = list(source.blocks())
    np.testing.assert_array_equal(np.concatenate([b.t for b in blocks]), whole.t)
    np.testing.assert_array_equal(np.concatenate([b.wrench for b in blocks]), whole.wrench)


def test_is_can_log_by_suffix():
    for name in ("a.asc", "a.BLF", "a.log", "a.trc", "a.asc.gz", "a.txt", "a.candump"):
        assert is_can_log(name), name
    for name in ("a.csv", "a.npz", "a.yaml", "a"):
        assert not is_can_log(name), name


def test_unreadable_logs_are_clear_errors(tmp_path, can_desk, ati_log_frames, canopen_traffic):
    with pytest.raises(ConfigError, match="no such CAN log"):
        read_can_log(tmp_path / "missing.asc", can_desk)
    junk = tmp_path / "junk.blf"
    junk.write_bytes(b"\x00\x01garbage" * 50)
    with pytest.raises(ConfigError, match=r"junk\.blf: not a readable \.blf CAN log"):
        read_can_log(junk, can_desk)
    empty = tmp_path / "empty.txt"
    empty.write_text("nothing here\n")
    with pytest.raises(ConfigError, match="no CAN frames found"):
        read_can_log(empty, can_desk)
    other = tmp_path / "other.log"
    write_frames(other, [canopen_traffic(50, 1.0, t0=T0)])
    with pytest.raises(ConfigError, match="no samples of desk `kitamura2017-can`"):
        read_can_log(other, can_desk)
    gz = tmp_path / "broken.asc.gz"
    gz.write_bytes(
        gzip.compress(b"date Mon\nbase hex timestamps absolute\n 0.1 1 200 Rx d 8 zz\n")[:40]
    )
    with pytest.raises(ConfigError):
        read_can_log(gz, can_desk)


def test_ati_capture_without_calibration(tmp_path, ati_log_frames):
    profile, config, t, wrench, frames = ati_log_frames
    no_rows = frames.take(~((frames.ident & 0xF) == 0x2) | (frames.ident > 0x7FF))
    path = tmp_path / "nocal.asc"
    write_frames(path, [no_rows])
    with pytest.raises(
        ConfigError, match=r"ATI sensor `fl` \(base 0x20\): the log lacks matrix row 0"
    ):
        read_can_log(path, profile)


def test_frames_before_a_corrupt_end_are_not_lost(tmp_path, can_desk, dbc_log_frames):
    """The fuzzing pass: a truncated ``.asc.gz`` (its gzip stream cut short) streamed
    nothing of its good lines; the frames read before the error were held in a batch and
    dropped with it. Now they are decoded first, then the error says where."""
    _, _, frames = dbc_log_frames
    whole = tmp_path / "desk.asc.gz"
    write_frames(whole, [frames])
    complete = read_can_log(whole, can_desk)
    cut = tmp_path / "cut.asc.gz"
    data = whole.read_bytes()
    cut.write_bytes(data[: len(data) * 9 // 10])
    got = []
    with pytest.raises(ConfigError, match=r"cut\.asc\.gz"), open_can_log(cut, can_desk) as src:
        for block in src.blocks():
            got.append(block.t)
    decoded = np.concatenate(got) if got else np.zeros(0)
    assert len(decoded) > 0.5 * len(complete.t)  # (about nine tenths; none before)
    np.testing.assert_array_equal(decoded, complete.t[: len(decoded)])


@pytest.mark.parametrize("name", ["blank.log", "blank.txt", "blank.asc"])
def test_a_text_log_of_no_frames_is_refused_after_its_first_lines(tmp_path, can_desk, name):
    """The fuzzing pass: 100 MB of junk lines in a `.log` were read to the end (368 s)
    before "no CAN frames found". Now the first 10,000 lines decide, wherever the file ends."""
    path = tmp_path / name
    path.write_text("x\n" * 200_000)
    with pytest.raises(ConfigError, match=r":10001: no CAN frame in its first 10,000 lines"):
        read_can_log(path, can_desk)
