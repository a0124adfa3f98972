"""A CSV recording read a block at a time: the header checked when the file is opened, each
block parsed by a compiled parser of plain numbers (:mod:`.csv_numbers`, where numba is
loaded: from the bytes read, up to a line that is not plain) or, as lines
(:mod:`.recording_lines`), by numpy's C reader, every fault named at its file:line:column;
and written back with ``%.10g``."""

from __future__ import annotations

import csv
import re
import sys
from pathlib import Path
from typing import BinaryIO

import numpy as np

from hapticdesk.errors import ConfigError
from hapticdesk.files.file_safety import regular_file_size
from hapticdesk.files.profile import ACCEL_COLUMN
from hapticdesk.files.recording import (
    MAX_COLUMNS,
    TIME_EXPECTED,
    Recording,
    bad_times,
    missing_columns_error,
    needed_columns,
    recording_from_table,
    rows_per_block,
)
from hapticdesk.files.recording_lines import MAX_BLOCK_CHARS, MAX_LINE_CHARS, RecordingLines

_EMPTY_CELL = re.compile(r"(?m)(?:^|(?<=,))[ \t]*(?=,)|(?<=,)[ \t]*$")


def _line_of_error(err: ConfigError, first_line: int, count: int) -> int | None:
    """The file line a reading error names, when it is one of the ``count`` lines from
    ``first_line`` on (``file:line`` or ``file:line:column``)."""
    found = re.search(r":(\d+)(?::\d+)?$", str(err.where))
    if found is None:
        return None
    line = int(found.group(1))
    return line if first_line <= line < first_line + count else None


def _separator_hint(header: list[str]) -> str:
    """A hint for a header read as one column that other separators split (a file of
    tabs or semicolons was told only which columns it lacked)."""
    if len(header) != 1:
        return ""
    for separator, name in (("\t", "tabs"), (";", "semicolons")):
        if len(header[0].split(separator)) > 2:
            return (
                f" (its header is one column: are its values separated by {name}? expected commas)"
            )
    return ""


def _data_line_offsets(lines: list[str]) -> list[int]:
    """Offsets of the lines numpy reads as rows (it skips empty ones); for error messages."""
    return [j for j, line in enumerate(lines) if line.strip("\r\n")]


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


