"""Stage 1, bad samples and gaps: the 6·S channels in, flags and the resultant wrench out.

NaN or infinity, a saturated channel, a time that does not increase and a stuck input flag a
sample, and the last good wrench is held over it, so no filter state is poisoned; a time step
between good samples longer than ``max_gap_s`` flags a gap (the filters restart there). Good
samples become the resultant wrench [F_o; M_o] about P_o by one linear map (paper eqs. 1–4).

A stuck input is a driver that repeats its last sample: every channel bit-identical to the
sample before, from the ``STUCK_RUN``-th repeat in a row on, with a notice when it sticks and
when it has been live again for ``LIVE_AGAIN_S``. A noisy sensor hardly ever repeats all its
6·S channels exactly (the simulator with the paper's noise, below one step of resolution on
most channels: twice in 105,617 samples, never twice in a row), but a noise-free one does all
the time (the simulator's ideal mode, a sensor quieter than its resolution): the check is on
only for an input with fewer than ``NOISE_FREE_REPEATS`` exact repeats in its first
``NOISE_CHECK_S``.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

import numpy as np

from hapticdesk.estimator.contacts import (
    FLAG_GAP,
    FLAG_NAN,
    FLAG_SATURATED,
    FLAG_STUCK,
    FLAG_TIME_BACK,
)
from hapticdesk.estimator.notices import Notice, add_notice, log
from hapticdesk.estimator.resolution import Resolution
from hapticdesk.estimator.settings import EstimatorSettings

BAD_SAMPLE = FLAG_NAN | FLAG_SATURATED | FLAG_TIME_BACK | FLAG_STUCK  # replaced by the last good
SQUARES_PIECE = 4096  # samples per piece of the range check (its squares stay in the cache)
STUCK_RUN = 5  # this many repeats of a sample in a row (and more) are a stuck input
NOISE_CHECK_S = 0.2  # an input with NOISE_FREE_REPEATS exact repeats this early is noise-free
NOISE_FREE_REPEATS = 3  # ... and has no stuck check
LIVE_AGAIN_S = 1.0  # a stuck input is live again after this long unstuck (bounds the notices)
# Candidates for a repeat are the samples whose Σ (channel / rating)² is within this of the
# one before: the same row's sum differs by a few ulps with its place in a block (the BLAS
# kernels round in another order; < 1e-13 for sums below 100, i.e. below 10× the ratings), a
# noisy row's by far more.
SAME_ENERGY = 1e-12


@dataclass
class SampleState:
    """What the stage remembers between blocks."""

    last_t: float = -math.inf  # the time of the last good sample
    last_good: np.ndarray | None = None  # its wrench (6,)
    squares: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))  # scratch
    steps: np.ndarray = field(default_factory=lambda: np.zeros(0))  # scratch
    previous: np.ndarray | None = None  # the last input sample (6S,), bad or good
    previous_energy: float = math.nan  # its Σ (channel / rating)²
    seen: int = 0  # input samples so far, up to the end of the noise check
    seen_repeats: int = 0  # exact repeats among them
    stuck_check: bool | None = None  # the stuck check is on; None: still deciding
    repeats: int = 0  # how many times in a row the last sample repeated the one before
    live: int = 0  # samples since the last stuck one (at most the stage's live_n)
    stuck_since: float = math.nan  # the first stuck sample of the current (or last) spell
    last_stuck_t: float = math.nan  # the last stuck sample
    time_back: int = 0  # samples whose time was not after an earlier one's, so far


class SampleStage:
    """Flags bad samples and gaps and maps the good ones to the resultant wrench."""

    def __init__(self, settings: EstimatorSettings, notices: list[Notice]) -> None:
        self.settings = settings
        self.notices = notices
        fs = settings.sample_rate_hz
        self.check_n = max(STUCK_RUN + 1, round(NOISE_CHECK_S * fs))
        self.live_n = max(1, round(LIVE_AGAIN_S * fs))
        self.state = SampleState(
            squares=np.empty((SQUARES_PIECE, len(settings.range_flat))),
            steps=np.empty(SQUARES_PIECE),
            live=self.live_n,
        )
        self.resolution = Resolution(len(settings.range_flat))  # each channel's step

    def process(self, t: np.ndarray, wrench: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Flags (k,) and the wrench (6, k) for ``t`` (k,), ``wrench`` (k, S, 6); a bad
        sample holds the last good wrench."""
        st = self.state
        k = len(t)
        flags = np.zeros(k, np.uint8)
        flat = wrench.reshape(k, -1)
        energy = np.empty(k)
        # first, so that its notices come before the stuck check's, however the input is cut
        back = self._time_back(t, flat)
        clean, near = self._in_range(flat, energy)
        if near is not None:  # (None: a noise-free input, see the module docstring)
            if len(near) == 0 and st.stuck_check and st.live >= self.live_n:
                # the common case, live input and nothing that might repeat: what
                # :meth:`_stuck` would do, without its calls (a short block's cost)
                st.previous, st.previous_energy = flat[-1].copy(), float(energy[-1])
                st.repeats = 0
            else:
                stuck = self._stuck(t, flat, energy, near)
                if stuck is not None:
                    flags[stuck] = FLAG_STUCK
                    clean = False
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
            self.resolution.observe(flat)
            with np.errstate(invalid="ignore", over="ignore"):
                raw = self.resultant(flat)
            st.last_good = raw[:, -1].copy()
            return flags, raw
        return self._process_slowly(t, flat, flags, back)

    def process_one(self, t: float, wrench: np.ndarray) -> np.ndarray | None:
        """:meth:`process` for one good sample that follows a good one within ``max_gap_s``
        while the input is not stuck: its wrench (6,), or None (state untouched) where the
        sample needs the block path (bad, after a gap, maybe a repeat)."""
        st = self.state
        if st.last_good is None or not (0.0 < t - st.last_t <= self.settings.user.max_gap_s):
            return None
        if st.stuck_check is None or st.live < self.live_n:
            return None  # the noise check, or a stuck spell not yet over: the block path
        flat = wrench.reshape(-1)
        with np.errstate(over="ignore", invalid="ignore"):
            energy = float(np.square(flat) @ self.settings.inv_range2)
        if not energy < 1.0:  # see _in_range
            return None
        if st.stuck_check:
            # an energy about the one before: compared channel by channel, as the block path
            # does; only a true repeat needs it (to count the run). A quantised, quiet input
            # meets the energy test a few times a second, which took the block path each time
            previous = st.previous
            if (
                abs(energy - st.previous_energy) <= SAME_ENERGY
                and previous is not None
                and np.array_equal(flat, previous)
            ):
                return None
            st.previous, st.previous_energy, st.repeats = flat.copy(), energy, 0
        st.last_t = t
        self.resolution.observe_one(flat)
        raw = self.settings.wrench_map @ flat  # (6,): paper eqs. (1)–(4)
        st.last_good = raw
        return raw

    def resultant(self, flat: np.ndarray) -> np.ndarray:
        """[F_o; M_o] (6, k) of the stacked channels ``flat`` (k, 6S), paper eqs. (1)–(4): as
        (k, 6S) @ (6S, 6) viewed transposed, which BLAS does in half the time of
        (6, 6S) @ (6S, k) on the rows as given."""
        return (flat @ self.settings.wrench_map_t).T

    def _in_range(self, flat: np.ndarray, energy: np.ndarray) -> tuple[bool, np.ndarray | None]:
        """Σ (channel / rating)² < 1 for every sample: proves no channel is saturated and all
        are finite. A fast first pass: only blocks where it fails are checked channel by
        channel. In pieces small enough that the squares stay in the CPU cache. The sums go
        to ``energy`` (k,); while a piece is in the cache, the samples whose sum is within
        ``SAME_ENERGY`` of the one before are found too (candidates for a repeat, see
        :meth:`_repeat_runs`; None while the stuck check is off). Returns both."""
        st = self.state
        squares, steps = st.squares, st.steps
        look = st.stuck_check is not False
        clean, found = True, []
        for a in range(0, len(flat), len(squares)):
            piece = flat[a : a + len(squares)]
            n = len(piece)
            sq, e = squares[:n], energy[a : a + n]
            with np.errstate(over="ignore", invalid="ignore"):  # (NaN, overflow: not in range)
                np.square(piece, out=sq)
                np.matmul(sq, self.settings.inv_range2, out=e)
                clean = clean and bool(e.max() < 1.0)
                if look:
                    step = steps[:n]
                    if a:
                        np.subtract(e, energy[a - 1 : a - 1 + n], out=step)
                    else:
                        step[0] = e[0] - st.previous_energy
                        np.subtract(e[1:], e[:-1], out=step[1:])
                    np.abs(step, out=step)
                    if np.fmin.reduce(step) <= SAME_ENERGY:  # (fmin: a NaN is never near)
                        found.append(np.flatnonzero(step <= SAME_ENERGY) + a)
        if not look:
            return clean, None
        return clean, np.concatenate(found) if found else np.zeros(0, np.intp)

    def _stuck(
        self, t: np.ndarray, flat: np.ndarray, energy: np.ndarray, near: np.ndarray
    ) -> np.ndarray | None:
        """Where the input is stuck (k,) bool, or None where it is nowhere; tells when it
        sticks and when it is live again. ``near``: the candidates for a repeat. Before
        that, the noise check decides whether to look at all (see the module docstring)."""
        st = self.state
        start = 0
        if st.stuck_check is None:
            start = self._check_noise(flat)
            if not st.stuck_check or start == len(flat):
                st.previous, st.previous_energy = flat[-1].copy(), float(energy[-1])
                return None
            st.previous, st.previous_energy = flat[start - 1].copy(), float(energy[start - 1])
        if start:
            near = near[near >= start] - start
        stuck = self._repeat_runs(flat[start:], energy[start:], near)
        self._tell(t[start:], stuck)
        if stuck is None or start == 0:
            return stuck
        return np.concatenate([np.zeros(start, bool), stuck])

    def _check_noise(self, flat: np.ndarray) -> int:
        """The noise check over the input's first ``check_n`` samples: ``NOISE_FREE_REPEATS``
        exact repeats turn the stuck check off, fewer turn it on. Returns where the check ends
        in this block."""
        st = self.state
        m = min(len(flat), self.check_n - st.seen)
        rows = flat[:m]
        st.seen_repeats += int(np.count_nonzero((rows[1:] == rows[:-1]).all(axis=1)))
        if st.previous is not None and m:
            st.seen_repeats += int((rows[0] == st.previous).all())
        st.seen += m
        if st.seen_repeats >= NOISE_FREE_REPEATS:
            st.stuck_check = False
            log.info("the input repeats samples exactly (noise-free): no stuck-input check")
        elif st.seen >= self.check_n:
            st.stuck_check = True
        return m

    def _repeat_runs(
        self, flat: np.ndarray, energy: np.ndarray, at: np.ndarray
    ) -> np.ndarray | None:
        """Where the input is stuck (k,) bool, or None: the samples that repeat the one before
        them bit for bit, from the ``STUCK_RUN``-th repeat in a row on. Only the candidates
        ``at`` (their energy about that of the one before) are compared channel by channel."""
        st = self.state
        k = len(flat)
        if k == 0:
            return None
        previous = st.previous
        st.previous, st.previous_energy = flat[-1].copy(), float(energy[-1])
        if len(at) == 0:  # the common case: nothing repeats
            st.repeats = 0
            return None
        before = flat[np.maximum(at - 1, 0)]
        if at[0] == 0:
            assert previous is not None  # (an energy was remembered with it)
            before[0] = previous
        repeats = at[(flat[at] == before).all(axis=1)]  # (few: a noisy input hardly repeats)
        carried, st.repeats = st.repeats, 0
        if len(repeats) == 0:
            return None
        # the repeats in a row up to each repeat, on the few repeats: runs of consecutive
        # indices, the first carried over from the block before where it starts the block
        starts = np.flatnonzero(np.diff(repeats, prepend=-2) != 1)
        lengths = np.diff(starts, append=len(repeats))
        run = np.arange(1, len(repeats) + 1) - np.repeat(starts, lengths)
        if repeats[0] == 0:
            run[: (starts[1] if len(starts) > 1 else len(run))] += carried
        if repeats[-1] == k - 1:
            st.repeats = int(run[-1])
        at_stuck = repeats[run >= STUCK_RUN]
        if len(at_stuck) == 0:
            return None
        stuck = np.zeros(k, bool)
        stuck[at_stuck] = True
        return stuck

    def _tell(self, t: np.ndarray, stuck: np.ndarray | None) -> None:
        """A notice where the input sticks, and one where it has been unstuck for ``live_n``
        samples (a spell ends there: at most one pair of notices per ``LIVE_AGAIN_S``)."""
        st, n, k = self.state, self.live_n, len(t)
        if stuck is None:
            if st.live < n:
                if n - st.live - 1 < k:
                    self._live_again(float(t[n - st.live - 1]))
                st.live = min(n, st.live + k)
            return
        index = np.arange(k)
        last_stuck = np.maximum.accumulate(np.where(stuck, index, -1))
        live = index - last_stuck  # samples since the last stuck one
        live[last_stuck < 0] += st.live  # (carried over from the block before)
        before = np.concatenate([[st.live], live[:-1]])
        sticks = np.flatnonzero(stuck & (before >= n))
        again = np.flatnonzero(live == n)
        for i in sorted([*sticks.tolist(), *again.tolist()]):  # a few spells, not samples
            if stuck[i]:
                st.stuck_since = float(t[i])
                add_notice(
                    self.notices,
                    st.stuck_since,
                    "stuck",
                    f"the input is stuck: every channel repeated one sample {STUCK_RUN} times; "
                    "its samples are flagged and skipped until it changes (a hung driver?)",
                    logging.WARNING,
                )
            else:
                if i >= n:
                    st.last_stuck_t = float(t[i - n])
                self._live_again(float(t[i]))
        st.live = min(n, int(live[-1]))
        st.last_stuck_t = float(t[last_stuck[-1]])  # (there is a stuck sample)

    def _tell_time_back(self, t: np.ndarray, latest: np.ndarray, back: np.ndarray) -> None:
        """A notice at the 1st, 10th, 100th… sample whose time is not after an earlier one's:
        a recording whose time runs backwards or stands still had ended with no contact and
        only "tare refused" to say why; a log with the odd repeated time stamp says it a few
        times, not at every one."""
        st = self.state
        before, st.time_back = st.time_back, st.time_back + len(back)
        for mark in (m for m in (10**e for e in range(19)) if before < m <= st.time_back):
            i = int(back[mark - before - 1])  # (each at its own sample: however cut in blocks)
            add_notice(
                self.notices,
                float(latest[i]),
                "time_back",
                f"time went back: a sample at t = {t[i]:.6g} s is not after t = "
                f"{latest[i]:.6g} s ({mark} such so far); they are flagged and skipped "
                "(samples out of order, or a clock that was reset?)",
                logging.WARNING,
            )

    def _live_again(self, t: float) -> None:
        st = self.state
        add_notice(
            self.notices,
            t,
            "live",
            f"the input is live again: it was stuck from t = {st.stuck_since:.3f} s to "
            f"{st.last_stuck_t:.3f} s",
        )

    def _time_back(self, t: np.ndarray, flat: np.ndarray) -> np.ndarray | None:
        """Which samples' times are not after an earlier finite sample's (said in notices);
        None when every time is after the one before (the common case, one comparison)."""
        st = self.state
        if t[0] > st.last_t and (len(t) == 1 or bool((t[1:] > t[:-1]).all())):
            return None
        finite = np.isfinite(flat).all(axis=1) & np.isfinite(t)
        # compare with the running maximum of earlier good times
        t_clean = np.where(finite, t, -np.inf)
        prev_max = np.maximum.accumulate(np.concatenate([[st.last_t], t_clean]))[:-1]
        back = finite & (t <= prev_max)
        if back.any():
            self._tell_time_back(t, prev_max, np.flatnonzero(back))
        return back

    def _process_slowly(
        self, t: np.ndarray, flat: np.ndarray, flags: np.ndarray, back: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray]:
        """The checks sample by sample (vectorised) for a block with something wrong in it;
        ``back``: :meth:`_time_back`'s samples."""
        st = self.state
        finite = np.isfinite(flat).all(axis=1) & np.isfinite(t)
        flags[~finite] |= FLAG_NAN
        with np.errstate(invalid="ignore"):
            sat = (np.abs(flat) >= self.settings.range_flat).any(axis=1)
        flags[finite & sat] |= FLAG_SATURATED
        if back is not None:  # time must increase
            flags[back] |= FLAG_TIME_BACK
        good = flags == 0
        if good.any():
            good_t = t[good]
            before = np.concatenate([[st.last_t], good_t[:-1]])
            gap = (good_t - before) > self.settings.user.max_gap_s
            if st.last_t == -math.inf:
                gap[0] = False
            flags[np.flatnonzero(good)[gap]] |= FLAG_GAP
            st.last_t = float(good_t[-1])
            self.resolution.observe(flat[good])
        with np.errstate(invalid="ignore", over="ignore"):  # bad rows are replaced below
            raw = self.resultant(flat)
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
