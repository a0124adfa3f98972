"""CAN logs: read them as frames or as a desk's samples, and write them.

Read: python-can's formats (``.asc`` Vector ASCII, ``.blf`` Vector binary, ``.trc`` PEAK
trace, ``.log`` candump ``-l`` files, each also ``.gz``) and candump's printed text through
cantools' log reader (``candump can0`` without times, ``-tz``/``-td`` relative, ``-ta``/``-tA``
absolute; any suffix other than the above, e.g. ``.txt``, ``.candump``). A log without times
gets them from the profile's sample rate. Write: python-can's ``Logger`` by suffix.

Every command that reads a recording reads these through :func:`read_can_log` (a
:class:`~hapticdesk.files.recording.Recording`) or :func:`open_can_log` (a finite
:class:`~hapticdesk.runtime.source.Source`).
"""

from __future__ import annotations

import logging
import re
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hapticdesk.canbus.assembler import AssembledBlock, FrameAssembler
from hapticdesk.canbus.ati_netcanoem import AtiCalibration, CalibrationCollector, ati_frame_ids
from hapticdesk.canbus.config import CanConfig, can_config
from hapticdesk.canbus.decoding import build_decoding
from hapticdesk.canbus.frames import FrameArray
from hapticdesk.canbus.stats import CanNotice, CanStats
from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.recording import Recording
from hapticdesk.files.yamlfile import ConfigError
from hapticdesk.runtime.source import Source, WrenchBlock

log = logging.getLogger("hapticdesk.canbus.logs")

PYTHON_CAN_SUFFIXES = (".asc", ".blf", ".log", ".trc")
WRITE_SUFFIXES = PYTHON_CAN_SUFFIXES
CANDUMP_TEXT_SUFFIXES = (".txt", ".candump", ".dump")
CHUNK_FRAMES = 50_000
#: the longest line a text log may have: a CAN FD frame of 64 bytes is under 400 characters in
#: every format read here, so a longer line is not a frame (a corrupt or hostile file would
#: otherwise be read whole into memory as one line)
MAX_LINE_CHARS = 4096
#: a text log whose first this many lines hold no frame is no CAN log (headers and comments
#: are a few dozen lines)
MAX_LINES_BEFORE_A_FRAME = 10_000
#: the most one BLF log container may inflate to: python-can writes containers of 128 KiB and
#: Vector's tools like ones, so a container inflating further is no log but a zlib bomb (one
#: of 4 MB grew python-can's reader to 4.1 GB before this bound)
MAX_BLF_CONTAINER_BYTES = 64 * 1024 * 1024
#: how much of a ``.log`` file is looked at to tell candump ``-l`` from candump's printed text
SNIFF_CHARS = 65_536
#: the widest identifiers CAN has (python-can's own ``Message`` check): 29 bits for an extended
#: frame, 11 for a standard one; the readers take any number (an ``.asc`` line of 12 hex digits
#: reached numpy's uint32 and ended the read with an OverflowError)
MAX_EXTENDED_ID = 0x1FFF_FFFF
MAX_STANDARD_ID = 0x7FF
#: the latest time a CAN log holds, in seconds since 1970: 9999-12-31 00:00 UTC (a day short
#: of the last date Python has, for the local time zone). python-can's .asc, .blf and .trc
#: writers date a log by its first frame, so a later one cannot be written; read, a time beyond
#: it (either way) is no clock's, and its gaps overflowed the assembler's integer sample counts
MAX_LOG_TIME_S = 253_402_214_400.0
#: in a log assembled by counter, a channel whose frame is missing holds its value this many
#: samples at most (:attr:`FrameAssembler.hold_samples`): a corrupt line loses one frame, not
#: the sample
HOLD_SAMPLES = 2
# candump -l / python-can .log lines: "(1700000000.000000) can0 123#DEADBEEF"
_CANUTILS_LINE = re.compile(r"^\s*\(\d+(\.\d+)?\)\s+\S+\s+[0-9A-Fa-f]+#")
# ... and all of one, as python-can's reader parses it without raising: an optional CAN FD
# flag digit, hex byte pairs or a remote request ``R``/``R8``, an optional direction
_CANUTILS_FRAME = re.compile(
    r"^\s*\(\d+(\.\d+)?\)\s+\S+\s+[0-9A-Fa-f]{1,8}#(#[0-9A-Fa-f])?"
    r"([Rr]\d?|([0-9A-Fa-f]{2})*)(\s+[RTrt])?\s*$"
)
# an .asc frame line whatever its time: python-can's ASC_MESSAGE_REGEX with any first word for
# the time (python-can skips a line whose time is not digits.digits, e.g. "-0.000000" or "nan",
# without a word; those lines are counted and named)
_ASC_FRAME_LIKE = re.compile(
    r"\s*\S+\s+(\d+\s+(\w+\s+(Tx|Rx)|ErrorFrame)|CANFD)", re.ASCII | re.IGNORECASE
)


