"""Recordings: sample times and every sensor's raw channels, as CSV or NPZ (DESIGN.md).

Header ``t`` then each sensor's channels, ``<sensor>_<channel>``, in the profile's order:
``<sensor>_fx … <sensor>_mz`` for a six-axis sensor, ``<sensor>_fz`` for a load cell, a
calibrated sensor's own channel names (:meth:`DeskProfile.channel_names`). Other columns
are kept as ``extra`` (the simulator's ground truth ``true_x, true_y, true_fn``, a desk's
accelerometers' ``acc_x, acc_y, acc_z``, ``acc2_x``, …) and otherwise ignored (text ones too,
except the accelerometers', whose bad cells are errors). A missing column is an error that names it.

Files are read in blocks (:class:`RecordingBlocks`) so that a replay's memory does not grow
with the file: CSV through numpy's C parser a block of lines at a time, NPZ each column's
``.npy`` member in slices. Errors name file:line:column (CSV) or the column (NPZ).
"""

from __future__ import annotations

import csv
import re
import zipfile
import zlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, BinaryIO

import numpy as np

from hapticdesk.files.profile import ACCEL_COLUMN, AXES
from hapticdesk.files.yamlfile import ConfigError, regular_file_size

RECORDING_SUFFIXES = (".csv", ".npz")
BLOCK_ROWS = 16_384  # samples per block read: ~14 s at 1.2 kHz; ~25 MB to parse a CSV block
#: the longest line read, in characters: a sample's line is a few hundred, a header a few
#: thousand; a file without line breaks (or /dev/zero) must not be read whole into one line.
#: Below the csv module's field limit (131,072), so no cell can reach it.
MAX_LINE_CHARS = 100_000
#: a block also ends once its lines hold this many characters (a block of long lines; with
#: the read ahead, at most twice this is held)
MAX_BLOCK_CHARS = 32_000_000
# an empty cell (between commas, or at either end of a line that has commas) reads as NaN
_EMPTY_CELL = re.compile(r"(?m)(?:^|(?<=,))[ \t]*(?=,)|(?<=,)[ \t]*$")


def _line_of_error(err: ConfigError, first_line: int, count: int) -> int | None:
    """The file line a reading error names, when it is one of the ``count`` lines from
    ``first_line`` on (``file:line`` or ``file:line:column``)."""
    found = re.search(r":(\d+)(?::\d+)?$", str(err.where))
    if found is None:
        return None
    line = int(found.group(1))
    return line if first_line <= line < first_line + count else None


def _data_line_offsets(lines: list[str]) -> list[int]:
    """Offsets of the lines numpy reads as rows (it skips empty ones); for error messages."""
    return [j for j, line in enumerate(lines) if line.strip("\r\n")]


def six_axis_columns(sensor_names: list[str]) -> list[str]:
    """The channel columns of a desk of six-axis sensors called ``sensor_names``."""
    return [f"{s}_{a}" for s in sensor_names for a in AXES]


@dataclass
class Recording:
    """``t`` (k,) seconds; ``wrench`` the sensors' raw readings; extra columns.

    For a desk of six-axis sensors (``channel_names`` None, or those of six-axis sensors)
    ``wrench`` is (k, S, 6), each sensor's fx … mz in its own frame; for a desk of any
    other sensors it is (k, C), its ``channel_names`` in order (:attr:`channels` is (k, C)
    for both).
    """

    t: np.ndarray
    wrench: np.ndarray
    sensor_names: list[str]
    extra: dict[str, np.ndarray] = field(default_factory=dict)
    #: the raw channels' column names; None: six per sensor, ``<sensor>_fx … _mz``
    channel_names: list[str] | None = None

    def __post_init__(self) -> None:
        k = len(self.t)
        if self.channel_names == six_axis_columns(self.sensor_names):
            self.channel_names = None
        if self.channel_names is None:
            n = len(self.sensor_names)
            if self.wrench.shape == (k, 6 * n):
                self.wrench = self.wrench.reshape(k, n, 6)
            if self.wrench.shape != (k, n, 6):
                raise ValueError(
                    f"wrench must have shape (k, S, 6) = ({k}, {n}, 6), found {self.wrench.shape}"
                )
        elif self.wrench.shape != (k, len(self.channel_names)):
            raise ValueError(
                f"the readings must have shape (k, C) = ({k}, {len(self.channel_names)}), "
                f"one column per channel, found {self.wrench.shape}"
            )

    def __len__(self) -> int:
        return len(self.t)

    @property
    def channels(self) -> np.ndarray:
        """The raw readings as (k, C), in :meth:`channel_columns` order."""
        return self.wrench.reshape(len(self.t), -1)

    def channel_columns(self) -> list[str]:
        """The raw channels' column names, in order."""
        if self.channel_names is None:
            return six_axis_columns(self.sensor_names)
        return list(self.channel_names)

    def columns(self) -> list[str]:
        return ["t"] + self.channel_columns() + list(self.extra)

    def table(self) -> np.ndarray:
        """All columns as one (k, C) float array in :meth:`columns` order."""
        parts = [self.t[:, None], self.channels]
        parts += [np.asarray(v, dtype=float)[:, None] for v in self.extra.values()]
        return np.hstack(parts)