class CsvRecordingReader:
    """One CSV recording, open, its header checked; :meth:`read` hands out its samples."""

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
        self._lines = RecordingLines(self._fh, self.where)
        try:
            self.header = self._read_header()
            needed = needed_columns(sensor_names, channel_names)
            seen = {name: i for i, name in enumerate(self.header)}
            missing = [c for c in needed if c not in seen]
            if missing:
                error = missing_columns_error(f"{self.where}:1", missing, sensor_names)
                raise ConfigError(error.where, error.message + _separator_hint(self.header))
        except BaseException:
            self.close()
            raise
        self.needed_index = [seen[c] for c in needed]
        # other named columns are kept as extras while they hold numbers, else ignored
        self.extra = [(n, i) for i, n in enumerate(self.header) if n and n not in needed]

    def _read_header(self) -> list[str]:
        """The first line's column names, each named once."""
        first = self._lines.take_line()  # (the lines after it left as bytes, if plain)
        if first is None:
            head = self._lines.take(1)
            first = head[0] if head else ""
        if not first.strip():
            raise ConfigError(f"{self.where}:1", "empty file, expected a header starting with `t`")
        header = [h.strip() for h in self._cells(first, 1)]
        if len(header) > MAX_COLUMNS:  # (before a block of them is parsed and kept)
            raise ConfigError(
                f"{self.where}:1:{MAX_COLUMNS + 1}",
                f"{len(header):,} columns; a recording has one per channel (time, the desk's "
                f"channels, a few more): at most {MAX_COLUMNS:,} are read",
            )
        seen: dict[str, int] = {}
        for i, name in enumerate(header):
            if name and name in seen:
                raise ConfigError(
                    f"{self.where}:1:{i + 1}",
                    f"column `{name}` appears twice (columns {seen[name] + 1} and {i + 1})",
                )
            seen[name] = i
        return header

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
        rows = rows_per_block(rows, len(self.header))
        table = self._plain_ahead(rows)
        if table is not None:
            return self._recording(self._in_order(table))
        first_line = self._lines.line + 1
        lines = [] if self._lines.exhausted else self._lines.take(rows)
        if not lines:
            failure = self._lines.take_failure()
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
                self._lines.fail_after(err)

    def _parse(self, lines: list[str], first_line: int) -> Recording:
        """The samples of ``lines`` (file lines from ``first_line`` on); ConfigError at the
        first bad one."""
        table = self._parse_plain(lines)
        if table is None:
            table = self._parse_careful(lines, first_line)
        rec = self._recording(table)
        bad = bad_times(rec.t)
        if bad.any():
            i = int(np.argmax(bad))
            offset = _data_line_offsets(lines)[i]
            column = self.needed_index[0]
            cells = self._cells(lines[offset], first_line + offset)
            cell = cells[column].strip() if column < len(cells) else ""
            raise ConfigError(
                f"{self.where}:{first_line + offset}:{column + 1}",
                f"`t` is {cell or 'empty'!r}; {TIME_EXPECTED}",
            )
        return rec

    def _recording(self, table: np.ndarray) -> Recording:
        """The samples of a table in :func:`~.recording.recording_from_table` order."""
        extra_names = [n for n, _ in self.extra]
        return recording_from_table(table, extra_names, self.sensor_names, self.channel_names)

    def _in_order(self, table: np.ndarray) -> np.ndarray:
        """A table of every column in :func:`~.recording.recording_from_table` order."""
        usecols = self.needed_index + [i for _, i in self.extra]
        return table if usecols == list(range(len(self.header))) else table[:, usecols]

    def _plain_ahead(self, rows: int) -> np.ndarray | None:
        """Up to ``rows`` next lines' table (every column) parsed straight from the bytes
        read, where numba is loaded (:func:`.csv_numbers.plain_rows`), as long as they are
        plain numbers, as many as the header's columns, with a time it may hold; None when the
        next line is not (the lines are then read as text, and any fault named). (The
        minute's 72,000 lines: no line decoded, split, joined and encoded again.)"""
        width = len(self.header)
        # (a line it reads is at most 27 characters a cell: never one too long to read)
        if "numba" not in sys.modules or 27 * width > MAX_LINE_CHARS:
            return None
        from hapticdesk.files.csv_numbers import plain_rows

        # (a block's lines hold at most MAX_BLOCK_CHARS, as read as text; a line here is at
        # least two characters a cell)
        rows = min(rows, MAX_BLOCK_CHARS // (2 * width) + 1)
        table, done = np.empty((rows, width)), 0
        while done < rows:
            ahead = self._lines.read_ahead(256 * (rows - done))
            if not ahead:
                break
            parsed, used = plain_rows(ahead, width, self.needed_index[0], table[done:])
            self._lines.took(parsed, used)
            done += parsed
            if used < len(ahead):  # (the table is full, or the next line is not plain)
                break
        return table[:done] if done else None

    def _parse_plain(self, lines: list[str]) -> np.ndarray | None:
        """The block's table (:func:`~.recording.recording_from_table` order) when every line
        is plainly numeric and as wide as the header: read by the compiled parser of plain
        numbers where numba is loaded already (:mod:`.csv_numbers`: the same floats, a third
        of the time), else (or where it leaves the block) one ``np.loadtxt`` of every column,
        which itself refuses
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
        width = len(self.header)
        table = None
        if "numba" in sys.modules:  # (loaded to estimate: the compiled parser imports nothing)
            from hapticdesk.files.csv_numbers import plain_numbers

            table = plain_numbers(lines, width)
        if table is None:
            table = self._loadtxt(lines)
        if table is None or table.shape[1] != width:  # (a trailing comma: read carefully)
            return None
        return self._in_order(table)

    def _loadtxt(self, lines: list[str]) -> np.ndarray | None:
        """Every column of ``lines`` by numpy's parser; None at anything it refuses."""
        try:
            return np.loadtxt(
                lines,
                delimiter=",",
                ndmin=2,
                dtype=float,
                comments=None,
                # (numpy's parser is 10-15 % faster without looking for quotes)
                quotechar='"' if self._lines.quoted else None,
            )
        except ValueError:
            return None

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
            # other columns are ignored (docs: File formats): a text column is not an error; but an
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


def write_csv(path: Path, rec: Recording) -> None:
    """``rec`` as CSV: the header, then one line per sample (``%.10g``, enough for the
    sensors' resolution)."""
    with path.open("w", encoding="utf-8", newline="") as fh:
        fh.write(",".join(rec.columns()) + "\n")
        np.savetxt(fh, rec.table(), delimiter=",", fmt="%.10g")