def _suffix(path: str | Path) -> str:
    suffixes = [s.lower() for s in Path(path).suffixes]
    if suffixes and suffixes[-1] == ".gz":
        suffixes = suffixes[:-1]
    return suffixes[-1] if suffixes else ""


def is_can_log(path: str | Path) -> bool:
    """True when ``path``'s suffix is a CAN log format this module reads."""
    return _suffix(path) in PYTHON_CAN_SUFFIXES + CANDUMP_TEXT_SUFFIXES


# --- frames -----------------------------------------------------------------------------------


def read_frames(
    path: str | Path, chunk_frames: int = CHUNK_FRAMES, skipped: dict[str, int] | None = None
) -> Iterator[FrameArray]:
    """The log's frames in chunks, in file order. ConfigError when it cannot be read.
    ``skipped``: filled with what was skipped, by reason, as the log is read (a run's
    summary says it: a log of 5 % junk lines had been "silently nothing")."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError(str(path), "no such CAN log")
    suffix = _suffix(path)
    any_frame = False
    if suffix in (".asc", ".blf", ".trc") or (suffix == ".log" and _looks_canutils(path)):
        chunks = _python_can_frames(path, chunk_frames, skipped)
    else:
        chunks = _candump_text_frames(path, chunk_frames, skipped)
    for chunk in chunks:
        any_frame = any_frame or len(chunk) > 0
        yield chunk
    if not any_frame:
        raise ConfigError(
            str(path),
            "no CAN frames found; expected a python-can log (.asc, .blf, .log, .trc) or "
            "candump output (`candump can0`, `-tz`, `-ta`, `-l`)",
        )


def _looks_canutils(path: Path) -> bool:
    """Whether the first line with text in the file's first :data:`SNIFF_CHARS` characters is
    a candump ``-l`` frame (a bounded read: a file of one endless line is not read whole)."""
    try:
        with _open_text(path) as fh:
            head = fh.read(SNIFF_CHARS)
    except (OSError, EOFError, UnicodeDecodeError):
        return True  # let python-can report what is wrong
    lines = head.splitlines()
    if len(head) == SNIFF_CHARS and lines:
        lines.pop()  # cut short by the bound: not a whole line
    for line in lines:
        if line.strip():
            return bool(_CANUTILS_LINE.match(line))
    return True


def _open_text(path: Path) -> Any:
    if path.suffix.lower() == ".gz":
        import gzip

        return gzip.open(path, "rt", encoding="utf-8", errors="replace")
    return path.open(encoding="utf-8", errors="replace")


def _first_undecodable_line(path: Path) -> int:
    """The number of the first line of ``path`` that is not UTF-8 (0: none found)."""
    import gzip

    opener: Any = gzip.open if path.suffix.lower() == ".gz" else open
    with opener(path, "rb") as fh:
        number = 0
        while raw := fh.readline(MAX_LINE_CHARS + 2):
            number += 1
            try:
                raw.decode("utf-8")
            except UnicodeDecodeError:
                return number
    return 0


_READERS = {
    ".asc": "ASCReader",
    ".blf": "BLFReader",
    ".trc": "TRCReader",
    ".log": "CanutilsLogReader",
}


def _python_can_frames(
    path: Path, chunk_frames: int, tally: dict[str, int] | None = None
) -> Iterator[FrameArray]:
    import gzip

    import can  # lazily: only CAN paths need python-can

    fmt = _suffix(path)
    mode = "rb" if fmt == ".blf" else "rt"
    batch: list[Any] = []
    failure: ConfigError | None = None
    text: _BoundedLines | None = None  # (None also when opening the file fails)
    lines: _CanutilsLines | None = None
    mismatched = _Skipped("frame(s) whose data bytes disagree with their DLC were")
    bad_ids = _Skipped(_BAD_ID)
    bad_times = _Skipped(_BAD_TIME)
    try:
        # we open the file so that it is closed whatever the reader raises
        opener = gzip.open if path.suffix.lower() == ".gz" else open
        with opener(path, mode) as fh:
            text = _BoundedLines(fh, path) if fmt != ".blf" else None
            if text is not None and fmt == ".asc":
                text.unread = (_ASC_FRAME_LIKE, bad_times)
            lines = _CanutilsLines(text) if fmt == ".log" and text is not None else None
            source = lines if lines is not None else text if text is not None else fh
            messages = (
                _blf_messages(fh, path) if fmt == ".blf" else getattr(can, _READERS[fmt])(source)
            )
            for msg in messages:
                number = text.frame_read() if text is not None else None
                if not _ident_fits(msg.arbitration_id, msg.is_extended_id):
                    bad_ids.add(number)
                    continue
                if not abs(msg.timestamp) <= MAX_LOG_TIME_S:  # (NaN too)
                    bad_times.add(number)
                    continue
                if text is not None:
                    if not (_dlc_holds(msg) or msg.is_remote_frame or msg.is_error_frame):
                        # a line whose data bytes disagree with its DLC (cut short, or bytes
                        # too many): which of the two is wrong cannot be told, so neither is
                        # believed (python-can kept the bytes as found and said nothing)
                        mismatched.add(number)
                        continue
                batch.append(msg)
                if len(batch) >= chunk_frames:
                    yield FrameArray.from_messages(batch)
                    batch = []
    except ConfigError as err:  # a line too long: already says where
        failure = err
    except (ValueError, OSError, EOFError, KeyError, IndexError, can.CanError) as err:
        number = text.number if text is not None else 0
        why = str(err)
        if isinstance(err, UnicodeDecodeError):  # raised for a whole buffer, lines ahead
            number = _first_undecodable_line(path)
            why = f"the line is not UTF-8 text (byte 0x{err.object[err.start]:02x}: {err.reason})"
        where = f"{path}:{number}" if number else str(path)
        failure = ConfigError(where, f"not a readable {fmt} CAN log: {why}")
    except MemoryError:
        where = f"{path}:{text.number}" if text is not None else str(path)
        failure = ConfigError(
            where, f"not a readable {fmt} CAN log: it needs more memory than there is"
        )
    except Exception as err:  # BLF and gzip readers raise their own kinds on corrupt files
        failure = ConfigError(str(path), f"not a readable {fmt} CAN log: {err!r}")
    # the frames read before a failure go on first: nothing already read is lost (a corrupt
    # block near the end of a BLF file dropped every frame before it)
    if batch:
        yield FrameArray.from_messages(batch)
    if failure is None and text is not None:
        text.frame_read(end=True)  # the last line may have been a frame line python-can skipped
    for skipped in (mismatched, bad_ids, bad_times):
        skipped.warn(path, tally)
    if failure is not None:
        raise failure
    if lines is not None:
        lines.skipped.warn(path, tally)


_BAD_ID = (
    f"frame(s) whose identifier is out of range (up to 0x{MAX_EXTENDED_ID:X} extended, "
    f"0x{MAX_STANDARD_ID:X} standard) were"
)
_BAD_TIME = (
    f"frame(s) whose time cannot be read or is out of range (expected seconds within "
    f"±{MAX_LOG_TIME_S:.0f} of 1970, up to year 9999) were"
)


def _ident_fits(ident: int, extended: bool) -> bool:
    return 0 <= ident <= (MAX_EXTENDED_ID if extended else MAX_STANDARD_ID)


class _Skipped:
    """Frames or lines skipped for one reason: how many, the first few lines (for the
    warning), the first reason given."""

    def __init__(self, what: str) -> None:
        self.what = what  # "<what> skipped (file:line, …)"
        self.lines: list[int] = []
        self.n = 0
        self.why: str | None = None

    def add(self, number: int | None, why: str | None = None) -> None:
        self.n += 1
        if number is not None and len(self.lines) < 3:
            self.lines.append(number)
        if self.why is None:
            self.why = why

    def warn(self, path: Path, tally: dict[str, int] | None = None) -> None:
        if not self.n:
            return
        if tally is not None:
            tally[self.what] = tally.get(self.what, 0) + self.n
        shown = ", ".join(f"{path}:{number}" for number in self.lines) or str(path)
        more = " …" if self.lines and self.n > len(self.lines) else ""
        why = f": {self.why}" if self.why else ""
        log.warning("%d %s skipped (%s%s)%s", self.n, self.what, shown, more, why)


def _dlc_holds(msg: Any) -> bool:
    """A message's data bytes are what its DLC says: a classic frame's DLC is its length; a
    CAN FD frame's is its length or (TRC 2.x) the DLC code of it (9 for 12 bytes … 15 for
    64)."""
    from can.util import dlc2len

    n = len(msg.data)
    return bool(n == msg.dlc or (msg.is_fd and n == dlc2len(msg.dlc)))


def _blf_messages(fh: Any, path: Path) -> Iterator[Any]:
    """python-can's BLF reading with each log container inflated within
    :data:`MAX_BLF_CONTAINER_BYTES` (its own reader inflates a container whole, however
    large): its loop over the objects, with python-can's container parser."""
    import zlib

    from can.io import blf

    reader = blf.BLFReader(fh)
    head = blf.OBJ_HEADER_BASE_STRUCT
    while data := reader.file.read(head.size):
        if len(data) < head.size:
            raise blf.BLFParseError("the file ends inside an object's header")
        signature, _, _, obj_size, obj_type = head.unpack(data)
        if signature != b"LOBJ" or obj_size < head.size:
            raise blf.BLFParseError("an object without its LOBJ header")
        obj_data = reader.file.read(obj_size - head.size)
        reader.file.read(obj_size % 4)  # padding
        if obj_type != blf.LOG_CONTAINER:
            continue
        method, _ = blf.LOG_CONTAINER_STRUCT.unpack_from(obj_data)
        container = obj_data[blf.LOG_CONTAINER_STRUCT.size :]
        if method == blf.ZLIB_DEFLATE:
            inflater = zlib.decompressobj()
            container = inflater.decompress(container, MAX_BLF_CONTAINER_BYTES)
            if inflater.unconsumed_tail:
                raise ConfigError(
                    str(path),
                    f"a log container inflates to more than {MAX_BLF_CONTAINER_BYTES >> 20} MiB "
                    "(a BLF log's hold about 128 KiB): not a CAN log hapticdesk reads",
                )
        elif method != blf.NO_COMPRESSION:
            log.warning("%s: a log container of unknown compression %d skipped", path, method)
            continue
        yield from reader._parse_container(container)