def accel_table(extra: dict[str, np.ndarray]) -> np.ndarray | None:
    """The accelerometer columns among ``extra`` as (k, A): ``acc_*``, then ``acc2_*``, …,
    each in x, y, z order (a profile's order), or None when there are none (the estimator
    checks them against the desk's profile)."""
    names = sorted((c for c in extra if ACCEL_COLUMN.fullmatch(c)), key=_accel_column_order)
    return named_columns(extra, names)


def named_columns(extra: dict[str, np.ndarray], names: list[str]) -> np.ndarray | None:
    """The columns ``names`` among ``extra`` as (k, len(names)) floats, or None when there are
    no names or any is missing (an accelerometer's readings: all of them or none)."""
    if not names or not all(name in extra for name in names):
        return None
    return np.column_stack([np.asarray(extra[name], dtype=float) for name in names])


def _accel_column_order(name: str) -> tuple[int, str]:
    prefix, axis = name.split("_")
    return int(prefix[3:] or 1), axis


def _empty_cells_as_nan(text: str) -> str:
    """``text`` (CSV lines) with each empty or blank cell written ``nan`` (a missing value, not
    an error). The pattern tries every position (1.0 s for 105,000 lines of 34 columns, twice
    numpy's parse): it runs only where an empty cell can be, which a plain numeric file never
    has (no ``,,``, no cell at a line's end or start, no blank)."""
    if (
        ",," in text
        or ",\n" in text
        or "\n," in text
        or text.startswith(",")
        or text.endswith(",")
        or " " in text
        or "\t" in text
    ):
        return _EMPTY_CELL.sub("nan", text)
    return text


def needed_columns(sensor_names: list[str], channel_names: list[str] | None = None) -> list[str]:
    """The columns a recording for ``sensor_names`` must have, in order: ``t``, then
    ``channel_names`` (default: six per sensor, ``<sensor>_fx … _mz``)."""
    return ["t"] + (six_axis_columns(sensor_names) if channel_names is None else channel_names)


def _missing_error(where: str, missing: list[str], sensor_names: list[str]) -> ConfigError:
    shown = ", ".join(missing[:6]) + (f" and {len(missing) - 6} more" if len(missing) > 6 else "")
    return ConfigError(
        where, f"missing column(s) {shown}; the desk's sensors are {', '.join(sensor_names)}"
    )


def _from_table(
    table: np.ndarray,
    extra_names: list[str],
    sensor_names: list[str],
    channel_names: list[str] | None,
) -> Recording:
    """(k, 1 + C + E) floats in :func:`needed_columns` order, then the extra columns."""
    c = len(needed_columns(sensor_names, channel_names)) - 1
    extra = {n: table[:, 1 + c + i] for i, n in enumerate(extra_names)}
    return Recording(
        table[:, 0].copy(), table[:, 1 : 1 + c], list(sensor_names), extra, channel_names
    )


