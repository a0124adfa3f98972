"""Recordings: sample times and every sensor's raw channels, as CSV or NPZ (docs: File formats).

Header ``t`` then each sensor's channels, ``<sensor>_<channel>``, in the profile's order:
``<sensor>_fx … <sensor>_mz`` for a six-axis sensor, ``<sensor>_fz`` for a load cell, a
calibrated sensor's own channel names (:meth:`DeskProfile.channel_names`). Other columns
are kept as ``extra`` (the simulator's ground truth ``true_x, true_y, true_fn``, a desk's
accelerometers' ``acc_x, acc_y, acc_z``, ``acc2_x``, …) and otherwise ignored (text ones too,
except the accelerometers', whose bad cells are errors). A missing column is an error that names it.

This module is the model; files are read and written by :mod:`.recording_io`, which picks
the CSV (:mod:`.recording_csv`) or NPZ (:mod:`.recording_npz`) module by the file's suffix.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from hapticdesk.errors import ConfigError
from hapticdesk.files.profile import ACCEL_COLUMN, AXES

#: the largest sample time a recording may hold, seconds since 1970: 9999-12-31 00:00 UTC (a
#: day short of the last date Python has, for the local time zone), a CAN log's too
#: (canbus.logs.skipped). One beyond it is no clock's: a time of 1e300 in one row took every
#: sample after it for one that went back in time
MAX_TIME_S = 253_402_214_400.0
#: the most columns a recording (CSV or NPZ) may have: every one is kept (an extra as
#: ``extra``), so its width sets the memory a sample takes (a 164 MB CSV of 4,000 columns:
#: 457 MB to estimate from; the fuzzing pass saw 1.38 GB). A 40-sensor desk of six-axis
#: sensors has 241, its accelerometers and the simulator's truth a few more
MAX_COLUMNS = 1024
#: the most values a block read holds (samples × columns, 8 MB as floats): 16,384 samples
#: up to 64 columns, fewer of a wider file, so a replay's memory does not grow with the width
#: (a 164 MB CSV of 1,024 columns: 360 MB resident when a block was 16,384 samples whatever
#: its width)
MAX_BLOCK_VALUES = 16_384 * 64
#: what a bad time is told
TIME_EXPECTED = f"every sample needs a finite time in seconds, within ±{MAX_TIME_S:.0f} (year 9999)"


def bad_times(t: np.ndarray) -> np.ndarray:
    """Where the times ``t`` are not finite or beyond :data:`MAX_TIME_S` (bool, like ``t``)."""
    return ~(np.abs(t) <= MAX_TIME_S)


def rows_per_block(rows: int, width: int) -> int:
    """At most ``rows`` samples of ``width`` columns, and no more than
    :data:`MAX_BLOCK_VALUES` values (at least one sample)."""
    return max(1, min(rows, MAX_BLOCK_VALUES // max(1, width)))


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


def needed_columns(sensor_names: list[str], channel_names: list[str] | None = None) -> list[str]:
    """The columns a recording for ``sensor_names`` must have, in order: ``t``, then
    ``channel_names`` (default: six per sensor, ``<sensor>_fx … _mz``)."""
    return ["t"] + (six_axis_columns(sensor_names) if channel_names is None else channel_names)


def missing_columns_error(where: str, missing: list[str], sensor_names: list[str]) -> ConfigError:
    """The error for a recording without the columns ``missing`` (the first six named)."""
    shown = ", ".join(missing[:6]) + (f" and {len(missing) - 6} more" if len(missing) > 6 else "")
    return ConfigError(
        where, f"missing column(s) {shown}; the desk's sensors are {', '.join(sensor_names)}"
    )


def recording_from_table(
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