class _BoundedLines:
    """A text log's lines, each read with a bounded length: a line longer than
    :data:`MAX_LINE_CHARS` is a ConfigError at ``file:line`` instead of the whole file read
    into memory. Iterates (python-can's readers) and has ``readline`` (cantools' parser);
    ``number`` is the line last read, for errors."""

    def __init__(self, fh: Any, path: Path) -> None:
        self._fh = fh
        self._path = path
        self.number = 0
        self.framed = False  # a frame was read (set by the reader's loop)
        # lines that look like frames, and where those the reader made no frame of are counted
        self.unread: tuple[re.Pattern[str], _Skipped] | None = None
        self._pending = 0  # the line last read, when it looks like a frame and none came of it

    def __iter__(self) -> Iterator[str]:
        return self

    def __next__(self) -> str:
        line = self.readline()
        if not line:
            raise StopIteration
        return line

    def frame_read(self, end: bool = False) -> int:
        """The reader made a frame of the line last read (or, ``end``, it read no more): its
        number. A frame-like line before it that gave no frame is counted in ``unread``."""
        if self._pending and end and self.unread is not None:
            self.unread[1].add(self._pending)
        if not end:
            self.framed = True
        self._pending = 0
        return self.number

    def readline(self) -> str:
        limit = MAX_LINE_CHARS
        if self._pending and self.unread is not None:  # the reader moved on without a frame
            self.unread[1].add(self._pending)
            self._pending = 0
        line: str = self._fh.readline(limit + 2)  # room for the line end ("\r\n")
        if not line:
            return line
        self.number += 1
        if self.unread is not None and self.unread[0].match(line):
            self._pending = self.number
        if self.number > MAX_LINES_BEFORE_A_FRAME and not self.framed:
            # (a file of blank or junk lines was read to its end, minutes for 100 MB, before
            # it said "no CAN frames found")
            raise ConfigError(
                f"{self._path}:{self.number}",
                f"no CAN frame in its first {MAX_LINES_BEFORE_A_FRAME:,} lines: is this a CAN log?",
            )
        if len(line.rstrip("\r\n")) > limit:
            raise ConfigError(
                f"{self._path}:{self.number}",
                f"a line longer than {limit} characters; a CAN log line (a frame, a header "
                "or a comment) is a few hundred at most: is this a CAN log?",
            )
        return line

    def close(self) -> None:
        """python-can closes its file when done; ours is closed by its ``with``."""