class RecordingBlocks:
    """A CSV or NPZ recording read in blocks of ``block_rows`` samples, in one pass.

    Memory stays flat whatever the file's size: only one block is held. The header (and for
    NPZ every column's type and length) is checked when the object is made, so a bad file is
    refused before anything runs. CSV blocks are parsed by numpy's C reader, not cell by cell.
    Use as a context manager or call :meth:`close`.
    """

    def __init__(
        self,
        path: str | Path,
        sensor_names: list[str],
        *,
        block_rows: int = BLOCK_ROWS,
        channel_names: list[str] | None = None,
    ) -> None:
        """``channel_names``: the raw channels' columns (:meth:`DeskProfile.channel_names`);
        None for six-axis sensors, ``<sensor>_fx … _mz``."""
        self.path = Path(path)
        self.sensor_names = list(sensor_names)
        self.block_rows = max(1, int(block_rows))
        self.extra_names: list[str] = []
        suffix = self.path.suffix.lower()
        names = (self.sensor_names, channel_names)
        if suffix == ".npz":
            self._reader: _CsvReader | _NpzReader = _NpzReader(self.path, *names)
        elif suffix == ".csv":
            self._reader = _CsvReader(self.path, *names)
        else:
            raise ConfigError(
                str(self.path),
                f"unknown recording format {suffix!r}; expected .csv or .npz "
                "(or a CAN log, see `hapticdesk record --help`)",
            )
        self._rows = 0
        # the first block is read now: a bad first row or an empty file is refused at once
        try:
            self._first = self._next_block()
        except BaseException:
            self.close()
            raise

    def _next_block(self) -> Recording | None:
        while True:
            block = self._reader.read(self.block_rows, self._rows)
            if block is None or len(block):
                return block
            # a block of blank lines only: read on

    def is_empty(self) -> bool:
        """True when the file holds no samples."""
        return self._first is None

    def first_times(self) -> np.ndarray:
        """The first block's sample times, before :meth:`blocks` hands it out (empty when the
        file holds no samples or the block is out)."""
        return np.zeros(0) if self._first is None else self._first.t

    @property
    def rows_read(self) -> int:
        """Samples handed out so far."""
        return self._rows

    def blocks(self) -> Iterator[Recording]:
        """Blocks in file order (never empty ones); ConfigError names the line of a bad value."""
        try:
            block, self._first = self._first, None
            while block is not None:
                self._rows += len(block)
                yield block
                block = self._next_block()
        finally:
            self.close()

    def close(self) -> None:
        self._reader.close()

    def __enter__(self) -> RecordingBlocks:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class _CsvReader:
    def __init__(
        self, path: Path, sensor_names: list[str], channel_names: list[str] | None
    ) -> None:
        self.where = str(path)
        self.sensor_names = sensor_names
        self.channel_names = channel_names
        self._fh: BinaryIO | None = None
        regular_file_size(path, "the recording")  # a FIFO would block, /dev/zero never end
        try:
            self._fh = path.open("rb")
        except OSError as err:
            raise ConfigError(self.where, f"cannot read: {err.strerror or err}") from None
        self.line = 0  # file lines handed out so far
        # lines read ahead (decoded, without their line ends) and their characters
        self._pending: list[str] = []
        self._pending_chars = 0
        self._tail = b""  # the start of a line whose end is not read yet
        self._quoted = False  # a quote seen: the plain parse reads quoted cells too
        self._started = False  # (a UTF-8 byte order mark is dropped from the first bytes)
        self._eof = False
        # a bad line found: raised once the good samples before it are handed out (so a
        # replay loses none of them to a bad line further on in the same block)
        self._failure: ConfigError | None = None
        try:
            head = self._take_lines(1)
            first = head[0] if head else ""
            if not first.strip():
                raise ConfigError(
                    f"{self.where}:1", "empty file, expected a header starting with `t`"
                )
            header = [h.strip() for h in self._cells(first, 1)]
        except BaseException:
            self.close()
            raise
        seen: dict[str, int] = {}
        for i, name in enumerate(header):
            if name and name in seen:
                self.close()
                raise ConfigError(
                    f"{self.where}:1:{i + 1}",
                    f"column `{name}` appears twice (columns {seen[name] + 1} and {i + 1})",
                )
            seen[name] = i
        needed = needed_columns(sensor_names, channel_names)
        missing = [c for c in needed if c not in seen]
        if missing:
            self.close()
            raise _missing_error(f"{self.where}:1", missing, sensor_names)
        self.header = header
        self.needed_index = [seen[c] for c in needed]
        # other named columns are kept as extras while they hold numbers, else ignored
        self.extra = [(n, i) for i, n in enumerate(header) if n and n not in needed]

    def _take_lines(self, rows: int) -> list[str]:
        """The next ``rows`` lines (fewer at the end of the file, or once they hold
        :data:`MAX_BLOCK_CHARS`), without their line ends.

        Read as bytes in pieces of bounded size, split and decoded by C string methods (no
        Python work per line), so a line is never longer than :data:`MAX_LINE_CHARS`: a file
        without line breaks is refused after that many characters, not read whole. A line
        that is too long or not UTF-8 ends the reading there: the lines before it are handed
        out first, then its error (``_failure``).
        """
        assert self._fh is not None
        while len(self._pending) < rows and self._pending_chars < MAX_BLOCK_CHARS and not self._eof:
            want = min(MAX_BLOCK_CHARS, max(1 << 16, 256 * (rows - len(self._pending))))
            data = self._fh.read(want)
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
            if not self._add_plain_lines(complete):
                parts = complete.replace(b"\r\n", b"\n").split(b"\n") if complete else []
                if complete.endswith(b"\n"):
                    parts.pop()  # (after the last line's end)
                self._add_lines(parts)
        lines = self._pending[:rows]
        del self._pending[:rows]
        self._pending_chars -= sum(map(len, lines))
        self.line += len(lines)
        return lines

    def _add_plain_lines(self, data: bytes) -> bool:
        """Add the lines of ``data`` when it is ASCII and no line (nor the tail) is too long,
        the usual case: decoded and split once (about twice as fast as splitting the bytes
        first). False, adding nothing, otherwise: :meth:`_add_lines` then finds where."""
        if not data.isascii() or len(self._tail) > MAX_LINE_CHARS:
            return False
        if not data:
            return True
        text = data.decode("ascii")
        self._quoted = self._quoted or '"' in text
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
            self._quoted = self._quoted or '"' in text
            lines = text.split("\n")
            self._pending.extend(lines)
            self._pending_chars += sum(map(len, lines))
        if bad is not None:
            if first + len(parts) == 1:
                raise bad  # (the header)
            self._tail, self._eof, self._failure = b"", True, bad

    def _cells(self, line: str, number: int) -> list[str]:
        """The cells of one CSV line (file line ``number``), as the csv module reads them."""
        try:
            return next(csv.reader([line]), [])
        except csv.Error as err:
            raise ConfigError(f"{self.where}:{number}", f"not a CSV line: {err}") from None

    def _check_widths(self, text: str, lines: list[str], first_line: int) -> None:
        """Every data line has as many values as the header: numpy reads only the columns it
        is asked for and would drop a value too many without a word (a shifted row). Counted
        cheaply: the block's commas against the header's, line by line only when they differ
        (or when quotes may hide commas)."""
        width = len(self.header)
        quoted = '"' in text
        if not quoted:
            n_data = len(lines) - lines.count("")  # numpy skips empty lines
            if text.count(",") == (width - 1) * n_data:
                return
        for j, line in enumerate(lines):
            if not line:
                continue
            cells = self._cells(line, first_line + j) if quoted else line.split(",")
            found = len(cells)
            if found > width and not "".join(cells[width:]).strip():
                continue  # empty cells after the last column (a logger's trailing comma)
            if found != width:
                raise ConfigError(
                    f"{self.where}:{first_line + j}",
                    f"this row has {found} value(s), the header {width}",
                )

    def read(self, rows: int, _done: int) -> Recording | None:
        if self._fh is None:
            return None
        first_line = self.line + 1
        lines = self._take_lines(rows) if self._failure is None or self._pending else []
        if not lines:
            failure, self._failure = self._failure, None
            self.close()
            if failure is not None:
                raise failure
            return None
        while True:
            try:
                return self._parse(lines, first_line)
            except ConfigError as err:
                bad = _line_of_error(err, first_line, len(lines))
                if bad is None or bad <= first_line:
                    raise
                # the samples before the bad line first; the error on the next read
                lines = lines[: bad - first_line]
                self._failure, self._pending, self._pending_chars = err, [], 0

    def _parse(self, lines: list[str], first_line: int) -> Recording:
        """The samples of ``lines`` (file lines from ``first_line`` on); ConfigError at the
        first bad one."""
        table = self._parse_plain(lines)
        if table is None:
            table = self._parse_careful(lines, first_line)
        rec = _from_table(table, [n for n, _ in self.extra], self.sensor_names, self.channel_names)
        if not np.isfinite(rec.t).all():
            i = int(np.argmax(~np.isfinite(rec.t)))
            offset = _data_line_offsets(lines)[i]
            column = self.needed_index[0]
            cells = self._cells(lines[offset], first_line + offset)
            cell = cells[column].strip() if column < len(cells) else ""
            raise ConfigError(
                f"{self.where}:{first_line + offset}:{column + 1}",
                f"`t` is {cell or 'empty'!r}; every sample needs a finite time in seconds",
            )
        return rec

    def _parse_plain(self, lines: list[str]) -> np.ndarray | None:
        """The block's table (:func:`_from_table` order) when every line is plainly numeric
        and as wide as the header: one ``np.loadtxt`` of every column, which itself refuses
        an empty or blank cell, a word and a row of another width. None otherwise, for
        :meth:`_parse_careful` to read the block again and name any fault at its
        file:line:column. (A recording as ``write_recording`` and the simulator write it,
        the paper scene's 105,617 lines of 34 columns: 0.40 s against 0.64 s through the
        careful path, which scans each block for empty cells and reads the columns by name;
        medians of 7, alternating in one process, on a loaded 2-core machine.)"""
        # (blank lines only: numpy would warn of no data; the first line is almost always
        # the one that shows it is not)
        if not any(line.strip("\r") for line in lines):
            return None
        try:
            table = np.loadtxt(
                lines,
                delimiter=",",
                ndmin=2,
                dtype=float,
                comments=None,
                # (numpy's parser is 10-15 % faster without looking for quotes)
                quotechar='"' if self._quoted else None,
            )
        except ValueError:
            return None
        width = len(self.header)
        if table.shape[1] != width:  # (a trailing comma on every line: read carefully)
            return None
        usecols = self.needed_index + [i for _, i in self.extra]
        return table if usecols == list(range(width)) else table[:, usecols]

    def _parse_careful(self, lines: list[str], first_line: int) -> np.ndarray:
        """The block's table read column by name, empty cells as NaN, text extra columns
        dropped; ConfigError at the first bad value or row."""
        text = _empty_cells_as_nan("\n".join(lines))
        self._check_widths(text, lines, first_line)
        table = np.zeros((0, len(self.needed_index) + len(self.extra)))  # blank lines only
        while text.strip():
            usecols = self.needed_index + [i for _, i in self.extra]
            try:
                table = np.loadtxt(
                    text.split("\n"),  # a list of str: StringIO would hold 4 bytes a character
                    delimiter=",",
                    usecols=usecols,
                    ndmin=2,
                    dtype=float,
                    comments=None,
                    quotechar='"',
                )
                break
            except ValueError as err:  # a bad value is raised; a text extra column dropped
                self._explain(err, first_line, usecols, lines)
        return table

    def _explain(
        self, err: ValueError, first_line: int, usecols: list[int], lines: list[str]
    ) -> None:
        """Turn numpy's message into file:line:column, or drop a non-numeric extra column."""
        message = str(err)
        offsets = _data_line_offsets(lines)

        def line_of(row: int) -> int:  # numpy counts rows from 0, skipping empty lines
            return first_line + (offsets[row] if row < len(offsets) else row)

        bad_value = re.search(
            r"could not convert string (.*) to \w+ at row (\d+), column (\d+)", message
        )
        if bad_value:
            row, col = int(bad_value.group(2)), usecols[int(bad_value.group(3)) - 1]
            extra = [e for e in self.extra if e[1] == col]
            # other columns are ignored (DESIGN.md): a text column is not an error; but an
            # accelerometer's columns are readings, whose silent loss would turn its
            # compensation off
            if extra and not ACCEL_COLUMN.fullmatch(extra[0][0]):
                self.extra.remove(extra[0])
                return
            raise ConfigError(
                f"{self.where}:{line_of(row)}:{col + 1}",
                f"column `{self.header[col]}`: {bad_value.group(1)} is not a number",
            ) from None
        # numpy counts rows from 1 in its column-count messages
        short = re.search(r"at row (\d+) with (\d+) columns", message)
        changed = re.search(r"changed from \d+ to (\d+) at row (\d+)", message)
        if short or changed:
            row, found = (
                (int(short.group(1)), int(short.group(2)))
                if short
                else (int(changed.group(2)), int(changed.group(1)))  # type: ignore[union-attr]
            )
            raise ConfigError(
                f"{self.where}:{line_of(row - 1)}",
                f"this row has {found} value(s), the header {len(self.header)}",
            ) from None
        raise ConfigError(f"{self.where}:{first_line}", f"unreadable rows: {message}") from None

    def close(self) -> None:
        if self._fh is not None:
            self._fh.close()
            self._fh = None


