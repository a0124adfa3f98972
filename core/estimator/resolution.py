"""The sensors' resolution, learned from their readings: each channel's smallest change.

A sensor reports in steps (an ADC count times a scale; 1/2000 of the rating for the paper's
sensors, Table 2). Where its noise is well below one step, the noise measured at the tare
misses two errors: at rest a channel sits on one step, so the tare sees almost no noise,
though a reading in motion is off by up to half a step (variance step²/12, and slow: a force
that changes by less than a step per sample keeps its rounding error for many samples, so
the low-pass does not average it away); and the zero itself is off by up to half a step on
every channel for as long as it is kept. Where the noise is a step or more it dithers the
rounding: the measured noise already holds the step²/12 and the tare's mean is true.
:func:`rounding_deficit` is the part of the rounding the measured noise lacks.

A channel's step is the smallest non-zero change between two consecutive good readings:
readings on a grid change by whole steps. Readings off a grid (floats, a CSV with many
decimals, the gauges of a sensor decoded through its calibration matrix) change by far less
than their noise, so their "step" adds nothing. A channel stops learning after
``CONFIRM_CHANGES`` changes; a quiet one learns its step at the first touches (until then it
has none, 0).

Measured (``python scripts/tap_accuracy.py --desk paper --noise N``, 1,000 edge taps): a
sensor whose noise no longer dithers its steps (below about 0.3 N on the paper desk's total
F_z) placed taps from the zero's offset and the differentiated force's rounding with a
confidence they did not have; see docs/stability.md.
"""

from __future__ import annotations

import numpy as np

# changes a channel's smallest change is taken over before it counts as its step: a quiet
# channel pressed quickly moves by several steps at a time at first, a held press by one
CONFIRM_CHANGES = 200
PIECE = 4096  # readings a block is learned from at a time
# a step that shrank by more than this share since the covariances were made remakes them
STEP_CHANGE = 0.1


class Resolution:
    """Learns each channel's step from the good readings, in order."""

    def __init__(self, n_channels: int) -> None:
        self.step = np.zeros(n_channels)  # (6S,) the smallest change so far; 0: none yet
        self.changes = np.zeros(n_channels, np.int64)  # changes seen per channel
        self.learning = np.arange(n_channels)  # the channels still learning their step
        self.last: np.ndarray | None = None  # the last good reading (6S,)
        self.used = np.zeros(n_channels)  # the steps the covariances were last made with
        self.dirty = False  # a step changed since :meth:`changed` last looked

    def observe(self, rows: np.ndarray) -> None:
        """Good readings (k, 6S), in order, following those observed before."""
        if len(self.learning) == 0 or len(rows) == 0:
            return
        last = rows[0] if self.last is None else self.last
        # in pieces: a noisy channel confirms its step in its first few hundred readings,
        # and a long block is not read whole for it
        for a in range(0, len(rows), PIECE):
            cols = self.learning
            if len(cols) == 0:
                break
            piece = rows[a : a + PIECE, cols]
            before = last[cols] if a == 0 else rows[a - 1, cols]
            self._learn(cols, np.abs(np.diff(piece, axis=0, prepend=before[None, :])))
        self.last = rows[-1].copy()

    def observe_one(self, row: np.ndarray) -> None:
        """One good reading (6S,) following those observed before."""
        cols = self.learning
        if len(cols) == 0:
            return
        last, self.last = self.last, row.copy()
        if last is not None:
            self._learn(cols, np.abs(row[cols] - last[cols])[None, :])

    def _learn(self, cols: np.ndarray, change: np.ndarray) -> None:
        """``change`` (k, len(cols)): the readings' absolute changes on the learning channels."""
        moved = change > 0  # (a NaN never reaches here: good readings only)
        if not moved.any():
            return
        smallest = np.where(moved, change, np.inf).min(axis=0)
        step = self.step[cols]
        now = np.where(step > 0, np.minimum(step, smallest), smallest)
        now[np.isinf(now)] = 0.0  # (not changed yet)
        if (now != step).any():
            self.step[cols] = now
            self.dirty = True
        self.changes[cols] += moved.sum(axis=0)
        self.learning = cols[self.changes[cols] < CONFIRM_CHANGES]

    def changed(self) -> bool:
        """Whether a step is new or has shrunk by over ``STEP_CHANGE`` since the last call
        that returned True (``used``, the steps the covariances are made with, then)."""
        if not self.dirty:
            return False
        self.dirty = False
        new = (self.used == 0) & (self.step > 0)
        shrunk = self.step < self.used * (1.0 - STEP_CHANGE)
        if not (new.any() or shrunk.any()):
            return False
        self.used = self.step.copy()
        return True


def rounding_deficit(wrench_map: np.ndarray, step: np.ndarray, measured: np.ndarray) -> np.ndarray:
    """The part of the rounding's covariance (6, 6) the ``measured`` noise (6, 6) lacks: the
    positive part of M diag(step²/12) Mᵀ − measured. Nothing where the noise dithers the
    rounding (the rounding is then in the measured noise), all of it where the channels sat
    on one step at the tare."""
    rounding = wrench_map @ (wrench_map.T * (step**2 / 12.0)[:, None])
    gap = rounding - measured
    values, vectors = np.linalg.eigh((gap + gap.T) / 2.0)
    return (vectors * np.clip(values, 0.0, None)) @ vectors.T
