"""Which sample each frame belongs to: its *sample key* (see :mod:`.assembler`).

:class:`CounterKeys` (``assemble: counter``) unwraps the frames' shared counter over its
wrap-around, the frame times telling a wrap from a long gap; a frame more than
:data:`REORDER_DEPTH` samples behind the newest is LATE. :class:`TimeKeys` (``assemble:
time``) starts a sample at each poll of the first-polled board, else at a pause longer than
``frame_gap_s``, else (a log without times) at a frame kind out of the order the kinds
first came in; an ATI board's second reply frame is paired with its first. Both carry their
state from push to push, so any split of the frames gives the same keys.
"""

from __future__ import annotations

import numpy as np

from hapticdesk.canbus.dbc_signals import frame_words
from hapticdesk.canbus.decoding import DeskDecoding
from hapticdesk.canbus.frames import FrameArray
from hapticdesk.canbus.stats import CanStats

REORDER_DEPTH = 3  # with counters, a sample is given up once a frame this many samples newer came
LATE = np.iinfo(np.int64).min  # the key of a frame that came too late for its sample
_NO_POLL = -1  # (sample keys by time are >= 0)
#: a frame whose time is this many sample periods before the latest frame's went back in time
TIME_BACK_PERIODS = 1.0


def count_time_back(stats: CanStats, dt: np.ndarray, rate: float) -> None:
    """Count the frames whose time went back (``dt`` from the frame before) in ``stats``."""
    with np.errstate(invalid="ignore"):
        stats.time_back += int(np.count_nonzero(dt < -TIME_BACK_PERIODS / rate))


class CounterKeys:
    """Sample keys from counters; every frame kind has one and all share it."""

    def __init__(self, decoding: DeskDecoding, rate: float, stats: CanStats) -> None:
        self.decoding = decoding
        self.rate = rate
        self.stats = stats
        self._prev_counter: int | None = None
        self._prev_key = 0
        self._prev_t = np.nan
        self._newest_key = np.iinfo(np.int64).min + REORDER_DEPTH

    def keys(self, frames: FrameArray, kind: np.ndarray) -> np.ndarray:
        """The sample key of each frame (``kind`` its kind index); LATE for a frame that
        came more than REORDER_DEPTH samples after its sample's newer ones."""
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
        count_time_back(self.stats, dt, self.rate)
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


