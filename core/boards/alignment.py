"""Channels sampled at their own moments, brought to the sample's time before the desk's map.

Four HX711 chips convert on four clocks; an ADS1256 reads four bridges one after the other,
~229 µs apart at its fastest (its datasheet's table 14: 4,374 channel readings a second).
While the force changes, channels read apart disagree — a tap's 100 N/s read 6 ms apart on
two legs is 0.6 N, centimetres at a finger's 2–5 N (docs/serial.md) — and the disagreement
is a false moment. So channel ``j`` of a sample stamped ``t``, read at ``t + offset_j``, is
replaced by its value at ``t``, interpolated linearly between its previous reading (at
``t_prev + offset_prev_j``) and this one. Only between two readings of the same epoch with
no gap between them: the first sample of an epoch or after a gap is given as read (counted
as unaligned), and nothing is ever extrapolated. A channel with offset 0 is given as read.
"""

from __future__ import annotations

import numpy as np

US = 1e-6


class ChannelAligner:
    """Streams samples ``(t, values, offsets_us)`` to values at ``t`` (module docstring).
    The same output whatever the split of the stream into blocks."""

    def __init__(self, n_channels: int) -> None:
        self._t = np.nan  # the previous sample's time
        self._values = np.full(n_channels, np.nan)
        self._offsets = np.zeros(n_channels)
        self.unaligned = 0  # samples given as read, for want of an earlier one

    def align(
        self, t: np.ndarray, values: np.ndarray, offsets_us: np.ndarray, fresh: np.ndarray
    ) -> np.ndarray:
        """Values (k, C) at the times ``t`` (k,): ``values`` read at ``t + offsets_us`` (k, C);
        ``fresh`` (k,) True where a sample has no earlier one to interpolate from."""
        k = len(t)
        if k == 0:
            return values
        read_at = t[:, None] + offsets_us * US
        before_t = np.concatenate([[self._t], t[:-1]])
        before_v = np.concatenate([self._values[None], values[:-1]])
        before_at = np.concatenate([(self._t + self._offsets * US)[None], read_at[:-1]])
        self._t, self._values = float(t[-1]), values[-1].copy()
        self._offsets = offsets_us[-1].copy()
        span = read_at - before_at
        usable = (
            ~fresh[:, None] & np.isfinite(before_v) & (span > 0) & np.isfinite(before_t)[:, None]
        )
        with np.errstate(invalid="ignore", divide="ignore"):
            weight = np.clip((t[:, None] - before_at) / span, 0.0, 1.0)
        aligned = np.where(usable, before_v + weight * (values - before_v), values)
        moved = (offsets_us != 0).any(axis=1)
        self.unaligned += int((moved & ~usable.all(axis=1)).sum())
        return aligned
