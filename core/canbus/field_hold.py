"""A lost frame's fields held from the samples before: a log with 5 % of its lines junk had
lost a frame in a third of its samples, and the NaN samples the estimator skips had refused
the tare for the whole run; a value one sample old is a truer sample than none. Held for a
few samples at most, the force sensors' fields only. Part of :mod:`.assembler`."""

from __future__ import annotations

import numpy as np

from hapticdesk.canbus.decoding import DeskDecoding


class FieldHold:
    """Each field's last value and how many samples ago it was read, carried from push to
    push, to fill the fields of a frame a sample lacks (:meth:`fill`)."""

    def __init__(self, decoding: DeskDecoding, hold_samples: int) -> None:
        #: a channel whose frame is missing from a sample takes its value from the samples
        #: before, for at most this many samples in a row (0: left NaN)
        self.hold_samples = hold_samples
        self._last_row = np.full(decoding.n_fields, np.nan)
        self._last_age = np.zeros(decoding.n_fields, dtype=np.int64)
        # only the force sensors' fields are held: a missing accelerometer reading stays NaN,
        # the estimator then flags that sample `no_accel` (the documented contract)
        self._holdable = np.zeros(decoding.n_fields, dtype=bool)
        force_readings = decoding.readings[: len(decoding.readings) - decoding.n_accelerometers]
        for reading in force_readings:
            self._holdable[reading.columns] = True

    def fill(self, table: np.ndarray) -> np.ndarray:
        """Fill, in place, each field a sample lacks (its frame was lost, doubled, or came
        with another counter) with the field's last value, when that is at most
        :attr:`hold_samples` samples old; returns where it did. Carried across pushes, so
        any split gives the same samples."""
        n = len(table)
        if self.hold_samples <= 0 or n == 0:
            return np.zeros(table.shape, dtype=bool)
        full = np.vstack([self._last_row[None, :], table])
        valid = ~np.isnan(full)
        rows = np.arange(n + 1)[:, None]
        last = np.maximum.accumulate(np.where(valid, rows, -1), axis=0)  # row of the last value
        # how old that value is, in samples: row 0 is the carried one, already _last_age old
        age = np.where(last > 0, rows - last, rows + self._last_age[None, :])
        fill = ~valid & (last >= 0) & (age <= self.hold_samples) & self._holdable[None, :]
        fill[0] = False
        columns = np.broadcast_to(np.arange(full.shape[1]), full.shape)
        full[fill] = full[np.maximum(last, 0)[fill], columns[fill]]
        table[:] = full[1:]
        held = fill[1:]
        read = valid[1:]
        # the carried value: each field's last real value and its age at the last sample
        seen = read.any(axis=0)
        last_real = n - 1 - np.argmax(read[::-1], axis=0)
        self._last_row = np.where(seen, table[last_real, np.arange(table.shape[1])], self._last_row)
        self._last_age = np.where(seen, n - 1 - last_real, self._last_age + n)
        return held