class _CanutilsLines:
    """The lines of a candump ``-l`` file that are frames; the others are skipped and counted
    (python-can's reader raises on the first junk line, which would end a replay with no line
    number). The lines come from :class:`_BoundedLines`, which numbers them."""

    def __init__(self, lines: _BoundedLines) -> None:
        self._lines = lines
        self.skipped = _Skipped(_NOT_FRAMES)

    def __iter__(self) -> Iterator[str]:
        for line in self._lines:
            if _CANUTILS_FRAME.match(line):
                yield line
            elif line.strip() and not line.lstrip().startswith(("#", ";")):
                self.skipped.add(self._lines.number)

    def close(self) -> None:
        """python-can closes its file when done; ours is closed by its ``with``."""


_NOT_FRAMES = "line(s) are not CAN frames and were"


def _candump_text_frames(
    path: Path, chunk_frames: int, tally: dict[str, int] | None = None
) -> Iterator[FrameArray]:
    import datetime

    from cantools.logreader import Parser

    deltas: bool | None = None  # candump -td prints the time since the previous frame
    clock = 0.0
    unknown = _Skipped(_NOT_FRAMES)
    unreadable = _Skipped("frame line(s) that cannot be read were")
    bad_ids = _Skipped(_BAD_ID)
    bad_times = _Skipped(_BAD_TIME)
    t: list[float] = []
    idents: list[int] = []
    exts: list[bool] = []
    datas: list[bytes] = []
    remote: list[bool] = []

    def chunk() -> FrameArray:
        nonlocal deltas, clock
        times = np.array(t, dtype=float)
        if deltas is None and np.isfinite(times).all() and relative:
            deltas = bool(np.any(np.diff(times) < 0))
        if deltas:
            times = clock + np.cumsum(times)
            clock = float(times[-1]) if len(times) else clock
        out = FrameArray.build(times, idents, datas, extended=np.array(exts, dtype=bool))
        out.flags[np.array(remote, dtype=bool)] |= 1
        for lst in (t, idents, exts, datas, remote):
            lst.clear()
        return out

    relative = False
    try:
        with _open_text(path) as fh:
            lines = _BoundedLines(fh, path)
            parser = Parser()
            # line by line, not cantools' iterlines: a line whose time it cannot make a date of
            # ("(2020-13-45 …)", "(99999999999999999999.0)") raises out of that loop, and ended
            # the whole read with no line named
            for line in lines:
                number = lines.number
                try:
                    frame = parser.parse(line.strip("\r\n"))
                    stamp = frame.timestamp if frame is not None else None
                    if isinstance(stamp, datetime.timedelta):
                        seconds = stamp.total_seconds()
                    elif isinstance(stamp, datetime.datetime):
                        seconds = stamp.timestamp()
                    else:
                        seconds = np.nan
                except (ValueError, OverflowError) as err:
                    unreadable.add(number, str(err))
                    continue
                if frame is None:
                    if line.strip() and not line.lstrip().startswith(("#", ";")):
                        unknown.add(number)
                    continue
                lines.framed = True
                if not _ident_fits(frame.frame_id, frame.is_extended_frame):
                    bad_ids.add(number)
                    continue
                if abs(seconds) > MAX_LOG_TIME_S:  # (NaN, no time, is kept)
                    bad_times.add(number)
                    continue
                relative = relative or isinstance(stamp, datetime.timedelta)
                t.append(seconds)
                idents.append(frame.frame_id)
                exts.append(frame.is_extended_frame)
                datas.append(frame.data)
                remote.append(frame.is_remote_frame)
                if len(datas) >= chunk_frames:
                    yield chunk()
    except (OSError, EOFError, UnicodeDecodeError) as err:
        raise ConfigError(str(path), f"cannot read: {err}") from None
    if datas:
        yield chunk()
    for skipped in (unknown, unreadable, bad_ids, bad_times):
        skipped.warn(path, tally)


