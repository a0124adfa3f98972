"""Frames into samples: which frames belong to one sample of the whole desk.

Every frame that carries sample data gets a *sample key*; one desk sample is all frames with
the same key, and it is complete when every frame kind (:mod:`hapticdesk.canbus.decoding`) is
in it. Keys come (:mod:`.sample_keys`) from

- **counters** (``assemble: counter``, every message has one and all share it): the counter
  unwrapped over its wrap-around, using the frame times, where there are any, to tell a wrap
  from a long gap. Frames may come in any order; a sample still incomplete when a frame three
  samples newer has arrived is given up;
- **time** otherwise: where a host polls (ATI), each poll of the first-polled board starts a
  sample; without polls, a pause longer than ``frame_gap_s`` (half a period) between frames;
  in a log without times, a frame kind that does not come after the previous one in the
  order the kinds first appeared.

What the keys cannot make whole is never guessed: a missing or doubled frame kind leaves its
channels NaN in that sample (the estimator flags and skips NaN samples), a frame whose sample
was already given out is dropped, and every such case is counted in :class:`CanStats`. A
field whose frame is lost is held from the sample before for a few samples at most
(:mod:`.field_hold`, logs assembled by counter); a sensor silent for longer is noticed
(:mod:`.silence`).

Sample times are on the sensor clock: ``key / sample_rate`` with counters, otherwise the
time of the sample's first frame. The same code serves a live bus and a log: ``push`` any
split of the frames and ``flush`` at the end; the result does not depend on the split.
"""

from __future__ import annotations

import collections
import logging
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from hapticdesk.canbus.dbc_signals import frame_words
from hapticdesk.canbus.decoding import (
    ERROR_FRAME,
    FOREIGN,
    PROTOCOL,
    REMOTE_FRAME,
    REQUEST,
    WRONG_LENGTH,
    DeskDecoding,
)
from hapticdesk.canbus.field_hold import FieldHold
from hapticdesk.canbus.frames import FrameArray
from hapticdesk.canbus.sample_keys import LATE, REORDER_DEPTH, CounterKeys, TimeKeys
from hapticdesk.canbus.silence import SilenceWatch
from hapticdesk.canbus.stats import CanNotice, CanStats, SensorSilentError
from hapticdesk.errors import Position

log = logging.getLogger("hapticdesk.canbus")

JUMP_PERIODS = 1.5  # sample times further apart than this count as lost samples
MAX_SAMPLE_FRAMES = 4  # by time, a sample of more than 4 × its frame kinds is given up
NOTICES_KEPT = 1000  # notices a source or assembler keeps (the oldest go first)


@dataclass
class AssembledBlock:
    """Samples given out by one push: ``t`` (k,), ``wrench`` (k, S, 6), new notices, and the
    accelerometers' readings ``accel`` (k, A) when the desk has some on the bus, one after the
    other (NaN where a frame is missing or its status voids it)."""

    t: np.ndarray
    wrench: np.ndarray
    notices: list[CanNotice]
    stop: SensorSilentError | None = None
    accel: np.ndarray | None = None


@dataclass
class _Pending:
    """Frames holding sample data that wait for the rest of their sample."""

    key: np.ndarray  # int64
    kind: np.ndarray  # int64: kind index, or n_kinds for a poll request
    t: np.ndarray
    ident: np.ndarray
    data: np.ndarray  # (n, 8) uint8

    @classmethod
    def empty(cls) -> _Pending:
        return cls(
            np.zeros(0, np.int64),
            np.zeros(0, np.int64),
            np.zeros(0),
            np.zeros(0, np.uint32),
            np.zeros((0, 8), np.uint8),
        )

    def join(self, other: _Pending) -> _Pending:
        if not len(self.key):
            return other
        return _Pending(
            np.concatenate([self.key, other.key]),
            np.concatenate([self.kind, other.kind]),
            np.concatenate([self.t, other.t]),
            np.concatenate([self.ident, other.ident]),
            np.concatenate([self.data, other.data]),
        )

    def take(self, index: np.ndarray) -> _Pending:
        return _Pending(
            self.key[index], self.kind[index], self.t[index], self.ident[index], self.data[index]
        )