class TimeKeys:
    """Sample keys by time: polls, pauses between frames, or the order of frame kinds."""

    def __init__(
        self, decoding: DeskDecoding, rate: float, frame_gap_s: float, stats: CanStats
    ) -> None:
        self.decoding = decoding
        self.rate = rate
        self.frame_gap_s = frame_gap_s
        self.stats = stats
        self.n_kinds = len(decoding.kinds)
        self.cluster = 0  # the key of the last sample begun
        self.polled = False  # a poll request has been seen: polls start samples
        # polled boards in the order their polls first came (a round polls them in order)
        self._poll_order = np.zeros(0, np.uint32)  # poll identifiers, sorted
        self._poll_rank = np.zeros(0, np.int64)  # ... and each one's place in a round
        self._prev_poll_rank = np.iinfo(np.int64).max
        # each polled board's reply kinds (its first and second frame: both carry the poll's
        # identifier's board) and the key of its latest poll, carried from push to push
        boards = [
            (int(decoding.kinds[first].ident), first, second)
            for second, first in decoding.second_halves.items()
            if int(decoding.kinds[first].ident) in decoding.request_sensor
        ]
        boards.sort()
        self._polled_ids = np.array([b[0] for b in boards], dtype=np.uint32)  # sorted
        self._board_of_kind = np.full(self.n_kinds + 1, -1, dtype=np.int64)  # (+1: polls)
        for b, (_, first, second) in enumerate(boards):
            self._board_of_kind[[first, second]] = b
        self._last_poll_key = np.full(len(boards), _NO_POLL, dtype=np.int64)
        self._prev_t = np.nan
        self._prev_rank = -1
        self._rank = np.full(self.n_kinds + 1, -1, dtype=np.int64)
        self._next_rank = 0
        self._halves = ReplyHalves(decoding.second_halves, self.n_kinds)

    def keys(self, frames: FrameArray, kind: np.ndarray) -> np.ndarray:
        """The sample key of each frame (``kind`` its kind index, n_kinds for a poll)."""
        is_request = kind == self.n_kinds
        prev_t = np.concatenate([[self._prev_t], frames.t[:-1]])
        dt = frames.t - prev_t
        count_time_back(self.stats, dt, self.rate)
        # ranks of kinds in the order they first appeared (for logs without times)
        unranked = (self._rank[kind] < 0) & ~is_request
        if unranked.any():  # (a kind keeps its rank: once all came, nothing to look up)
            new = np.unique(kind[unranked])
            first = np.array([np.argmax(kind == k) for k in new])
            for k in new[np.argsort(first)]:
                self._rank[k] = self._next_rank
                self._next_rank += 1
        rank = np.where(is_request, -1, self._rank[kind])
        by_poll = self._round_starts(frames.ident, is_request)
        if self.polled:  # polls start the samples from the first poll on: no gaps to look at
            boundary = by_poll
        else:
            after_polls = np.cumsum(is_request) > 0
            prev_rank = np.concatenate([[self._prev_rank], rank[:-1]])
            with np.errstate(invalid="ignore"):
                by_gap = np.where(
                    np.isfinite(dt), dt > self.frame_gap_s, (rank <= prev_rank) & (rank >= 0)
                )
            boundary = np.where(after_polls, by_poll, by_gap)
            self.polled = bool(after_polls[-1])
        keys = self.cluster + np.cumsum(boundary)
        self.cluster = int(keys[-1])
        self._prev_t = frames.t[-1]
        self._prev_rank = int(rank[-1])
        self._key_replies_by_poll(keys, kind, frames.ident, is_request)
        self._halves.pair(keys, kind)
        return keys

    def _round_starts(self, ident: np.ndarray, is_request: np.ndarray) -> np.ndarray:
        """Where a poll round starts: at a poll of a board polled no later in a round than
        the board of the poll before (the first-polled board's poll, as a rule; a later
        board's when the host left the boards before it out of a round, e.g. one that still
        owed its reply)."""
        out = np.zeros(len(ident), dtype=bool)
        if not is_request.any():
            return out
        polls = ident[is_request].astype(np.uint32)
        known_at = np.minimum(np.searchsorted(self._poll_order, polls), len(self._poll_order) - 1)
        new = (
            np.unique(polls[self._poll_order[known_at] != polls])
            if len(self._poll_order)
            else np.unique(polls)
        )
        if len(new):  # ranks in the order the boards' polls first came
            first = np.array([np.argmax(polls == p) for p in new])
            known = dict(zip(self._poll_order.tolist(), self._poll_rank.tolist(), strict=True))
            for p in new[np.argsort(first)]:
                known[int(p)] = len(known)
            self._poll_order = np.array(sorted(known), dtype=np.uint32)
            self._poll_rank = np.array([known[p] for p in sorted(known)], dtype=np.int64)
        rank = self._poll_rank[np.searchsorted(self._poll_order, polls)]
        before = np.concatenate([[self._prev_poll_rank], rank[:-1]])
        out[is_request] = rank <= before
        self._prev_poll_rank = int(rank[-1])
        return out

    def _key_replies_by_poll(
        self, keys: np.ndarray, kind: np.ndarray, ident: np.ndarray, is_request: np.ndarray
    ) -> None:
        """Give each reply of a polled board the key of its own board's latest poll, in place.

        A host that never polls a board again before its reply came (the live source's
        poller) makes that exact: a reply that comes late, after other boards' later polls,
        still lands in the sample it was asked for, never in a later sample as if it had been
        taken then. One that comes more than a round after its poll is LATE: its sample is
        given out by then when frames are pushed as they come, so in any split."""
        n_boards = len(self._polled_ids)
        if not n_boards:
            return
        poll_pos = np.flatnonzero(is_request)
        at = np.minimum(np.searchsorted(self._polled_ids, ident[poll_pos]), n_boards - 1)
        known = self._polled_ids[at] == ident[poll_pos]
        poll_pos, poll_board = poll_pos[known], at[known]
        reply_pos = np.flatnonzero(self._board_of_kind[kind] >= 0)
        if len(reply_pos):
            # every board's latest poll before it (a push before's first), for all boards at
            # once: the events sorted by board, then place; each reply takes the last poll's
            board = np.concatenate(
                [np.arange(n_boards), poll_board, self._board_of_kind[kind[reply_pos]]]
            )
            place = np.concatenate([np.full(n_boards, -1), poll_pos, reply_pos])
            key = np.concatenate(
                [self._last_poll_key, keys[poll_pos], np.zeros(len(reply_pos), np.int64)]
            )
            is_poll = np.arange(len(board)) < n_boards + len(poll_pos)
            order = np.lexsort((place, board))
            latest = np.maximum.accumulate(np.where(is_poll[order], np.arange(len(order)), 0))
            own_sorted = key[order][latest]
            own = np.empty_like(own_sorted)
            own[order] = own_sorted
            own = own[n_boards + len(poll_pos) :]
            asked = own != _NO_POLL  # (before any poll of its board: keyed by time)
            own = np.where(own < keys[reply_pos] - 1, LATE, own)
            keys[reply_pos[asked]] = own[asked]
        if len(poll_pos):  # each board's latest poll, for the next push
            last = len(poll_board) - 1 - np.unique(poll_board[::-1], return_index=True)[1]
            self._last_poll_key[poll_board[last]] = keys[poll_pos[last]]