#: the most members (columns) an NPZ recording may have: 60,000 tiny extra columns took
#: 3.4 GB (each read as a stream of its own); a 40-sensor desk has 241
MAX_NPZ_MEMBERS = 1024


#: what a damaged or unusual zip raises as a member is read: an encrypted member or one of an
#: unsupported compression method is a RuntimeError (NotImplementedError), not an OSError
_NPZ_ERRORS = (OSError, ValueError, EOFError, RuntimeError, zipfile.BadZipFile, zlib.error)


class _NpzReader:
    """Each column's ``.npy`` member read in slices: no column is ever loaded whole."""

    def __init__(
        self, path: Path, sensor_names: list[str], channel_names: list[str] | None
    ) -> None:
        self.where = str(path)
        self.sensor_names = sensor_names
        self.channel_names = channel_names
        self._members: list[tuple[str, IO[bytes], np.dtype]] = []
        self._zip: zipfile.ZipFile | None = None
        regular_file_size(path, "the recording")  # a FIFO would block, /dev/zero never end
        try:
            self._zip = zipfile.ZipFile(path)
            members = len(self._zip.infolist())
            columns = self._headers() if members <= MAX_NPZ_MEMBERS else {}
        except _NPZ_ERRORS as err:
            self.close()
            raise ConfigError(self.where, f"not a readable NPZ recording: {err}") from None
        if members > MAX_NPZ_MEMBERS:  # (each opened member is a stream with its buffers)
            self.close()
            raise ConfigError(
                self.where,
                f"{members:,} members; a recording has one per column (time, six per sensor, "
                f"a few more): at most {MAX_NPZ_MEMBERS:,} are read",
            )
        needed = needed_columns(sensor_names, channel_names)
        missing = [c for c in needed if c not in columns]
        if missing:
            self.close()
            raise _missing_error(self.where, missing, sensor_names)
        for name in needed:
            shape, dtype = columns[name]
            problem = _column_problem(shape, dtype)
            if problem:
                self.close()
                raise ConfigError(self.where, f"column `{name}` {problem}")
        lengths = {name: columns[name][0][0] for name in needed}
        self.length = lengths["t"]
        uneven = {n: k for n, k in lengths.items() if k != self.length}
        if uneven:
            shown = ", ".join(f"`{n}` {k}" for n, k in list(uneven.items())[:4])
            self.close()
            raise ConfigError(
                self.where,
                f"columns of different lengths: `t` has {self.length} rows, {shown}; "
                "every column needs one value per sample",
            )
        # other columns are kept when they are numbers, one per sample; otherwise ignored
        self.extra = [
            n
            for n, (shape, dtype) in columns.items()
            if n not in needed and not _column_problem(shape, dtype) and shape[0] == self.length
        ]
        try:
            for name in needed + self.extra:
                self._members.append((name, self._open_data(name), columns[name][1]))
        except _NPZ_ERRORS as err:
            self.close()
            raise ConfigError(self.where, f"not a readable NPZ recording: {err}") from None

    def _headers(self) -> dict[str, tuple[tuple[int, ...], np.dtype]]:
        assert self._zip is not None
        out = {}
        for member in self._zip.namelist():
            if member.endswith(".npy"):
                with self._zip.open(member) as fh:
                    out[member[:-4]] = _npy_header(fh)
        return out

    def _open_data(self, name: str) -> IO[bytes]:
        assert self._zip is not None
        fh = self._zip.open(name + ".npy")
        _npy_header(fh)  # leaves the stream at the first value
        return fh

    def read(self, rows: int, done: int) -> Recording | None:
        if self._zip is None or done >= self.length:
            self.close()
            return None
        k = min(rows, self.length - done)
        table = np.empty((k, len(self._members)))
        try:
            for j, (name, fh, dtype) in enumerate(self._members):
                raw = fh.read(k * dtype.itemsize)
                if len(raw) != k * dtype.itemsize:
                    raise ConfigError(
                        self.where,
                        f"column `{name}` ends after {done + len(raw) // dtype.itemsize} of its "
                        f"{self.length} rows (a truncated file?)",
                    )
                table[:, j] = np.frombuffer(raw, dtype=dtype)
        except _NPZ_ERRORS as err:
            raise ConfigError(self.where, f"not a readable NPZ recording: {err}") from None
        rec = _from_table(table, self.extra, self.sensor_names, self.channel_names)
        bad = ~np.isfinite(rec.t)
        if bad.any():
            row = done + int(np.argmax(bad)) + 1
            raise ConfigError(
                self.where,
                f"`t` is {rec.t[np.argmax(bad)]} in row {row}; every sample needs a finite "
                "time in seconds",
            )
        return rec

    def close(self) -> None:
        for _, fh, _ in self._members:
            fh.close()
        self._members = []
        if getattr(self, "_zip", None) is not None:
            assert self._zip is not None
            self._zip.close()
        self._zip = None


