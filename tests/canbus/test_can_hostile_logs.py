"""Hostile CAN logs and databases: a line of any length, a huge or broken database, a signal
that cannot be decoded. Each is a clear error naming the file (and line), found in bounded
memory; the limits are made small here instead of writing gigabytes."""

from __future__ import annotations

import gzip
import re
from pathlib import Path

import pytest

from hapticdesk.canbus import can_database
from hapticdesk.canbus.config_reader import can_config
from hapticdesk.canbus.logs import log_files, python_can_logs
from hapticdesk.canbus.logs.formats import read_frames
from hapticdesk.canbus.logs.writer import write_frames
from hapticdesk.errors import ConfigError

from .can_profiles import error_at, full_can, line_of

LIMIT = 200


def _insert_long_line(path: Path, at: int, gz: bool = False) -> None:
    """Put a line of ``5 * LIMIT`` characters (no frame) in front of line ``at``."""
    lines = path.read_text(encoding="utf-8").splitlines(keepends=True)
    lines.insert(at - 1, "7" * (5 * LIMIT) + "\n")
    text = "".join(lines)
    if gz:
        path.unlink()
        with gzip.open(str(path) + ".gz", "wt", encoding="utf-8") as fh:
            fh.write(text)
    else:
        path.write_text(text, encoding="utf-8")


@pytest.mark.parametrize("suffix", [".log", ".asc", ".trc", ".txt", ".log.gz", ".asc.gz"])
@pytest.mark.parametrize("at", [1, 3])
def test_a_line_too_long_is_refused_at_file_and_line(
    tmp_path, monkeypatch, canopen_traffic, suffix, at
):
    monkeypatch.setattr(log_files, "MAX_LINE_CHARS", LIMIT)
    gz = suffix.endswith(".gz")
    written = tmp_path / f"bus{suffix.removesuffix('.gz')}"
    frames = canopen_traffic(40, 1.0, t0=1_700_000_000.0)
    if written.suffix == ".txt":  # candump's printed text: "  can0  123   [8]  00 11 …"
        rows = []
        for i in range(len(frames)):
            data = " ".join(f"{b:02X}" for b in frames.data[i, : frames.dlc[i]].tolist())
            rows.append(f"  can0  {int(frames.ident[i]):03X}   [{frames.dlc[i]}]  {data}\n")
        written.write_text("".join(rows), encoding="utf-8")
    else:
        write_frames(written, [frames])
    _insert_long_line(written, at, gz)
    path = Path(str(written) + ".gz") if gz else written
    with pytest.raises(ConfigError) as info:
        for _ in read_frames(path):
            pass
    assert str(info.value).startswith(f"{path}:{at}: a line longer than {LIMIT} characters")


def test_a_line_at_the_limit_is_read(tmp_path, monkeypatch):
    line = "(1700000000.000000) can0 123#" + "00" * 8
    monkeypatch.setattr(log_files, "MAX_LINE_CHARS", len(line))
    path = tmp_path / "bus.log"
    path.write_text(f"{line}\r\n{line}\n{line}", encoding="utf-8")
    assert sum(len(chunk) for chunk in read_frames(path)) == 3


def test_sniffing_reads_a_bounded_prefix(tmp_path, monkeypatch):
    """A `.log` of one endless line is not read whole to tell candump -l from printed text."""
    monkeypatch.setattr(python_can_logs, "SNIFF_CHARS", 64)
    path = tmp_path / "one-line.log"
    path.write_text("\0" * 10_000, encoding="utf-8")
    reads: list[int] = []
    real_open = python_can_logs.open_text

    def spy(p):
        fh = real_open(p)
        real_read = fh.read

        def read(size=-1):
            reads.append(size)
            return real_read(size)

        fh.read = read
        return fh

    monkeypatch.setattr(python_can_logs, "open_text", spy)
    assert python_can_logs.looks_canutils(path) is True  # undecided: python-can then names the line
    assert reads == [64]
    path.write_text("  can0  123   [1]  00\n" + "x" * 10_000, encoding="utf-8")
    assert python_can_logs.looks_canutils(path) is False


def test_a_database_too_big_is_refused_before_it_is_parsed(profile_text, monkeypatch):
    monkeypatch.setattr(can_database, "MAX_DATABASE_BYTES", 1000)

    def never(*args, **kwargs):
        raise AssertionError("parsed")

    import cantools

    monkeypatch.setattr(cantools.database, "load_file", never)
    text = full_can()
    line, col, message = error_at(profile_text, text)
    assert (line, col) == (line_of(text, "kitamura2017.dbc"), 13)
    assert "kitamura2017.dbc is" in message and "MiB; at most" in message


def test_a_failure_without_a_message_still_says_why(profile_text, monkeypatch):
    import cantools

    def fails(*args, **kwargs):
        raise cantools.database.UnsupportedDatabaseFormatError(
            None, MemoryError(), None, None, None
        )

    monkeypatch.setattr(cantools.database, "load_file", fails)
    _, _, message = error_at(profile_text, full_can())
    assert 'DBC: "it needs more memory than there is"' in message
    assert '""' not in message