def write_frames(path: str | Path, frames: Iterable[FrameArray], channel: Any = None) -> int:
    """Write frames to a python-can log chosen by suffix; returns the number written."""
    import can

    path = Path(path)
    if _suffix(path) not in WRITE_SUFFIXES:
        raise ConfigError(
            str(path), f"cannot write CAN logs as {path.suffix!r}; use {', '.join(WRITE_SUFFIXES)}"
        )
    checked = isinstance(frames, (list, tuple))
    if checked:  # all at hand: refused before the file is made (or an old one overwritten)
        for chunk in frames:
            if (failure := _unwritable(path, chunk)) is not None:
                raise failure
    n = 0
    failure = None
    with can.Logger(str(path)) as logger:
        for chunk in frames:
            if not checked and (failure := _unwritable(path, chunk)) is not None:
                break
            for msg in chunk.to_messages(channel=channel):
                logger.on_message_received(msg)
            n += len(chunk)
    if failure is not None:
        path.unlink(missing_ok=True)  # no log cut short at the bad frame is left behind
        raise failure
    return n


def _unwritable(path: Path, chunk: FrameArray) -> ConfigError | None:
    """Why ``chunk`` cannot go in the log at ``path``: a time out of its range (python-can
    failed on it with an OverflowError or "year 11533 is out of range", or for ``.log`` wrote
    times that read back all equal)."""
    bad = ~np.isnan(chunk.t) & ~((chunk.t >= 0) & (chunk.t <= MAX_LOG_TIME_S))
    if not bad.any():
        return None
    t = float(chunk.t[np.argmax(bad)])
    return ConfigError(
        str(path),
        f"cannot write a frame at {t:.6g} s: a {_suffix(path)} CAN log's times are seconds "
        f"since 1970 from 0 to {MAX_LOG_TIME_S:.0f} (year 9999); are the source's times in "
        "seconds?",
    )