def _npy_header(fh: IO[bytes]) -> tuple[tuple[int, ...], np.dtype]:
    version = np.lib.format.read_magic(fh)
    if version == (1, 0):
        shape, fortran, dtype = np.lib.format.read_array_header_1_0(fh)
    else:
        shape, fortran, dtype = np.lib.format.read_array_header_2_0(fh)
    return tuple(shape), np.dtype(dtype)


def _column_problem(shape: tuple[int, ...], dtype: np.dtype) -> str:
    """Why a stored array cannot be a column of numbers ('' when it can)."""
    if dtype.hasobject or dtype.kind not in "biuf" or dtype.fields is not None:
        return f"holds {dtype} values; expected numbers"
    if len(shape) != 1:
        return f"has shape {shape}; expected one value per sample, shape (k,)"
    return ""


def read_recording(
    path: str | Path,
    sensor_names: list[str],
    *,
    block_rows: int = BLOCK_ROWS,
    channel_names: list[str] | None = None,
) -> Recording:
    """Read a whole CSV or NPZ recording for a desk with ``sensor_names`` (and, for a desk
    of other than six-axis sensors, its ``channel_names``; through :class:`RecordingBlocks`;
    for long files prefer streaming the blocks)."""
    with RecordingBlocks(
        path, sensor_names, block_rows=block_rows, channel_names=channel_names
    ) as reader:
        return concat_recordings(list(reader.blocks()), sensor_names, channel_names)


