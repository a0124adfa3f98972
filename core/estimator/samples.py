"""Stage 1, bad samples and gaps: the 6·S channels in, flags and the resultant wrench out.

NaN or infinity, a saturated channel and a time that does not increase flag a sample, and the
last good wrench is held over it, so no filter state is poisoned; a time step longer than
``max_gap_s`` flags a gap (the filters restart there). Good samples become the resultant
wrench [F_o; M_o] about P_o by one linear map (paper eqs. 1–4).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from hapticdesk.estimator.contacts import FLAG_GAP, FLAG_NAN, FLAG_SATURATED, FLAG_TIME_BACK
from hapticdesk.estimator.settings import EstimatorSettings

BAD_SAMPLE = FLAG_NAN | FLAG_SATURATED | FLAG_TIME_BACK  # replaced by the last good sample
SQUARES_PIECE = 4096  # samples per piece of the range check (its squares stay in the cache)


@dataclass
class SampleState:
    """What the stage remembers between blocks."""

    last_t: float = -math.inf  # the time of the last good sample
    last_good: np.ndarray | None = None  # its wrench (6,)
    squares: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))  # scratch


class SampleStage:
    """Flags bad samples and gaps and maps the good ones to the resultant wrench."""

    def __init__(self, settings: EstimatorSettings) -> None:
        self.settings = settings
        self.state = SampleState(squares=np.empty((SQUARES_PIECE, len(settings.range_flat))))

    def process(self, t: np.ndarray, wrench: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Flags (k,) and the wrench (6, k) for ``t`` (k,), ``wrench`` (k, S, 6); a bad
        sample holds the last good wrench."""
        st = self.state
        k = len(t)
        flags = np.zeros(k, np.uint8)
        flat = wrench.reshape(k, -1)
        clean = self._in_range(flat)
        previous = st.last_t if st.last_t > -math.inf else t[0] - 1.0 / self.settings.sample_rate_hz
        steps = np.empty(k)  # time steps; NaN where a time is NaN
        steps[0] = t[0] - previous
        steps[1:] = t[1:] - t[:-1]
        if clean and steps.min() > 0:  # the common case: finite, in range, time increasing
            gap = steps > self.settings.user.max_gap_s
            if st.last_t == -math.inf:
                gap[0] = False  # the very first sample follows nothing
            if gap.any():
                flags[gap] = FLAG_GAP
            st.last_t = float(t[-1])
            with np.errstate(invalid="ignore", over="ignore"):
                raw = self.settings.wrench_map @ flat.T  # (6, k): paper eqs. (1)–(4)
            st.last_good = raw[:, -1].copy()
            return flags, raw
        return self._process_slowly(t, flat, flags)

    def process_one(self, t: float, wrench: np.ndarray) -> np.ndarray | None:
        """:meth:`process` for one sample that follows a good one within ``max_gap_s``: its
        wrench (6,), or None (state untouched) where the sample is bad or after a gap."""
        st = self.state
        if st.last_good is None or not (0.0 < t - st.last_t <= self.settings.user.max_gap_s):
            return None
        flat = wrench.reshape(-1)
        with np.errstate(over="ignore", invalid="ignore"):
            if not float(np.square(flat) @ self.settings.inv_range2) < 1.0:  # see _in_range
                return None
        st.last_t = t
        raw = self.settings.wrench_map @ flat  # (6,): paper eqs. (1)–(4)
        st.last_good = raw
        return raw

    def _in_range(self, flat: np.ndarray) -> bool:
        """Σ (channel / rating)² < 1 for every sample: proves no channel is saturated and all
        are finite. A fast first pass: only blocks where it fails are checked channel by
        channel. In pieces small enough that the squares stay in the CPU cache."""
        squares = self.state.squares
        for a in range(0, len(flat), len(squares)):
            piece = flat[a : a + len(squares)]
            sq = squares[: len(piece)]
            with np.errstate(over="ignore", invalid="ignore"):  # (NaN, overflow: not in range)
                np.square(piece, out=sq)
                if not (sq @ self.settings.inv_range2).max() < 1.0:
                    return False
        return True

    def _process_slowly(
        self, t: np.ndarray, flat: np.ndarray, flags: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """The checks sample by sample (vectorised) for a block with something wrong in it."""
        st = self.state
        finite = np.isfinite(flat).all(axis=1) & np.isfinite(t)
        flags[~finite] |= FLAG_NAN
        with np.errstate(invalid="ignore"):
            sat = (np.abs(flat) >= self.settings.range_flat).any(axis=1)
        flags[finite & sat] |= FLAG_SATURATED
        # time must increase: compare with the running maximum of earlier good times
        t_clean = np.where(finite, t, -np.inf)
        prev_max = np.maximum.accumulate(np.concatenate([[st.last_t], t_clean]))[:-1]
        flags[finite & (t <= prev_max)] |= FLAG_TIME_BACK
        good = flags == 0
        if good.any():
            good_t = t[good]
            before = np.concatenate([[st.last_t], good_t[:-1]])
            gap = (good_t - before) > self.settings.user.max_gap_s
            if st.last_t == -math.inf:
                gap[0] = False
            flags[np.flatnonzero(good)[gap]] |= FLAG_GAP
            st.last_t = float(good_t[-1])
        with np.errstate(invalid="ignore", over="ignore"):  # bad rows are replaced below
            raw = self.settings.wrench_map @ flat.T
        return flags, self._hold_last_good(raw, good)

    def _hold_last_good(self, raw: np.ndarray, good: np.ndarray) -> np.ndarray:
        """``raw`` (6, k) with each bad sample replaced by the last good one before it."""
        st = self.state
        index = np.where(good, np.arange(len(good)), -1)
        np.maximum.accumulate(index, out=index)
        held = index >= 0
        raw = np.where(held, raw[:, np.maximum(index, 0)], 0.0)
        if st.last_good is not None:
            raw[:, ~held] = st.last_good[:, None]
        elif good.any():  # bad samples before the first good one ever: back-fill it
            raw[:, ~held] = raw[:, np.flatnonzero(good)[0]][:, None]
        if good.any():
            st.last_good = raw[:, np.flatnonzero(good)[-1]].copy()
        return np.ascontiguousarray(raw)
