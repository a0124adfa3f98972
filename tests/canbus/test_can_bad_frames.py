"""Frame lines a log reader cannot use (an identifier wider than CAN's, a time no clock has or
that cannot be read), times a log writer cannot hold, and a bus interface that fails in its
own way: each is skipped and named at file:line, or is a located error, never an unexpected
one."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from hapticdesk.canbus.bus_spec import CanSourceError
from hapticdesk.canbus.frames import FrameArray
from hapticdesk.canbus.logs.desk_samples import decode_can_log
from hapticdesk.canbus.logs.formats import read_frames
from hapticdesk.canbus.logs.writer import write_frames
from hapticdesk.canbus.source import open_can_source
from hapticdesk.cli import main
from hapticdesk.errors import ConfigError
from hapticdesk.files.recording import Recording
from hapticdesk.files.recording_io import write_recording

ASC_HEAD = "date Tue Nov 24 12:37:15.59 2026\nbase hex  timestamps absolute\nBegin Triggerblock\n"
ASC_ROW = " {t} 1  {ident}    Rx   d 8 F1 FF 00 00 2F 0D 00 00\n"
TRC_HEAD = ";$FILEVERSION=2.1\n;$STARTTIME=45000.5\n;$COLUMNS=N,O,T,B,I,d,R,L,D\n;\n"
TRC_ROW = "{n:7d} {t:>13} DT 1 {ident:>8} Rx -  8    F1 FF 00 00 2F 0D 00 00\n"
TXT_ROW = "({t})  can0  {ident}   [8]  F1 FF 00 00 2F 0D 00 00\n"


def _log(path, rows: list[str]) -> None:
    """A text log of ``rows`` (frame lines) in the format of ``path``'s suffix."""
    head = {".asc": ASC_HEAD, ".trc": TRC_HEAD}.get(path.suffix, "")
    tail = "End TriggerBlock\n" if path.suffix == ".asc" else ""
    path.write_text(head + "".join(rows) + tail, encoding="utf-8")


def _row(suffix: str, i: int, ident: str, t: str | None = None) -> str:
    if suffix == ".asc":
        return ASC_ROW.format(t=t or f"{i / 1000:.6f}", ident=ident)
    if suffix == ".trc":
        return TRC_ROW.format(n=i + 1, t=t or f"{i:.3f}", ident=ident.rjust(4, "0"))
    return TXT_ROW.format(t=t or f"{1_700_000_000 + i / 1000:.6f}", ident=ident)


def _read(path) -> int:
    return sum(len(chunk) for chunk in read_frames(path))


@pytest.mark.parametrize("suffix", [".asc", ".trc", ".txt"])
@pytest.mark.parametrize("ident", ["FFFFFFFFFFFF", "100000000000", "40000000x", "800"])
def test_an_identifier_wider_than_can_s_is_skipped_and_named(tmp_path, caplog, suffix, ident):
    # it reached numpy's uint32 and ended the read ("Python integer 281474976710655 out of
    # bounds for uint32", an unexpected OverflowError); the .log reader already skipped it
    if ident.endswith("x") and suffix != ".asc":
        ident = ident[:-1]  # an extended id: "x" is .asc's mark; the others tell by width
    if suffix == ".txt":  # without candump's error flag (bit 29): cantools skips those as no frame
        ident = f"{int(ident.rstrip('x'), 16) & ~0x2000_0000:X}".rjust(3, "0")
    path = tmp_path / f"bus{suffix}"
    rows = [_row(suffix, i, "110") for i in range(5)]
    rows.insert(2, _row(suffix, 9, ident))
    _log(path, rows)
    first = {".asc": 4, ".trc": 5, ".txt": 1}[suffix]
    with caplog.at_level("WARNING", logger="hapticdesk.canbus.logs"):
        assert _read(path) == 5
    assert (
        "1 frame(s) whose identifier is out of range (up to 0x1FFFFFFF extended, 0x7FF "
        f"standard) were skipped ({path}:{first + 2})"
    ) in caplog.text


def test_the_auditors_wide_identifier_is_a_located_error(tmp_path, capsys):
    path = tmp_path / "id48.asc"
    _log(path, [ASC_ROW.format(t="0.000000", ident="FFFFFFFFFFFF")])
    assert main(["contacts", "--desk", "kitamura2017-can", str(path)]) == 2
    err = capsys.readouterr().err
    assert "unexpected" not in err and f"{path}: no CAN frames found" in err