def concat_recordings(
    parts: list[Recording], sensor_names: list[str], channel_names: list[str] | None = None
) -> Recording:
    """Blocks back into one recording; an extra column dropped in any block is dropped."""
    if not parts:
        width = len(needed_columns(sensor_names, channel_names)) - 1
        return Recording(np.zeros(0), np.zeros((0, width)), list(sensor_names), {}, channel_names)
    if len(parts) == 1:
        return parts[0]
    names = [n for n in parts[-1].extra if all(n in p.extra for p in parts)]
    return Recording(
        np.concatenate([p.t for p in parts]),
        np.concatenate([p.wrench for p in parts]),
        list(sensor_names),
        {n: np.concatenate([p.extra[n] for p in parts]) for n in names},
        parts[0].channel_names,
    )


def write_recording(path: str | Path, rec: Recording) -> None:
    """Write CSV (``%.9g``, enough for the sensors' resolution) or NPZ by the file's suffix."""
    path = Path(path)
    suffix = path.suffix.lower()
    cols = rec.columns()
    if suffix == ".npz":
        table = rec.table()
        columns: dict[str, np.ndarray] = {c: table[:, i] for i, c in enumerate(cols)}
        np.savez_compressed(path, **columns)  # type: ignore[arg-type]
    elif suffix == ".csv":
        with path.open("w", encoding="utf-8", newline="") as fh:
            fh.write(",".join(cols) + "\n")
            np.savetxt(fh, rec.table(), delimiter=",", fmt="%.10g")
    else:
        raise ConfigError(str(path), f"unknown recording format {suffix!r}; expected .csv or .npz")
