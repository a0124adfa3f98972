"""Recordings to and from files, the format chosen by the file's suffix from one table
(STYLE 22): :data:`READERS` and :data:`WRITERS` name the CSV module (:mod:`.recording_csv`)
and the NPZ module (:mod:`.recording_npz`). :class:`RecordingBlocks` streams a recording a
block at a time, so a replay's memory does not grow with the file; :func:`read_recording`
reads one whole, :func:`write_recording` writes one."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Protocol

import numpy as np

from hapticdesk.errors import ConfigError
from hapticdesk.files.recording import Recording, concat_recordings
from hapticdesk.files.recording_csv import CsvRecordingReader, write_csv
from hapticdesk.files.recording_npz import NpzRecordingReader, write_npz

BLOCK_ROWS = 16_384  # samples per block read: ~14 s at 1.2 kHz; ~25 MB to parse a CSV block


class BlockReader(Protocol):
    """A recording format's reader, opened on a file with its header checked."""

    def read(self, rows: int, done: int) -> Recording | None:
        """The next ``rows`` samples at most (``done`` handed out before), None at the end."""

    def close(self) -> None:
        """Release the file; safe to call more than once."""


#: suffix -> the reader of that format: ``(path, sensor_names, channel_names)``
READERS: dict[str, Callable[[Path, list[str], list[str] | None], BlockReader]] = {
    ".csv": CsvRecordingReader,
    ".npz": NpzRecordingReader,
}
#: suffix -> the writer of that format
WRITERS: dict[str, Callable[[Path, Recording], None]] = {".csv": write_csv, ".npz": write_npz}
RECORDING_SUFFIXES = tuple(READERS)


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
        suffix = self.path.suffix.lower()
        if suffix not in READERS:
            raise ConfigError(
                str(self.path),
                f"unknown recording format {suffix!r}; expected .csv or .npz "
                "(or a CAN log, see `hapticdesk record --help`)",
            )
        self._reader: BlockReader = READERS[suffix](self.path, self.sensor_names, channel_names)
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


def write_recording(path: str | Path, rec: Recording) -> None:
    """Write CSV (``%.10g``, enough for the sensors' resolution) or NPZ by the file's suffix."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in WRITERS:
        raise ConfigError(str(path), f"unknown recording format {suffix!r}; expected .csv or .npz")
    WRITERS[suffix](path, rec)