def _decode_groups(
    decoding: DeskDecoding,
) -> tuple[np.ndarray, np.ndarray, list[tuple[Callable[[np.ndarray], np.ndarray], np.ndarray]]]:
    """Frame kinds decoded by one function into as many fields (an ATI desk: every board's
    first frames, then every board's second) decoded together, in one call: each kind's
    group (-1 for poll requests, the extra last kind), its row in the group, and each
    group's decode function with its kinds' slots."""
    n_kinds = len(decoding.kinds)
    groups: dict[tuple[object, int], list[int]] = {}
    for k, kind in enumerate(decoding.kinds):
        groups.setdefault((kind.decode, len(kind.slots)), []).append(k)
    group_of_kind = np.full(n_kinds + 1, -1, dtype=np.int64)  # (+1: poll requests)
    row_in_group = np.zeros(n_kinds + 1, dtype=np.int64)
    decode_groups: list[tuple[Callable[[np.ndarray], np.ndarray], np.ndarray]] = []
    for g, ks in enumerate(groups.values()):
        group_of_kind[ks] = g
        row_in_group[ks] = np.arange(len(ks))
        slots = np.stack([decoding.kinds[k].slots for k in ks])
        decode_groups.append((decoding.kinds[ks[0]].decode, slots))
    return group_of_kind, row_in_group, decode_groups