@pytest.mark.parametrize(
    ("stamp", "why"),
    [
        ("2020-13-45 10:00:00.000000", "does not match format"),
        ("0000-01-01 10:00:00.000000", "year 0 is out of range"),
        ("99999999999999999999.000000", "out of range"),
        ("9999999999999.000000", "out of range"),
    ],
)
def test_candump_text_lines_whose_time_cannot_be_read_are_skipped_and_named(
    tmp_path, caplog, stamp, why
):
    # cantools raised out of its line loop (ValueError, OverflowError): the whole read ended
    # as an unexpected error with no line named
    absolute = "-" in stamp  # -tA: the good lines must be of the same kind
    rows = [
        TXT_ROW.format(t=f"2020-12-19 12:04:45.{i:06d}" if absolute else f"{i}.000000", ident="110")
        for i in range(4)
    ]
    rows.insert(1, TXT_ROW.format(t=stamp, ident="110"))
    path = tmp_path / "bus.txt"
    _log(path, rows)
    with caplog.at_level("WARNING", logger="hapticdesk.canbus.logs"):
        assert _read(path) == 4
    assert f"1 frame line(s) that cannot be read were skipped ({path}:2): " in caplog.text
    assert why in caplog.text


@pytest.mark.parametrize("suffix", [".asc", ".blf", ".trc", ".log"])
@pytest.mark.parametrize("t0", [3e11, 1e300, -1.0])
def test_times_a_log_cannot_hold_are_refused_before_writing(tmp_path, suffix, t0):
    # python-can failed on them ("year 11533 is out of range", OverflowError), or (.log)
    # wrote times that all read back as one
    path = tmp_path / f"out{suffix}"
    frames = FrameArray.build(t0 + np.arange(3) / 1000, 0x110, [bytes(8)] * 3)
    with pytest.raises(ConfigError) as info:
        write_frames(path, [FrameArray.build([0.5], 0x110, [bytes(8)]), frames])
    assert str(info.value).startswith(
        f"{path}: cannot write a frame at {t0:.6g} s: a {suffix} CAN log's times are seconds "
        "since 1970 from 0 to 253402214400 (year 9999)"
    )
    assert not path.exists()
    # frames coming as they are read: the ones before are not left in a log cut short
    with pytest.raises(ConfigError):
        write_frames(path, iter([FrameArray.build([0.5], 0x110, [bytes(8)]), frames]))
    assert not path.exists()


def test_recording_far_in_the_future_as_a_can_log_is_a_located_error(
    tmp_path, capsys, can_desk, make_samples
):
    t, wrench = make_samples(12, 4)
    source = tmp_path / "far.npz"
    write_recording(source, Recording(t + 3e11, wrench, can_desk.sensor_names))
    out = tmp_path / "out.asc"
    argv = ["record", "--source", f"replay:{source}", "--desk", "kitamura2017-can", "-o"]
    assert main([*argv, str(out)]) == 2
    err = capsys.readouterr().err
    assert "unexpected" not in err and len(err.strip().splitlines()) == 1
    # beyond year 9999 the recording itself is refused, at its row (as a CSV's at its cell)
    assert f"{source}: `t` is 3e+11 in row 1; every sample needs" in err and not out.exists()
    # a time a recording may hold, but not a CAN log once it starts now (record dates the
    # frames from the wall clock): the log's writer refuses it
    write_recording(source, Recording(t + 2.53e11, wrench, can_desk.sensor_names))
    assert main([*argv, str(out)]) == 2
    err = capsys.readouterr().err
    assert "unexpected" not in err and len(err.strip().splitlines()) == 1
    assert f"{out}: cannot write a frame at 2.5" in err and not out.exists()


@pytest.mark.parametrize("error", [NameError("name 'canGetNumberOfChannels' is not defined")])
def test_any_failure_of_an_interface_to_open_is_a_clean_error(can_desk, error):
    # python-can's kvaser interface without its library raises NameError: it was an
    # unexpected error, where some 20 other interfaces were a clean one
    def factory(**kwargs):
        raise error

    with pytest.raises(CanSourceError) as info:
        open_can_source("can:kvaser:0", can_desk, bus_factory=factory)
    assert str(info.value) == (
        "can:kvaser:0: cannot open CAN interface 'kvaser' channel '0': python-can failed with "
        "NameError: name 'canGetNumberOfChannels' is not defined (is the interface's driver "
        "library installed?)"
    )


