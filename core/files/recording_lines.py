"""A CSV recording's lines read a block at a time, bounded: bytes read in pieces of limited
size, split and decoded by C string methods (no Python work per line), so a line is never
longer than :data:`MAX_LINE_CHARS` and a block never holds much more than
:data:`MAX_BLOCK_CHARS`. A line too long or not UTF-8 ends the reading there; the lines
before it are handed out first, then its error. The CSV reader (:mod:`.recording_csv`) parses
what this hands out."""

from __future__ import annotations

from typing import BinaryIO

from hapticdesk.errors import ConfigError

#: the longest line read, in characters: a sample's line is a few hundred, a header a few
#: thousand; a file without line breaks (or /dev/zero) must not be read whole into one line.
#: Below the csv module's field limit (131,072), so no cell can reach it.
MAX_LINE_CHARS = 100_000
#: a block also ends once its lines hold this many characters (a block of long lines; with
#: the read ahead, at most twice this is held)
MAX_BLOCK_CHARS = 32_000_000


class RecordingLines:
    """The lines of an open file, ``take(rows)`` at a time, without their line ends."""

    def __init__(self, fh: BinaryIO, where: str) -> None:
        self._fh = fh
        self.where = where
        self.line = 0  # file lines handed out so far
        # lines read ahead (decoded, without their line ends) and their characters
        self._pending: list[str] = []
        self._pending_chars = 0
        self._tail = b""  # the start of a line whose end is not read yet
        # complete lines read ahead as bytes (each with its end), before any decoded: from
        # _ahead_at on, for a parser of the bytes (read_ahead); decoded when lines are taken
        self._ahead = b""
        self._ahead_at = 0
        self.quoted = False  # a quote seen: the plain parse reads quoted cells too
        self._started = False  # (a UTF-8 byte order mark is dropped from the first bytes)
        self._eof = False
        #: a bad line found: raised once the good samples before it are handed out (so a
        #: replay loses none of them to a bad line further on in the same block)
        self.failure: ConfigError | None = None

    @property
    def exhausted(self) -> bool:
        """True when a failure waits and no line before it is left to hand out."""
        return self.failure is not None and not self._pending

    def fail_after(self, err: ConfigError) -> None:
        """A line of the block handed out last is bad: drop the lines read ahead, and raise
        ``err`` once the lines before it are parsed (:meth:`take_failure`)."""
        self.failure, self._pending, self._pending_chars = err, [], 0

    def take_failure(self) -> ConfigError | None:
        """The failure waiting, if any, now handed over (it is raised once)."""
        failure, self.failure = self.failure, None
        return failure

    def take(self, rows: int) -> list[str]:
        """The next ``rows`` lines (fewer at the end of the file, or once they hold
        :data:`MAX_BLOCK_CHARS`), without their line ends.

        Read as bytes in pieces of bounded size, split and decoded by C string methods (no
        Python work per line), so a line is never longer than :data:`MAX_LINE_CHARS`: a file
        without line breaks is refused after that many characters, not read whole. A line
        that is too long or not UTF-8 ends the reading there: the lines before it are handed
        out first, then its error (:attr:`failure`).
        """
        if self._ahead_at < len(self._ahead):  # (they come first: decoded now)
            self._decode(self._ahead[self._ahead_at :])
        self._ahead, self._ahead_at = b"", 0
        while len(self._pending) < rows and self._pending_chars < MAX_BLOCK_CHARS and not self._eof:
            self._decode(self._read(256 * (rows - len(self._pending))))
        lines = self._pending[:rows]
        del self._pending[:rows]
        self._pending_chars -= sum(map(len, lines))
        self.line += len(lines)
        return lines

    def read_ahead(self, size: int) -> memoryview:
        """The complete lines read ahead, as the bytes they were read as, each with its line
        end, for a parser of plain lines (one that reads the bytes, not the lines: no line
        decoded, split and joined again); about ``size`` bytes are read once those are used
        up (:meth:`took` says how many were). Empty where none can be handed out so: at the
        end of the file, while decoded lines wait, or where the bytes read are not plain
        ASCII lines ended by LF alone (they are decoded then, and their faults named, for
        :meth:`take`)."""
        if self._pending or self.failure is not None:
            return memoryview(b"")
        if self._ahead_at == len(self._ahead) and not self._eof:
            data = self._read(size)
            self._ahead, self._ahead_at = b"", 0
            if not data.isascii() or b"\r" in data or len(self._tail) > MAX_LINE_CHARS:
                self._decode(data)
                return memoryview(b"")
            if data:
                self._ahead = data if data.endswith(b"\n") else data + b"\n"  # (the last line)
        return memoryview(self._ahead)[self._ahead_at :]

    def take_line(self) -> str | None:
        """The next line (a header), the lines after it left read ahead as bytes
        (:meth:`read_ahead`); None where they cannot be (:meth:`take` it then)."""
        ahead = self.read_ahead(1 << 16)
        end = self._ahead.find(b"\n", self._ahead_at, self._ahead_at + MAX_LINE_CHARS + 1)
        if not ahead or end < 0:
            return None
        line = self._ahead[self._ahead_at : end].decode("ascii")
        self.took(1, end + 1 - self._ahead_at)
        return line

    def took(self, lines: int, size: int) -> None:
        """The first ``lines`` lines, ``size`` bytes, of :meth:`read_ahead`'s are handed out."""
        self._ahead_at += size
        self.line += lines

    def _read(self, size: int) -> bytes:
        """The complete lines of about ``size`` more bytes read (at least 64 KiB, at most
        :data:`MAX_BLOCK_CHARS`), each with its end; at the end of the file the last line,
        without one."""
        data = self._fh.read(min(MAX_BLOCK_CHARS, max(1 << 16, size)))
        if not self._started:
            self._started = True
            data = data.removeprefix(b"\xef\xbb\xbf")
        if not data:
            self._eof = True
            complete, self._tail = self._tail, b""  # (the last line, without its end)
        else:
            # complete lines, each with its end; a CR LF split between two reads meets
            # again in the tail
            data = self._tail + data
            cut = data.rfind(b"\n") + 1
            complete, self._tail = data[:cut], data[cut:]
        return complete

    def _decode(self, complete: bytes) -> None:
        """Complete lines read (:meth:`_read`) decoded into the lines read ahead."""
        if not self._add_plain_lines(complete):
            parts = complete.replace(b"\r\n", b"\n").split(b"\n") if complete else []
            if complete.endswith(b"\n"):
                parts.pop()  # (after the last line's end)
            self._add_lines(parts)

    def _add_plain_lines(self, data: bytes) -> bool:
        """Add the lines of ``data`` when it is ASCII and no line (nor the tail) is too long,
        the usual case: decoded and split once (about twice as fast as splitting the bytes
        first). False, adding nothing, otherwise: :meth:`_add_lines` then finds where."""
        if not data.isascii() or len(self._tail) > MAX_LINE_CHARS:
            return False
        if not data:
            return True
        text = data.decode("ascii")
        self.quoted = self.quoted or '"' in text
        if "\r" in text:
            text = text.replace("\r\n", "\n")
        lines = text.split("\n")
        if text.endswith("\n"):
            lines.pop()  # (after the last line's end)
        if max(map(len, lines), default=0) > MAX_LINE_CHARS:
            return False
        self._pending.extend(lines)
        self._pending_chars += sum(map(len, lines))  # (as taken off: line ends not counted)
        return True

    def _add_lines(self, parts: list[bytes]) -> None:
        """Decode complete lines read ahead; stop at one too long or not UTF-8."""
        first = self.line + len(self._pending) + 1  # the file line of parts[0]
        bad: ConfigError | None = None
        longest = max(map(len, parts), default=0)
        if longest > MAX_LINE_CHARS or len(self._tail) > MAX_LINE_CHARS:
            index = next((i for i, x in enumerate(parts) if len(x) > MAX_LINE_CHARS), len(parts))
            bad = ConfigError(
                f"{self.where}:{first + index}",
                f"a line longer than {MAX_LINE_CHARS} characters (a recording's lines are a "
                "few hundred): is this a recording, with a line break after each sample?",
            )
            parts = parts[:index]
        data = b"\n".join(parts)
        try:
            text = data.decode("utf-8")
        except UnicodeDecodeError as err:
            index = data.count(b"\n", 0, err.start)
            column = err.start - (data.rfind(b"\n", 0, err.start) + 1) + 1
            bad = ConfigError(
                f"{self.where}:{first + index}:{column}",
                f"not UTF-8 text: byte 0x{data[err.start]:02x} ({err.reason}); save the "
                "recording as UTF-8",
            )
            parts = parts[:index]
            text = b"\n".join(parts).decode("utf-8")
        if parts:
            self.quoted = self.quoted or '"' in text
            lines = text.split("\n")
            self._pending.extend(lines)
            self._pending_chars += sum(map(len, lines))
        if bad is not None:
            if first + len(parts) == 1:
                raise bad  # (the header)
            self._tail, self._eof, self.failure = b"", True, bad
