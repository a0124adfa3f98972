"""python-can's log formats read as frames: ``.asc`` (Vector ASCII), ``.blf`` (Vector
binary), ``.trc`` (PEAK trace) and ``.log`` (candump ``-l``), each also ``.gz``.

python-can's own readers parse them; around them this module bounds what a corrupt or
hostile file can cost (text lines of bounded length, BLF containers inflated within
:data:`MAX_BLF_CONTAINER_BYTES`), skips and counts the frames it cannot believe (an
identifier or time out of range, data bytes that disagree with the DLC, junk lines of a
``.log``), and hands out the frames read before a failure before it raises it at its line.
"""

from __future__ import annotations

import gzip
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from hapticdesk.canbus.frames import FrameArray
from hapticdesk.canbus.logs.log_files import (
    BoundedLines,
    first_undecodable_line,
    log_suffix,
    open_text,
)
from hapticdesk.canbus.logs.skipped import (
    BAD_ID,
    BAD_TIME,
    MAX_LOG_TIME_S,
    NOT_FRAMES,
    Skipped,
    ident_fits,
    log,
)
from hapticdesk.errors import ConfigError

PYTHON_CAN_SUFFIXES = (".asc", ".blf", ".log", ".trc")
#: the most one BLF log container may inflate to: python-can writes containers of 128 KiB and
#: Vector's tools like ones, so a container inflating further is no log but a zlib bomb (one
#: of 4 MB grew python-can's reader to 4.1 GB before this bound)
MAX_BLF_CONTAINER_BYTES = 64 * 1024 * 1024
#: how much of a ``.log`` file is looked at to tell candump ``-l`` from candump's printed text
SNIFF_CHARS = 65_536
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


#: python-can's reader class of each format (BLF is read by :func:`_blf_messages`)
_READERS = {
    ".asc": "ASCReader",
    ".trc": "TRCReader",
    ".log": "CanutilsLogReader",
}
_MISMATCHED = "frame(s) whose data bytes disagree with their DLC were"


def looks_canutils(path: Path) -> bool:
    """Whether the first line with text in the file's first :data:`SNIFF_CHARS` characters is
    a candump ``-l`` frame (a bounded read: a file of one endless line is not read whole)."""
    try:
        with open_text(path) as fh:
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


def read_python_can_frames(
    path: Path, chunk_frames: int, tally: dict[str, int] | None = None
) -> Iterator[FrameArray]:
    """The log's frames in chunks of ``chunk_frames``, in file order; what was skipped is
    warned of (and added to ``tally``, by reason); a failure is raised, at its line where
    known, after the frames read before it."""
    fmt = log_suffix(path)
    checks = _MessageChecks()
    batch: list[Any] = []
    failure: ConfigError | None = None
    text: BoundedLines | None = None  # (None also when opening the file fails)
    lines: CanutilsLines | None = None
    try:
        # we open the file so that it is closed whatever the reader raises
        opener = gzip.open if path.suffix.lower() == ".gz" else open
        with opener(path, "rb" if fmt == ".blf" else "rt") as fh:
            text = BoundedLines(fh, path) if fmt != ".blf" else None
            messages, lines = _messages(fh, path, fmt, text, checks.bad_times)
            for msg in messages:
                number = text.frame_read() if text is not None else None
                if not checks.believed(msg, number, text is not None):
                    continue
                batch.append(msg)
                if len(batch) >= chunk_frames:
                    yield FrameArray.from_messages(batch)
                    batch = []
    except Exception as err:  # (what each kind says: _failure)
        failure = _failure(err, path, fmt, text)
    # the frames read before a failure go on first: nothing already read is lost (a corrupt
    # block near the end of a BLF file dropped every frame before it)
    if batch:
        yield FrameArray.from_messages(batch)
    if failure is None and text is not None:
        text.frame_read(end=True)  # the last line may have been a frame line python-can skipped
    checks.warn(path, tally)
    if failure is not None:
        raise failure
    if lines is not None:
        lines.skipped.warn(path, tally)