class ReplyHalves:
    """Pairs each second frame of a reply with its first (an ATI board's 0x1 after its 0x0),
    for every board at once, carrying from push to push the first frame still waiting.

    A board sends the two frames of a reply in order, but traffic of higher priority can
    delay the second until after the host's next poll, which starts the next sample: by its
    poll it would land there (doubled) and void two samples. So a second frame takes the key
    of the last first frame of its kind before it that has no second yet, if that first frame
    is of its own poll round or the one before (any older is not its reply's).
    """

    def __init__(self, second_halves: dict[int, int], n_kinds: int) -> None:
        self.n_pairs = len(second_halves)
        self._pair_of_first = np.full(n_kinds + 1, -1, dtype=np.int64)  # (+1: polls)
        self._pair_of_second = np.full(n_kinds + 1, -1, dtype=np.int64)
        for p, (second, first) in enumerate(second_halves.items()):
            self._pair_of_first[first], self._pair_of_second[second] = p, p
        # per pair: whether a first frame of an earlier push waits for its second, its key
        self._open = np.zeros(self.n_pairs, dtype=bool)
        self._open_key = np.zeros(self.n_pairs, dtype=np.int64)

    def pair(self, keys: np.ndarray, kind: np.ndarray) -> None:
        """Give each second frame its first frame's key, in place (``kind`` per frame)."""
        a_pos = np.flatnonzero(self._pair_of_first[kind] >= 0)
        b_pos = np.flatnonzero(self._pair_of_second[kind] >= 0)
        if not len(a_pos) and not len(b_pos):
            return
        n_pairs = self.n_pairs
        # the events of every pair, sorted by pair, then place: first the pair's carried
        # first frame (place -1, a real one if open), then its frames of this push
        pair = np.concatenate(
            [
                np.arange(n_pairs),
                self._pair_of_first[kind[a_pos]],
                self._pair_of_second[kind[b_pos]],
            ]
        )
        place = np.concatenate([np.full(n_pairs, -1), a_pos, b_pos])
        order = np.lexsort((place, pair))
        n_firsts = n_pairs + len(a_pos)
        is_first = order < n_firsts  # (or the carried one)
        real = np.concatenate([self._open, np.ones(len(a_pos), bool), np.zeros(len(b_pos), bool)])
        key = np.concatenate([self._open_key, keys[a_pos], keys[b_pos]])[order]
        # the first frame before each event (the carried one before any of this push)
        latest = np.maximum.accumulate(np.where(is_first, np.arange(len(order)), 0))
        second = np.flatnonzero(~is_first)
        owner = latest[second]
        # one second frame per first frame: a second after the same first keeps its key
        takes = is_first[second - 1] & real[order][owner]
        takes &= (key[owner] >= key[second] - 1) & (key[owner] <= key[second])
        at = b_pos[order[second[takes]] - n_firsts]
        keys[at] = key[owner[takes]]
        answered = np.zeros(len(order), dtype=bool)
        answered[owner[takes]] = True
        # each pair's last first frame waits for its second if none took it
        firsts = np.flatnonzero(is_first)
        last = firsts[np.searchsorted(pair[order][firsts], np.arange(n_pairs), side="right") - 1]
        self._open = real[order][last] & ~answered[last]
        self._open_key = key[last]