# --- samples ----------------------------------------------------------------------------------


@dataclass
class CanLogDecoding:
    """What decoding a log gave: the samples and what was seen on the way."""

    recording: Recording
    stats: CanStats
    notices: list[CanNotice] = field(default_factory=list)


def log_calibrations(path: str | Path, config: CanConfig) -> dict[str, AtiCalibration]:
    """Calibrations of the ATI boards the profile gives none for, from the replies in a log."""
    wanted = {n: s for n, s in config.ati_sensors.items() if s.calibration is None}
    if not wanted:
        return {}
    collectors = {n: CalibrationCollector(s.base) for n, s in wanted.items()}
    ids = np.array(sorted(set().union(*(ati_frame_ids(s.base) for s in wanted.values()))))
    for chunk in read_frames(path):
        sel = np.flatnonzero(np.isin(chunk.ident, ids))
        idents = chunk.ident[sel].tolist()
        dlcs = chunk.dlc[sel].tolist()
        for j, i in enumerate(sel.tolist()):
            payload = chunk.data[i, : dlcs[j]].tobytes()
            for c in collectors.values():
                c.feed(idents[j], payload)
        if all(c.calibration() is not None for c in collectors.values()):
            break
    out = {}
    for name, c in collectors.items():
        cal = c.calibration()
        if cal is None:
            hint = " (row replies without their requests)" if c.unpaired_rows else ""
            raise ConfigError(
                str(path),
                f"ATI sensor `{name}` (base 0x{c.base:02X}): the log lacks "
                f"{', '.join(c.missing()) or 'a usable matrix'}{hint}; record the start-up "
                "exchange with `hapticdesk record`, or give `calibration` in the profile",
            )
        if c.units is None:
            log.warning("ATI sensor %s: the log has no units reply (0x8); assuming N and N·m", name)
        out[name] = cal
    return out


