"""An NPZ recording read a block at a time: one ``.npy`` member per column (``t`` and the
channels by name, as a CSV's header names them), each read in slices so no column is ever
loaded whole; every member's type and length checked when the file is opened. Written
with ``numpy.savez_compressed``."""

from __future__ import annotations

import zipfile
import zlib
from pathlib import Path
from typing import IO

import numpy as np

from hapticdesk.errors import ConfigError
from hapticdesk.files.file_safety import regular_file_size
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

#: the most members (columns) an NPZ recording may have, as many as a CSV's columns: 60,000
#: tiny extra columns took 3.4 GB (each read as a stream of its own)
MAX_NPZ_MEMBERS = MAX_COLUMNS


#: what a damaged or unusual zip raises as a member is read: an encrypted member or one of an
#: unsupported compression method is a RuntimeError (NotImplementedError), not an OSError
_NPZ_ERRORS = (OSError, ValueError, EOFError, RuntimeError, zipfile.BadZipFile, zlib.error)


class NpzRecordingReader:
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
            raise missing_columns_error(self.where, missing, sensor_names)
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
        k = min(rows_per_block(rows, len(self._members)), self.length - done)
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
        except ConfigError:  # (a ValueError too: said once, not wrapped in the message below)
            raise
        except _NPZ_ERRORS as err:
            raise ConfigError(self.where, f"not a readable NPZ recording: {err}") from None
        rec = recording_from_table(table, self.extra, self.sensor_names, self.channel_names)
        bad = bad_times(rec.t)
        if bad.any():
            row = done + int(np.argmax(bad)) + 1
            raise ConfigError(
                self.where, f"`t` is {rec.t[np.argmax(bad)]:g} in row {row}; {TIME_EXPECTED}"
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


def write_npz(path: Path, rec: Recording) -> None:
    """``rec`` as NPZ: one compressed member per column, named as a CSV's header names it."""
    table = rec.table()
    columns: dict[str, np.ndarray] = {c: table[:, i] for i, c in enumerate(rec.columns())}
    np.savez_compressed(path, **columns)  # type: ignore[arg-type]