class FrameAssembler:
    """Streaming frames -> desk samples for one :class:`DeskDecoding` (see module docstring)."""

    def __init__(
        self,
        decoding: DeskDecoding,
        sample_rate_hz: float,
        *,
        assemble: str = "time",
        frame_gap_s: float | None = None,
        silent_timeout_s: float = 0.2,
        silent_sensor: str = "continue",
        where: Position | str = "",
        hold_samples: int = 0,
        count_lost: bool = True,
    ) -> None:
        if assemble == "counter" and decoding.counter_modulus is None:
            raise ValueError("assemble='counter' needs a counter in every frame kind")
        self.decoding = decoding
        self.rate = float(sample_rate_hz)
        self.assemble = assemble
        self.frame_gap_s = frame_gap_s if frame_gap_s is not None else 0.5 / self.rate
        self.silent_timeout_s = silent_timeout_s
        self.silent_sensor = silent_sensor
        self.where = where
        # False where a live poller counts the rounds it skipped (the gaps between its
        # samples' times are not losses: a round polled late is caught up)
        self.count_lost = count_lost
        self.stats = CanStats()
        # the most recent ones: a bus that keeps failing must not grow this for the whole run
        self.notices: collections.deque[CanNotice] = collections.deque(maxlen=NOTICES_KEPT)
        names = decoding.sensor_names
        self.stats.incomplete = {n: 0 for n in names}
        self.stats.held = {n: 0 for n in names}
        self.stats.invalid = {n: 0 for n in names}
        self.stats.status = {n: {} for n in names}
        n_kinds = len(decoding.kinds)
        self._n_kinds = n_kinds
        # which frame kinds carry each sensor's data (for "is it still talking")
        self._sensor_kinds = [
            np.array([k for k in range(n_kinds) if s in decoding.kinds[k].sensors], dtype=np.int64)
            for s in range(len(names))
        ]
        self._kind_is_sensors = np.zeros((n_kinds, len(names)), dtype=bool)
        for s, kinds in enumerate(self._sensor_kinds):
            self._kind_is_sensors[kinds, s] = True
        self._group_of_kind, self._row_in_group, self._decode_groups = _decode_groups(decoding)
        self._pending = _Pending.empty()
        self._last_key: int | None = None  # key of the last sample given out
        self._key0: int | None = None
        self._t0: float | None = None
        self._last_t: float | None = None
        self._keys: CounterKeys | TimeKeys = (
            CounterKeys(decoding, self.rate, self.stats)
            if assemble == "counter"
            else TimeKeys(decoding, self.rate, self.frame_gap_s, self.stats)
        )
        self._silence = SilenceWatch(names, silent_timeout_s, silent_sensor, where)
        self._accel_axes = decoding.accel_axes  # the last groups: the accelerometers
        self._hold = FieldHold(decoding, hold_samples)

    # --- public -------------------------------------------------------------------------

    @property
    def last_sample_time(self) -> float | None:
        """Time of the last sample given out (None before the first)."""
        return self._last_t

    def push(self, frames: FrameArray) -> AssembledBlock:
        """Take more frames (in arrival order); give out the samples now complete or given up."""
        if self._silence.stopped is not None:
            return self._result(np.zeros(0), np.zeros((0, len(self._sensor_kinds), 6)), [])
        codes = self.decoding.classify(frames)
        self._count(frames, codes)
        relevant = (codes >= 0) | (codes == REQUEST)
        if self.assemble == "counter":
            relevant = codes >= 0
        if relevant.any():
            sub = frames.take(relevant)
            kind = codes[relevant]
            kind[kind == REQUEST] = self._n_kinds
            keys = self._keys.keys(sub, kind)
            self._pending = self._pending.join(_Pending(keys, kind, sub.t, sub.ident, sub.data))
        return self._give_out(flush=False)

    def flush(self) -> AssembledBlock:
        """End of the stream: give out everything still waiting, complete or not."""
        if self._silence.stopped is not None:
            return self._result(np.zeros(0), np.zeros((0, len(self._sensor_kinds), 6)), [])
        return self._give_out(flush=True)

    # --- samples ------------------------------------------------------------------------

    def _give_out(self, flush: bool) -> AssembledBlock:
        p = self._pending
        n_sensors = len(self._sensor_kinds)
        nothing = (np.zeros(0), np.zeros((0, n_sensors, 6)))
        if not len(p.key):
            return self._result(*nothing, [])
        late = p.key == LATE
        if self._last_key is not None:
            late |= p.key <= self._last_key  # its sample was given out already
        if late.any():
            late_kinds = p.kind[late & (p.kind < self._n_kinds)]
            self.stats.late += len(late_kinds)
            for s, kinds in enumerate(self._sensor_kinds):
                self._silence.late_frames[s] += int(np.isin(late_kinds, kinds).sum())
            p = p.take(~late)
            if not len(p.key):
                self._pending = p
                return self._result(*nothing, [])
        keys, row_of = np.unique(p.key, return_inverse=True)
        n_rows, n_kinds = len(keys), self._n_kinds
        presence = np.bincount(row_of * (n_kinds + 1) + p.kind, minlength=n_rows * (n_kinds + 1))
        presence = presence.reshape(n_rows, n_kinds + 1)[:, :n_kinds]
        complete = (presence >= 1).all(axis=1)
        if flush:
            final = np.ones(n_rows, dtype=bool)
        elif self.assemble == "counter":
            final = complete | (keys <= keys[-1] - REORDER_DEPTH)
        else:
            # a sample that keeps growing (polls stopped, yet frames keep coming) is given up
            overgrown = np.bincount(row_of, minlength=n_rows) > MAX_SAMPLE_FRAMES * (n_kinds + 1)
            # by polls, an incomplete sample waits one more round: its reply's second frame
            # may come after the next poll (see _pair_halves)
            assert isinstance(self._keys, TimeKeys)
            waits = 1 if self._keys.polled and self.decoding.second_halves else 0
            final = complete | (keys < self._keys.cluster - waits) | overgrown
        n_out = n_rows if final.all() else int(np.argmin(final))
        if n_out == 0:
            self._pending = p
            return self._result(*nothing, [])
        out = row_of < n_out
        self._pending = p.take(~out)
        return self._samples(p.take(out), row_of[out], keys[:n_out], presence[:n_out])

    def _samples(
        self, p: _Pending, row_of: np.ndarray, keys: np.ndarray, presence: np.ndarray
    ) -> AssembledBlock:
        n = len(keys)
        decoding = self.decoding
        table = np.full((n, decoding.n_fields), np.nan)
        group_of = self._group_of_kind[p.kind]
        for g, (decode, slots) in enumerate(self._decode_groups):
            sel = group_of == g
            if sel.any():
                columns = slots[self._row_in_group[p.kind[sel]]]
                table[row_of[sel][:, None], columns] = decode(p.data[sel])
        doubled = presence > 1
        if doubled.any():
            for k in np.flatnonzero(doubled.any(axis=0)).tolist():
                rows = doubled[:, k]
                table[np.ix_(np.flatnonzero(rows), decoding.kinds[k].slots)] = np.nan
                self.stats.duplicates += int(presence[rows, k].sum())
        if self.assemble == "time":
            self._check_counters(p, row_of, n, table)
        held = self._hold.fill(table)
        t = self._times(p, row_of, keys)
        wrench, invalid, counts = decoding.channels(table)
        missing = (np.isnan(wrench).any(axis=2) & ~invalid).sum(axis=0).tolist()
        wrench[invalid] = np.nan
        n_invalid = invalid.sum(axis=0).tolist()
        any_held = bool(held.any())
        for s, reading in enumerate(decoding.readings):
            if any_held:
                self.stats.held[reading.name] += int(held[:, reading.columns].any(axis=1).sum())
            self.stats.invalid[reading.name] += n_invalid[s]
            self.stats.incomplete[reading.name] += missing[s]
            bits = self.stats.status[reading.name]
            for label, count in counts[s].items():
                bits[label] = bits.get(label, 0) + count
        self._count_lost(keys, t)
        talking = (presence > 0) @ self._kind_is_sensors  # (k, S) bool: any of its kinds came
        notices, stop_at = self._silence.watch(t, talking)
        if stop_at is not None:
            t, wrench = t[:stop_at], wrench[:stop_at]
            keys = keys[:stop_at]
            self._pending = _Pending.empty()
        if len(keys):
            self._last_key = int(keys[-1])
            self._last_t = float(t[-1])
        self.stats.samples += len(t)
        return self._result(t, wrench, notices)

    def _times(self, p: _Pending, row_of: np.ndarray, keys: np.ndarray) -> np.ndarray:
        if self._key0 is None:
            self._key0 = int(keys[0])
        by_key = (keys - self._key0) / self.rate
        if self.assemble == "counter" or not np.isfinite(p.t).any():
            return by_key
        order = np.argsort(row_of, kind="stable")
        starts = np.searchsorted(row_of[order], np.arange(len(keys)))
        first = np.fmin.reduceat(p.t[order], starts)
        if self._t0 is None:
            self._t0 = float(first[0]) if np.isfinite(first[0]) else 0.0
        return np.where(np.isfinite(first), first - self._t0, by_key)

    def _check_counters(self, p: _Pending, row_of: np.ndarray, n: int, table: np.ndarray) -> None:
        """Time mode: one sensor's frames in a sample must carry the same counter."""
        for reading, kinds in zip(self.decoding.readings, self._sensor_kinds, strict=True):
            counted = [k for k in kinds if self.decoding.kinds[k].counter is not None]
            if len(counted) < 2:
                continue
            values = np.full((n, len(counted)), np.nan)
            for j, k in enumerate(counted):
                sel = p.kind == k
                layout = self.decoding.kinds[k].counter
                assert layout is not None
                values[row_of[sel], j] = layout.raw(frame_words(p.data[sel]))
            with np.errstate(invalid="ignore"):
                spread = np.nanmax(values, axis=1) - np.nanmin(values, axis=1)
            bad = np.nan_to_num(spread) > 0
            if bad.any():
                table[np.ix_(np.flatnonzero(bad), reading.columns)] = np.nan
                self.stats.counter_mismatch += int(bad.sum())

    def _count_lost(self, keys: np.ndarray, t: np.ndarray) -> None:
        if not self.count_lost:
            return
        if self.assemble == "counter":
            prev = self._last_key if self._last_key is not None else keys[0] - 1
            steps = np.diff(np.concatenate([[prev], keys]))
            self.stats.lost_samples += int(np.sum(np.maximum(steps - 1, 0)))
        elif np.isfinite(t).all():
            prev = self._last_t if self._last_t is not None else t[0]
            periods = np.diff(np.concatenate([[prev], t])) * self.rate
            jumped = periods > JUMP_PERIODS  # jitter of a host clock is not a loss
            self.stats.lost_samples += int(np.sum(np.rint(periods[jumped]) - 1))

    def _result(
        self, t: np.ndarray, wrench: np.ndarray, notices: list[CanNotice]
    ) -> AssembledBlock:
        for notice in notices:
            log.warning("%s", notice.message)
        self.notices.extend(notices)
        if not self._accel_axes:
            return AssembledBlock(t, wrench, notices, self._silence.stopped)
        sensors = wrench.shape[1] - len(self._accel_axes)
        parts = [wrench[:, sensors + i, axes] for i, axes in enumerate(self._accel_axes)]
        accel = parts[0] if len(parts) == 1 else np.concatenate(parts, axis=1)
        return AssembledBlock(t, wrench[:, :sensors], notices, self._silence.stopped, accel)

    # --- counting -----------------------------------------------------------------------

    def _count(self, frames: FrameArray, codes: np.ndarray) -> None:
        s = self.stats
        s.frames += len(codes)
        s.data_frames += int(np.count_nonzero(codes >= 0))
        s.requests += int(np.count_nonzero(codes == REQUEST))
        s.protocol += int(np.count_nonzero(codes == PROTOCOL))
        s.error_frames += int(np.count_nonzero(codes == ERROR_FRAME))
        s.remote_frames += int(np.count_nonzero(codes == REMOTE_FRAME))
        for code, table in ((FOREIGN, s.foreign), (WRONG_LENGTH, s.wrong_length)):
            if not (codes == code).any():
                continue
            ids, counts = np.unique(frames.ident[codes == code], return_counts=True)
            for ident, count in zip(ids.tolist(), counts.tolist(), strict=True):
                table[ident] = table.get(ident, 0) + count
