"""Recordings: sample times and every sensor's six channels, as CSV or NPZ (DESIGN.md).

Header ``t`` then ``<sensor>_fx … <sensor>_mz`` for each sensor of the profile. Other columns
are kept as ``extra`` (the simulator's ground truth ``true_x, true_y, true_fn``) and otherwise
ignored. A missing column is an error that names it.
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hapticdesk.files.profile import AXES
from hapticdesk.files.yamlfile import ConfigError

RECORDING_SUFFIXES = (".csv", ".npz")


@dataclass
class Recording:
    """``t`` (k,) seconds; ``wrench`` (k, S, 6) per sensor in its own frame; extra columns."""

    t: np.ndarray
    wrench: np.ndarray
    sensor_names: list[str]
    extra: dict[str, np.ndarray] = field(default_factory=dict)

    def __post_init__(self) -> None:
        k = len(self.t)
        if self.wrench.shape != (k, len(self.sensor_names), 6):
            raise ValueError(
                f"wrench must have shape (k, S, 6) = ({k}, {len(self.sensor_names)}, 6), "
                f"found {self.wrench.shape}"
            )

    def __len__(self) -> int:
        return len(self.t)

    def columns(self) -> list[str]:
        return ["t"] + [f"{s}_{a}" for s in self.sensor_names for a in AXES] + list(self.extra)

    def table(self) -> np.ndarray:
        """All columns as one (k, C) float array in :meth:`columns` order."""
        parts = [self.t[:, None], self.wrench.reshape(len(self.t), -1)]
        parts += [np.asarray(v, dtype=float)[:, None] for v in self.extra.values()]
        return np.hstack(parts)


def _from_columns(
    names: list[str], data: dict[str, np.ndarray], sensor_names: list[str], where: str
) -> Recording:
    needed = ["t"] + [f"{s}_{a}" for s in sensor_names for a in AXES]
    missing = [c for c in needed if c not in data]
    if missing:
        shown = ", ".join(missing[:6]) + (
            f" and {len(missing) - 6} more" if len(missing) > 6 else ""
        )
        raise ConfigError(
            where, f"missing column(s) {shown}; the desk's sensors are {', '.join(sensor_names)}"
        )
    t = np.asarray(data["t"], dtype=float)
    wrench = (
        np.stack(
            [
                np.stack([np.asarray(data[f"{s}_{a}"], dtype=float) for a in AXES], axis=-1)
                for s in sensor_names
            ],
            axis=1,
        )
        if sensor_names
        else np.zeros((len(t), 0, 6))
    )
    extra = {n: np.asarray(data[n], dtype=float) for n in names if n not in needed}
    return Recording(t, wrench, list(sensor_names), extra)


def read_recording(path: str | Path, sensor_names: list[str]) -> Recording:
    """Read a CSV or NPZ recording for a desk with ``sensor_names``."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".npz":
        try:
            with np.load(path, allow_pickle=False) as npz:
                data = {k: npz[k] for k in npz.files}
        except (OSError, ValueError) as err:
            raise ConfigError(str(path), f"not a readable NPZ recording: {err}") from None
        return _from_columns(list(data), data, sensor_names, str(path))
    if suffix != ".csv":
        raise ConfigError(
            str(path),
            f"unknown recording format {suffix!r}; expected .csv or .npz "
            "(or a CAN log, see `hapticdesk record --help`)",
        )
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as err:
        raise ConfigError(str(path), f"cannot read: {err.strerror or err}") from None
    return parse_csv(text, sensor_names, str(path))


def parse_csv(text: str, sensor_names: list[str], where: str = "<csv>") -> Recording:
    """Parse CSV text; empty cells and ``nan`` become NaN (flagged later, not here)."""
    reader = csv.reader(io.StringIO(text))
    try:
        header = [h.strip() for h in next(reader)]
    except StopIteration:
        raise ConfigError(f"{where}:1", "empty file, expected a header starting with `t`") from None
    body = text.split("\n", 1)[1] if "\n" in text else ""
    if body.strip():
        try:
            table = np.loadtxt(
                io.StringIO(body),
                delimiter=",",
                ndmin=2,
                dtype=float,
                converters=lambda s: float(s) if s.strip() else np.nan,
            )
        except ValueError as err:
            raise ConfigError(where, f"a value is not a number: {err}") from None
        if table.shape[1] != len(header):
            raise ConfigError(where, f"rows have {table.shape[1]} values, the header {len(header)}")
    else:
        table = np.zeros((0, len(header)))
    data = {name: table[:, i] for i, name in enumerate(header)}
    return _from_columns(header, data, sensor_names, where)


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