def _messages(
    fh: Any, path: Path, fmt: str, text: BoundedLines | None, bad_times: Skipped
) -> tuple[Iterator[Any], CanutilsLines | None]:
    """python-can's messages of the open log, and for a ``.log`` the filter of its lines
    (which counts the junk ones)."""
    import can  # lazily: only CAN paths need python-can

    if text is None:
        return _blf_messages(fh, path), None
    if fmt == ".asc":
        text.unread = (_ASC_FRAME_LIKE, bad_times)
    lines = CanutilsLines(text) if fmt == ".log" else None
    reader = getattr(can, _READERS[fmt])
    return reader(lines if lines is not None else text), lines


class _MessageChecks:
    """Which of python-can's messages are believed; the others counted by reason."""

    def __init__(self) -> None:
        self.mismatched = Skipped(_MISMATCHED)
        self.bad_ids = Skipped(BAD_ID)
        self.bad_times = Skipped(BAD_TIME)

    def believed(self, msg: Any, number: int | None, from_text: bool) -> bool:
        """True for a frame to keep; ``number`` its line in a text log."""
        if not ident_fits(msg.arbitration_id, msg.is_extended_id):
            self.bad_ids.add(number)
            return False
        if not abs(msg.timestamp) <= MAX_LOG_TIME_S:  # (NaN too)
            self.bad_times.add(number)
            return False
        if from_text and not (_dlc_holds(msg) or msg.is_remote_frame or msg.is_error_frame):
            # a line whose data bytes disagree with its DLC (cut short, or bytes too many):
            # which of the two is wrong cannot be told, so neither is believed (python-can
            # kept the bytes as found and said nothing)
            self.mismatched.add(number)
            return False
        return True

    def warn(self, path: Path, tally: dict[str, int] | None) -> None:
        for skipped in (self.mismatched, self.bad_ids, self.bad_times):
            skipped.warn(path, tally)


def _failure(err: Exception, path: Path, fmt: str, text: BoundedLines | None) -> ConfigError:
    """What a reader's exception says to the user, at the line last read where known."""
    import can

    if isinstance(err, ConfigError):  # a line too long: already says where
        return err
    if isinstance(err, (ValueError, OSError, EOFError, KeyError, IndexError, can.CanError)):
        number = text.number if text is not None else 0
        why = str(err)
        if isinstance(err, UnicodeDecodeError):  # raised for a whole buffer, lines ahead
            number = first_undecodable_line(path)
            why = f"the line is not UTF-8 text (byte 0x{err.object[err.start]:02x}: {err.reason})"
        where = f"{path}:{number}" if number else str(path)
        return ConfigError(where, f"not a readable {fmt} CAN log: {why}")
    if isinstance(err, MemoryError):
        where = f"{path}:{text.number}" if text is not None else str(path)
        return ConfigError(
            where, f"not a readable {fmt} CAN log: it needs more memory than there is"
        )
    # BLF and gzip readers raise their own kinds on corrupt files
    return ConfigError(str(path), f"not a readable {fmt} CAN log: {err!r}")


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


class CanutilsLines:
    """The lines of a candump ``-l`` file that are frames; the others are skipped and counted
    (python-can's reader raises on the first junk line, which would end a replay with no line
    number). The lines come from :class:`BoundedLines`, which numbers them."""

    def __init__(self, lines: BoundedLines) -> None:
        self._lines = lines
        self.skipped = Skipped(NOT_FRAMES)

    def __iter__(self) -> Iterator[str]:
        for line in self._lines:
            if _CANUTILS_FRAME.match(line):
                yield line
            elif line.strip() and not line.lstrip().startswith(("#", ";")):
                self.skipped.add(self._lines.number)

    def close(self) -> None:
        """python-can closes its file when done; ours is closed by its ``with``."""