def test_a_signal_of_scale_zero_is_refused(profile_text, tmp_path):
    profile_text(full_can())  # writes the shipped DBC next to the profile
    dbc = tmp_path / "kitamura2017.dbc"
    text = dbc.read_text(encoding="utf-8")
    changed = re.sub(r"(SG_ Fz : 32\|16@1- \()0\.01,", r"\g<1>0,", text, count=1)
    assert changed != text
    dbc.write_text(changed, encoding="utf-8")
    profile = profile_text(full_can())
    with pytest.raises(ConfigError) as info:
        can_config(profile)
    message = str(info.value)
    # the first message with Fz in the DBC is FL_FORCE
    assert f"desk.yaml:{line_of(full_can(), 'fz: FL_FORCE.Fz')}:" in message
    assert "`FL_FORCE.Fz`" in message and "kitamura2017.dbc has scale 0" in message


def test_a_blf_container_that_inflates_past_the_bound_is_refused_after_the_frames_before(
    tmp_path, monkeypatch, canopen_traffic
):
    """A zlib bomb in a BLF log: python-can's reader inflates a container whole (4 MB grew it
    to 4.1 GB); read here, the container stops at the bound and the frames before it go on."""
    import zlib

    from can.io import blf

    monkeypatch.setattr(python_can_logs, "MAX_BLF_CONTAINER_BYTES", 1 << 20)
    path = tmp_path / "bus.blf"
    frames = canopen_traffic(40, 1.0, t0=1_700_000_000.0)
    write_frames(path, [frames])
    good = sum(len(chunk) for chunk in read_frames(path))
    assert good == len(frames)
    bomb = zlib.compress(b"\0" * (8 << 20), 9)  # 8 MiB of zeros in about 8 KiB
    header = blf.LOG_CONTAINER_STRUCT.pack(blf.ZLIB_DEFLATE, 128 * 1024)  # (it lies)
    size = blf.OBJ_HEADER_BASE_STRUCT.size + len(header) + len(bomb)
    obj = blf.OBJ_HEADER_BASE_STRUCT.pack(b"LOBJ", 16, 1, size, blf.LOG_CONTAINER)
    with path.open("ab") as fh:
        fh.write(obj + header + bomb + b"\0" * (size % 4))
    read = 0
    with pytest.raises(ConfigError) as info:
        for chunk in read_frames(path):
            read += len(chunk)
    assert read == good  # nothing read before it is lost
    assert str(info.value) == (
        f"{path}: a log container inflates to more than 1 MiB (a BLF log's hold about "
        "128 KiB): not a CAN log hapticdesk reads"
    )


@pytest.mark.parametrize("suffix", [".asc", ".trc"])
def test_a_frame_whose_bytes_disagree_with_its_dlc_is_skipped_and_named(tmp_path, caplog, suffix):
    # python-can keeps a line's bytes as found: 4 bytes under a DLC of 8 had become a frame of
    # 4 (zeros after), 10 bytes in a .trc one of 10; neither is believed now, and both named
    import can

    from hapticdesk.canbus.frames import FrameArray

    path = tmp_path / f"bus{suffix}"
    sent = [
        can.Message(timestamp=1.0 + i / 1000, arbitration_id=0x181 + i % 4, data=bytes(range(8)))
        for i in range(20)
    ]
    write_frames(path, [FrameArray.from_messages(sent)])
    lines = path.read_text(encoding="utf-8").splitlines()
    eights = [i for i, line in enumerate(lines) if line.rstrip().endswith("04 05 06 07")]
    assert len(eights) == 20
    short, long = eights[3], eights[7]
    lines[short] = lines[short].rstrip()[: -len(" 04 05 06 07")]
    lines[long] = lines[long].rstrip() + " 08 09"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    with caplog.at_level("WARNING", logger="hapticdesk.canbus.logs"):
        read = list(read_frames(path))
    assert all((chunk.dlc == 8).all() for chunk in read)
    if suffix == ".trc":
        assert sum(len(chunk) for chunk in read) == 18
        named = f"2 frame(s) whose data bytes disagree with their DLC were skipped ({path}:"
        assert f"{named}{short + 1}, {path}:{long + 1})" in caplog.text
    else:  # an ASC line may go on after its data (python-can reads the DLC's bytes of it)
        assert sum(len(chunk) for chunk in read) == 19
        named = f"1 frame(s) whose data bytes disagree with their DLC were skipped ({path}:"
        assert f"{named}{short + 1})" in caplog.text


def test_can_fd_frames_whose_dlc_is_a_code_are_kept(tmp_path, caplog):
    # TRC 2.x writes a CAN FD frame's DLC code (9 for 12 bytes, 15 for 64): those frames are
    # whole, not a length that disagrees with their bytes
    data = [bytes(range(n)) for n in (8, 12, 64, 8)]
    rows = [
        f"{i + 1:7d} {i:13.3f} {'FD' if len(d) > 8 else 'DT'} 1     0181 Rx -  "
        f"{ {8: 8, 12: 9, 64: 15}[len(d)]:<4d} {' '.join(f'{b:02X}' for b in d)}"
        for i, d in enumerate(data)
    ]
    path = tmp_path / "fd.trc"
    path.write_text(
        ";$FILEVERSION=2.1\n;$STARTTIME=45000.5\n;$COLUMNS=N,O,T,B,I,d,R,L,D\n;\n"
        + "\n".join(rows)
        + "\n",
        encoding="utf-8",
    )
    with caplog.at_level("WARNING", logger="hapticdesk.canbus.logs"):
        read = list(read_frames(path))
    assert sum(len(chunk) for chunk in read) == 4
    assert "disagree" not in caplog.text