def _assembler(path: str | Path, profile: DeskProfile) -> FrameAssembler:
    config = can_config(profile)
    decoding = build_decoding(config, profile, log_calibrations(path, config))
    return FrameAssembler(
        decoding,
        profile.sample_rate_hz,
        assemble=config.assemble,
        frame_gap_s=config.frame_gap_s,
        silent_timeout_s=config.silent_timeout_s,
        silent_sensor=config.silent_sensor,
        where=str(path),
        # by counter a sample's frames are known for sure, so a lost one is a known hole;
        # by time, an incomplete sample may be frames split wrongly, and nothing is held
        hold_samples=HOLD_SAMPLES if config.assemble == "counter" else 0,
    )


def _blocks(
    path: str | Path, assembler: FrameAssembler, skipped: dict[str, int] | None = None
) -> Iterator[AssembledBlock]:
    for chunk in read_frames(path, skipped=skipped):
        block = assembler.push(chunk)
        yield block
        if block.stop is not None:
            raise block.stop
    block = assembler.flush()
    yield block
    if block.stop is not None:
        raise block.stop


def decode_can_log(path: str | Path, profile: DeskProfile) -> CanLogDecoding:
    """Decode a whole log into a Recording, with the statistics of what was in it."""
    assembler = _assembler(path, profile)
    ts, ws, accs = [], [], []
    for block in _blocks(path, assembler):
        ts.append(block.t)
        ws.append(block.wrench)
        if block.accel is not None:
            accs.append(block.accel)
    t = np.concatenate(ts)
    if not len(t):
        raise _nothing_decoded(Path(path), profile.name, assembler.stats)
    extra = {}
    if accs and profile.accelerometer is not None:  # the columns a recording would have
        accel = np.concatenate(accs)
        extra = {c: accel[:, i] for i, c in enumerate(profile.accelerometer_columns())}
    recording = Recording(t, np.concatenate(ws), profile.sensor_names, extra)
    return CanLogDecoding(recording, assembler.stats, list(assembler.notices))


def _nothing_decoded(path: Path, desk: str, stats: CanStats) -> ConfigError:
    """No sample decoded: say what the frames were instead."""
    reasons = stats.summary()[1:]
    if stats.data_frames or stats.wrong_length:
        why = "; ".join(reasons) or "no frame kind complete"
    else:
        why = f"none with the identifiers its `can:` section decodes ({'; '.join(reasons)})"
    return ConfigError(
        str(path), f"no samples of desk `{desk}` in this log: {stats.frames} frames, {why}"
    )


def read_can_log(path: str | Path, profile: DeskProfile) -> Recording:
    """A CAN log decoded through the profile's ``can:`` section (problems logged as warnings)."""
    result = decode_can_log(path, profile)
    lines = result.stats.summary()
    if len(lines) > 1:
        log.warning("%s: %s", path, "; ".join(lines))
    return result.recording


class CanLogSource(Source):
    """A CAN log as a finite source of wrench blocks, decoded chunk by chunk."""

    def __init__(self, path: str | Path, profile: DeskProfile) -> None:
        self.path = Path(path)
        self.sensor_names = profile.sensor_names
        self.sample_rate_hz = profile.sample_rate_hz
        self.profile_name = profile.name
        self.assembler = _assembler(path, profile)
        self._closed = False
        #: lines and frames the reader skipped, by reason (see :func:`read_frames`)
        self.skipped: dict[str, int] = {}

    @property
    def stats(self) -> CanStats:
        return self.assembler.stats

    def summary(self) -> list[str]:
        lines = self.stats.summary()
        lines[1:1] = [f"{n} {what} skipped" for what, n in self.skipped.items()]
        return [f"CAN log {self.path.name}: {line}" for line in lines]

    def blocks(self) -> Iterator[WrenchBlock]:
        for block in _blocks(self.path, self.assembler, self.skipped):
            if self._closed:
                return
            if len(block.t):
                yield WrenchBlock(block.t, block.wrench, accel=block.accel)
        if not self.stats.samples:
            raise _nothing_decoded(self.path, self.profile_name, self.stats)

    def close(self) -> None:
        self._closed = True


def open_can_log(path: str | Path, profile: DeskProfile) -> Source:
    """A finite :class:`~hapticdesk.runtime.source.Source` of the log's samples."""
    return CanLogSource(path, profile)