@pytest.mark.parametrize("bad", ["-0.000000", "nan", "1e20", "-5.000000"])
def test_asc_frame_lines_whose_time_cannot_be_read_are_counted_and_named(tmp_path, caplog, bad):
    # python-can skips them without a word: 2000 such lines read as one frame, said nowhere
    path = tmp_path / "bus.asc"
    rows = [ASC_ROW.format(t="0.000000", ident="110")]
    rows += [ASC_ROW.format(t=bad, ident="110") for _ in range(1999)]
    _log(path, rows)
    with caplog.at_level("WARNING", logger="hapticdesk.canbus.logs"):
        assert _read(path) == 1
    assert (
        "1999 frame(s) whose time cannot be read or is out of range (expected seconds within "
        f"±253402214400 of 1970, up to year 9999) were skipped ({path}:5, {path}:6, {path}:7 …)"
    ) in caplog.text


def test_a_header_only_asc_has_no_frames(tmp_path):
    path = tmp_path / "bus.asc"
    _log(path, [" 0.000000 Start of measurement\n"])
    with pytest.raises(ConfigError, match="no CAN frames found"):
        _read(path)


@pytest.mark.parametrize(
    ("suffix", "far"), [(".asc", "100000000000000000000.000000"), (".trc", "1e300")]
)
def test_frames_at_times_no_clock_has_are_skipped_without_a_numpy_warning(
    tmp_path, caplog, can_desk, dbc_frames, suffix, far
):
    # their gap to the frames before overflowed the assembler's int64 sample counts: numpy's
    # "invalid value encountered in cast" reached the user
    _, _, frames = dbc_frames(24)
    path = tmp_path / f"bus{suffix}"
    write_frames(path, [frames])
    lines = path.read_text(encoding="utf-8").splitlines(keepends=True)
    rows = [i for i, line in enumerate(lines) if " Rx " in line]
    half = rows[len(rows) // 2 :]
    for i in half:
        words = lines[i].split(None, 2)
        if suffix == ".asc":
            lines[i] = f" {far} {words[1]} {words[2]}"
        else:
            lines[i] = f"{words[0]:>7} {far:>13} {words[2]}"
    path.write_text("".join(lines), encoding="utf-8")
    with caplog.at_level("WARNING", logger="hapticdesk.canbus.logs"), warnings.catch_warnings():
        warnings.simplefilter("error")
        decoded = decode_can_log(path, can_desk)
    assert decoded.stats.frames == len(rows) - len(half)
    assert (
        f"{len(half)} frame(s) whose time cannot be read or is out of range (expected seconds "
        f"within ±253402214400 of 1970, up to year 9999) were skipped ({path}:{half[0] + 1}, "
    ) in caplog.text


@pytest.mark.parametrize("command", ["emulate", "record"])
def test_the_real_kvaser_interface_without_its_library_is_a_clean_error(command, tmp_path, capsys):
    """python-can's kvaser, here without Kvaser's canlib, fails with its own NameError (or, once
    python-can mends it, a CanError): either way one line, exit 2."""
    scene = tmp_path / "s.yaml"
    scene.write_text("desk: kitamura2017-can\ntimeline:\n  - idle: 0.2\n")
    argv = {
        "emulate": ["emulate", "--desk", "kitamura2017-can", "--scene", str(scene)]
        + ["--bus", "kvaser:0", "--speed", "0"],
        "record": ["record", "--source", "can:kvaser:0", "--desk", "kitamura2017-can"]
        + ["-o", str(tmp_path / "r.csv"), "--seconds", "1"],
    }[command]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "cannot open CAN interface 'kvaser' channel '0'" in err and "unexpected" not in err


@pytest.mark.parametrize("suffix", [".asc", ".trc"])
def test_a_line_that_is_not_text_is_named_at_its_line(tmp_path, suffix):
    """The decoder fails for a whole buffer: the line said had been 0, or the buffer's first."""
    path = tmp_path / f"junk{suffix}"
    head = {".asc": ASC_HEAD, ".trc": TRC_HEAD}[suffix].encode()
    path.write_bytes(head + b"\xff junk\n")
    line = head.count(b"\n") + 1
    with pytest.raises(
        ConfigError,
        match=rf"junk\{suffix}:{line}: not a readable \{suffix} CAN log: the line "
        r"is not UTF-8 text \(byte 0xff: invalid start byte\)",
    ):
        list(read_frames(path))
