"""Frames into samples: which frames belong to one sample of the whole desk.

Every frame that carries sample data gets a *sample key*; one desk sample is all frames with
the same key, and it is complete when every frame kind (:mod:`hapticdesk.canbus.decoding`) is
in it. Keys come from

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
was already given out is dropped, and every such case is counted in :class:`CanStats`.

Sample times are on the sensor clock: ``key / sample_rate`` with counters, otherwise the
time of the sample's first frame. The same code serves a live bus and a log: ``push`` any
split of the frames and ``flush`` at the end; the result does not depend on the split.
"""

from __future__ import annotations

import collections
import logging
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
from hapticdesk.canbus.frames import FrameArray
from hapticdesk.canbus.stats import CanNotice, CanStats, SensorSilentError, silence_message
from hapticdesk.files.yamlfile import Position

log = logging.getLogger("hapticdesk.canbus")

REORDER_DEPTH = 3  # with counters, a sample is given up once a frame this many samples newer came
JUMP_PERIODS = 1.5  # sample times further apart than this count as lost samples
LATE = np.iinfo(np.int64).min  # the key of a frame that came too late for its sample
MAX_SAMPLE_FRAMES = 4  # by time, a sample of more than 4 × its frame kinds is given up
NOTICES_KEPT = 1000  # notices a source or assembler keeps (the oldest go first)
#: a frame whose time is this many sample periods before the latest frame's went back in time
TIME_BACK_PERIODS = 1.0


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
        #: a channel whose frame is missing from a sample takes its value from the samples
        #: before, for at most this many samples in a row (0: left NaN)
        self.hold_samples = hold_samples
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
        self._pending = _Pending.empty()
        self._last_key: int | None = None  # key of the last sample given out
        self._key0: int | None = None
        self._t0: float | None = None
        self._last_t: float | None = None
        # key state: counter unwrapping, or clustering by time
        self._prev_counter: int | None = None
        self._newest_key = np.iinfo(np.int64).min + REORDER_DEPTH
        self._prev_key = 0
        self._prev_t = np.nan
        self._prev_rank = -1
        self._cluster = 0
        self._rank = np.full(n_kinds + 1, -1, dtype=np.int64)
        self._next_rank = 0
        self._lead_request: int | None = None
        self._polled = False  # a poll request has been seen: polls start samples
        # per reply whose frames come in order (ATI 0x0 then 0x1): the key of the last first
        # frame still waiting for its second, if any
        self._open_first: dict[int, int | None] = {a: None for a in decoding.second_halves.values()}
        # silence per sensor
        self._last_seen = np.full(len(names), np.nan)
        self._silent = np.zeros(len(names), dtype=bool)
        self._late_frames = np.zeros(len(names), dtype=np.int64)  # since the sensor last fit
        self._stopped: SensorSilentError | None = None
        self._accel_axes = decoding.accel_axes  # the last groups: the accelerometers
        # the last value of each field and how many samples ago it was read (for the hold)
        self._last_row = np.full(decoding.n_fields, np.nan)
        self._last_age = np.zeros(decoding.n_fields, dtype=np.int64)
        # only the force sensors' fields are held: a missing accelerometer reading stays NaN,
        # the estimator then flags that sample `no_accel` (the documented contract)
        self._holdable = np.zeros(decoding.n_fields, dtype=bool)
        force_readings = decoding.readings[: len(decoding.readings) - len(self._accel_axes)]
        for reading in force_readings:
            self._holdable[reading.columns] = True

    # --- public -------------------------------------------------------------------------

    @property
    def last_sample_time(self) -> float | None:
        """Time of the last sample given out (None before the first)."""
        return self._last_t

    def push(self, frames: FrameArray) -> AssembledBlock:
        """Take more frames (in arrival order); give out the samples now complete or given up."""
        if self._stopped is not None:
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
            keys = (
                self._counter_keys(sub, kind)
                if self.assemble == "counter"
                else self._time_keys(sub, kind)
            )
            self._pending = self._pending.join(_Pending(keys, kind, sub.t, sub.ident, sub.data))
        return self._give_out(flush=False)

    def flush(self) -> AssembledBlock:
        """End of the stream: give out everything still waiting, complete or not."""
        if self._stopped is not None:
            return self._result(np.zeros(0), np.zeros((0, len(self._sensor_kinds), 6)), [])
        return self._give_out(flush=True)

    # --- keys ---------------------------------------------------------------------------

    def _counter_keys(self, frames: FrameArray, kind: np.ndarray) -> np.ndarray:
        modulus = int(self.decoding.counter_modulus or 0)
        counter = np.zeros(len(kind), dtype=np.int64)
        for k in np.unique(kind):
            sel = kind == k
            layout = self.decoding.kinds[k].counter
            assert layout is not None
            counter[sel] = layout.raw(frame_words(frames.data[sel])).astype(np.int64)
        if self._prev_counter is None:
            self._prev_counter, self._prev_key, self._prev_t = (
                int(counter[0]),
                int(counter[0]),
                frames.t[0],
            )
        prev_c = np.concatenate([[self._prev_counter], counter[:-1]])
        # the latest time seen before each frame: a frame whose time went back (a corrupt or
        # merged log) neither counts as a wrap of the counter nor moves the clock for the
        # frames after it (0.5 % of them had made 1.6 million samples "lost" and no tap)
        clock = np.fmax.accumulate(np.concatenate([[self._prev_t], frames.t]))
        prev_t = clock[:-1]
        dt = frames.t - prev_t
        self._count_time_back(dt)
        # Within half its range the counter alone decides (host clocks stall and burst, and a
        # fast replay is not on the sample clock); across a longer pause the time says how
        # many wraps were missed.
        half = modulus // 2
        periods = np.where(np.isfinite(dt), dt * self.rate, 0.0)
        expected = np.where(periods >= half, np.rint(periods), 0).astype(np.int64)
        delta = expected + np.mod(counter - prev_c - expected + half, modulus) - half
        keys = self._prev_key + np.cumsum(delta)
        self._prev_counter, self._prev_key, self._prev_t = (
            int(counter[-1]),
            int(keys[-1]),
            clock[-1],
        )
        # A frame more than REORDER_DEPTH samples behind the newest one before it is late,
        # whether or not its sample has been given out yet: so a log read at once and a bus
        # read frame by frame agree, and a sensor whose counter went its own way (a reboot)
        # is never merged into other samples.
        newest = np.maximum.accumulate(np.concatenate([[self._newest_key], keys]))[:-1]
        self._newest_key = max(self._newest_key, int(keys.max()))
        return np.where(keys <= newest - REORDER_DEPTH, LATE, keys)

    def _time_keys(self, frames: FrameArray, kind: np.ndarray) -> np.ndarray:
        is_request = kind == self._n_kinds
        if self._lead_request is None and is_request.any():
            # the board polled first in each round starts a sample
            self._lead_request = int(frames.ident[np.argmax(is_request)])
        after_polls = self._polled | (np.cumsum(is_request) > 0)
        prev_t = np.concatenate([[self._prev_t], frames.t[:-1]])
        dt = frames.t - prev_t
        self._count_time_back(dt)
        # ranks of kinds in the order they first appeared (for logs without times)
        new = np.unique(kind[(self._rank[kind] < 0) & ~is_request])
        if len(new):
            first = np.array([np.argmax(kind == k) for k in new])
            for k in new[np.argsort(first)]:
                self._rank[k] = self._next_rank
                self._next_rank += 1
        rank = np.where(is_request, -1, self._rank[kind])
        prev_rank = np.concatenate([[self._prev_rank], rank[:-1]])
        with np.errstate(invalid="ignore"):
            by_poll = is_request & (frames.ident == self._lead_request)
            by_gap = np.where(
                np.isfinite(dt), dt > self.frame_gap_s, (rank <= prev_rank) & (rank >= 0)
            )
        boundary = np.where(after_polls, by_poll, by_gap)
        keys = self._cluster + np.cumsum(boundary)
        self._cluster = int(keys[-1])
        self._prev_t = frames.t[-1]
        self._prev_rank = int(rank[-1])
        self._polled = bool(after_polls[-1])
        for second, first in self.decoding.second_halves.items():
            self._pair_halves(keys, kind, first, second)
        return keys

    def _count_time_back(self, dt: np.ndarray) -> None:
        with np.errstate(invalid="ignore"):
            self.stats.time_back += int(np.count_nonzero(dt < -TIME_BACK_PERIODS / self.rate))

    def _pair_halves(self, keys: np.ndarray, kind: np.ndarray, first: int, second: int) -> None:
        """Give each second frame of a reply its first frame's key, in place.

        A board sends the two frames of a reply in order, but traffic of higher priority can
        delay the second until after the host's next poll, which starts the next sample: by
        its poll it would land there (doubled) and void two samples. So a second frame takes
        the key of the last first frame before it that has no second yet, if that first
        frame is of its own poll round or the one before (any older is not its reply's).
        """
        a_pos = np.flatnonzero(kind == first)
        b_pos = np.flatnonzero(kind == second)
        carried = self._open_first[first]
        if len(b_pos):
            # the first frame before each second one: its index in a_pos, -1 an earlier push's
            prev = np.searchsorted(a_pos, b_pos) - 1
            a_keys = keys[a_pos] if len(a_pos) else np.zeros(1, np.int64)
            owner = np.where(prev >= 0, a_keys[np.maximum(prev, 0)], carried or 0)
            # one second frame per first frame: a second after the same first keeps its key
            takes = np.concatenate([[True], prev[1:] != prev[:-1]])
            takes &= (prev >= 0) | (carried is not None)
            takes &= (owner >= keys[b_pos] - 1) & (owner <= keys[b_pos])
            keys[b_pos[takes]] = owner[takes]
            answered = set(prev[takes].tolist())
        else:
            answered = set()
        if len(a_pos):
            last = len(a_pos) - 1
            self._open_first[first] = None if last in answered else int(keys[a_pos[last]])
        elif -1 in answered:
            self._open_first[first] = None

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
                self._late_frames[s] += int(np.isin(late_kinds, kinds).sum())
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
            waits = 1 if self._polled and self.decoding.second_halves else 0
            final = complete | (keys < self._cluster - waits) | overgrown
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
        for k, kind in enumerate(decoding.kinds):
            sel = p.kind == k
            if sel.any():
                table[row_of[sel][:, None], kind.slots] = kind.decode(p.data[sel])
            doubled = presence[:, k] > 1
            if doubled.any():
                table[np.ix_(np.flatnonzero(doubled), kind.slots)] = np.nan
                self.stats.duplicates += int(presence[doubled, k].sum())
        if self.assemble == "time":
            self._check_counters(p, row_of, n, table)
        held = self._hold(table)
        t = self._times(p, row_of, keys)
        wrench = np.empty((n, len(decoding.readings), 6))
        for s, reading in enumerate(decoding.readings):
            self.stats.held[reading.name] += int(held[:, reading.columns].any(axis=1).sum())
            w, invalid, counts = reading.channels(table)
            missing = np.isnan(w).any(axis=1) & ~invalid
            w[invalid] = np.nan
            wrench[:, s] = w
            self.stats.invalid[reading.name] += int(invalid.sum())
            self.stats.incomplete[reading.name] += int(missing.sum())
            bits = self.stats.status[reading.name]
            for label, count in counts.items():
                bits[label] = bits.get(label, 0) + count
        self._count_lost(keys, t)
        talking = np.stack([(presence[:, ks] > 0).any(axis=1) for ks in self._sensor_kinds], axis=1)
        notices, stop_at = self._watch_silence(t, talking)
        if stop_at is not None:
            t, wrench = t[:stop_at], wrench[:stop_at]
            keys = keys[:stop_at]
            self._pending = _Pending.empty()
        if len(keys):
            self._last_key = int(keys[-1])
            self._last_t = float(t[-1])
        self.stats.samples += len(t)
        return self._result(t, wrench, notices)

    def _hold(self, table: np.ndarray) -> np.ndarray:
        """Fill, in place, each field a sample lacks (its frame was lost, doubled, or came
        with another counter) with the field's last value, when that is at most
        :attr:`hold_samples` samples old; returns where it did. A log with 5 % of its lines
        junk had lost a frame in a third of its samples, and the NaN samples the estimator
        skips had refused the tare for the whole run; a value one sample old is a truer
        sample than none. Carried across pushes, so any split gives the same samples."""
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
        if self.assemble == "counter":
            prev = self._last_key if self._last_key is not None else keys[0] - 1
            steps = np.diff(np.concatenate([[prev], keys]))
            self.stats.lost_samples += int(np.sum(np.maximum(steps - 1, 0)))
        elif np.isfinite(t).all():
            prev = self._last_t if self._last_t is not None else t[0]
            periods = np.diff(np.concatenate([[prev], t])) * self.rate
            jumped = periods > JUMP_PERIODS  # jitter of a host clock is not a loss
            self.stats.lost_samples += int(np.sum(np.rint(periods[jumped]) - 1))

    def _watch_silence(
        self, t: np.ndarray, talking: np.ndarray
    ) -> tuple[list[CanNotice], int | None]:
        """Notice sensors that stop and come back; stop at the first silence if configured."""
        notices: list[CanNotice] = []
        stop_at: int | None = None
        names = self.decoding.sensor_names
        for s, name in enumerate(names):
            if np.isnan(self._last_seen[s]):
                self._last_seen[s] = t[0]
            seen = np.where(talking[:, s], t, -np.inf)
            last = np.maximum(np.maximum.accumulate(seen), self._last_seen[s])
            silent = ~talking[:, s] & (t - last > self.silent_timeout_s)
            prev = np.concatenate([[self._silent[s]], silent[:-1]])
            for i in np.flatnonzero(silent & ~prev):
                text = silence_message(
                    name, self.silent_timeout_s, float(last[i]), int(self._late_frames[s])
                )
                if self.silent_sensor == "stop":
                    if stop_at is None or i < stop_at:
                        stop_at = int(i)
                        self._stopped = SensorSilentError(
                            self.where, text + "; stopping (`silent_sensor: stop`)"
                        )
                    break
                notices.append(CanNotice(float(t[i]), "silent", text + "; its channels are NaN"))
            for i in np.flatnonzero(talking[:, s] & prev):
                notices.append(
                    CanNotice(
                        float(t[i]), "back", f"sensor {name} is sending again at t={t[i]:.3f} s"
                    )
                )
            if talking[:, s].any():
                self._late_frames[s] = 0
            self._silent[s] = bool(silent[-1]) if len(silent) else self._silent[s]
            self._last_seen[s] = last[-1]
        if stop_at is not None:
            notices = [n for n in notices if n.t < t[stop_at]]
        notices.sort(key=lambda n: n.t)
        return notices, stop_at

    def _result(
        self, t: np.ndarray, wrench: np.ndarray, notices: list[CanNotice]
    ) -> AssembledBlock:
        for notice in notices:
            log.warning("%s", notice.message)
        self.notices.extend(notices)
        if not self._accel_axes:
            return AssembledBlock(t, wrench, notices, self._stopped)
        sensors = wrench.shape[1] - len(self._accel_axes)
        parts = [wrench[:, sensors + i, axes] for i, axes in enumerate(self._accel_axes)]
        accel = parts[0] if len(parts) == 1 else np.concatenate(parts, axis=1)
        return AssembledBlock(t, wrench[:, :sensors], notices, self._stopped, accel)

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
            ids, counts = np.unique(frames.ident[codes == code], return_counts=True)
            for ident, count in zip(ids.tolist(), counts.tolist(), strict=True):
                table[ident] = table.get(ident, 0) + count
