"""Opening a CAN log: the format its name says (:func:`log_suffix`, ``.gz`` taken off), its
text (gzip or plain, undecodable bytes replaced), and its lines read with a bounded length
(:class:`BoundedLines`): a file of one endless line is refused at ``file:line``, not read
whole into memory."""

from __future__ import annotations

import gzip
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from hapticdesk.canbus.logs.skipped import Skipped
from hapticdesk.errors import ConfigError

#: the longest line a text log may have: a CAN FD frame of 64 bytes is under 400 characters in
#: every format read here, so a longer line is not a frame (a corrupt or hostile file would
#: otherwise be read whole into memory as one line)
MAX_LINE_CHARS = 4096
#: a text log whose first this many lines hold no frame is no CAN log (headers and comments
#: are a few dozen lines)
MAX_LINES_BEFORE_A_FRAME = 10_000


def log_suffix(path: str | Path) -> str:
    """The suffix that says a log's format, lower case, ``.gz`` taken off (``""``: none)."""
    suffixes = [s.lower() for s in Path(path).suffixes]
    if suffixes and suffixes[-1] == ".gz":
        suffixes = suffixes[:-1]
    return suffixes[-1] if suffixes else ""


def open_text(path: Path) -> Any:
    """The log's text (gunzipped for ``.gz``), undecodable bytes replaced."""
    if path.suffix.lower() == ".gz":
        return gzip.open(path, "rt", encoding="utf-8", errors="replace")
    return path.open(encoding="utf-8", errors="replace")


def first_undecodable_line(path: Path) -> int:
    """The number of the first line of ``path`` that is not UTF-8 (0: none found)."""
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


class BoundedLines:
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
        self.unread: tuple[re.Pattern[str], Skipped] | None = None
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
