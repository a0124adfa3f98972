"""A lane: one action use with its own bounded queue and worker thread, and the watchdog's part.

The sensing thread only puts events on a lane (never blocks), so a slow action cannot delay
sensing, and one action cannot delay another; events within one lane keep their order. Each
call runs in its own ``try``; a call that runs past its timeout is given up on
(:meth:`Lane.check_timeout`, called by the dispatcher's watchdog), counted, and a fresh worker
starts (Python cannot kill the hung thread, it is left behind as a daemon; after
:data:`MAX_ABANDONED` of them the lane pauses for :data:`PAUSE_S`, its events are dropped and
counted meanwhile, and then it takes events again, which the log says). An action with an
``order_key`` waits for its turn before each call (ordering.py): the actions sharing a device
keep the gestures' order across their lanes.
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, fields
from typing import Any

from hapticdesk.gestures.event import GestureEvent
from hapticdesk.runtime.ordering import Turnstile

log = logging.getLogger(__name__)

DEFAULT_TIMEOUT_S = 5.0
DEFAULT_LANE_QUEUE = 256
MAX_ABANDONED = 3  # hung calls per lane before the lane pauses
PAUSE_S = 30.0  # how long a lane that keeps hanging takes no events (a webhook server rebooting)
#: the longest a call waits for the calls before it of its ``order_key`` (each is given up on at
#: its own timeout, so only a lost turn waits this long; the turns before are then given up on)
ORDER_WAIT_S = 10.0
_TURN_SLICE_S = 0.1  # a worker waiting for its turn looks this often whether the run ended
_STOP = object()


@dataclass
class LaneStats:
    """Counts for one lane (one action use)."""

    submitted: int = 0
    ok: int = 0
    failed: int = 0
    timed_out: int = 0
    dropped: int = 0  # the lane's queue was full, or the lane was given up
    not_run: int = 0  # still queued when the run ended

    def add(self, other: LaneStats) -> None:
        for f in fields(self):
            setattr(self, f.name, getattr(self, f.name) + getattr(other, f.name))


class Lane:
    """One action with its own bounded queue and worker thread."""

    def __init__(
        self,
        label: str,
        action: Callable[[GestureEvent], Any],
        *,
        timeout_s: float | None = None,
        queue_size: int = DEFAULT_LANE_QUEUE,
        pause_s: float = PAUSE_S,
    ) -> None:
        self.label = label
        self.pause_s = pause_s
        self.action = action
        own = getattr(action, "timeout_s", None)
        self.timeout_s = float(timeout_s or own or DEFAULT_TIMEOUT_S)
        key = getattr(action, "order_key", None)
        #: the actions whose calls keep the gestures' order share this text (None: no order)
        self.order_key = key if isinstance(key, str) and key else None
        #: the key's turnstile, given by the dispatcher (None: the lane waits for nothing)
        self.turnstile: Turnstile | None = None
        self.stats = LaneStats()
        self._queue: queue.Queue[Any] = queue.Queue(maxsize=queue_size)
        self._lock = threading.Lock()
        self._busy_since: float | None = None
        self._ticket: int | None = None  # the turn of the call running now
        self._close_deadline: float | None = None
        self._generation = 0
        self._abandoned = 0
        self._paused_until: float | None = None  # given up until then (monotonic time)
        self.pauses = 0
        self._closed = False
        self._stopped = threading.Event()
        self._worker: threading.Thread | None = None
        self._left_behind: list[threading.Thread] = []  # workers inside a timed-out call
        self._start_worker()

    @property
    def given_up(self) -> bool:
        """Paused after hanging too often (it takes events again after :attr:`pause_s`)."""
        return self._paused_until is not None

    def submit(self, event: GestureEvent) -> bool:
        """Queue ``event`` without blocking; False (and counted) when it cannot be queued."""
        with self._lock:
            if self._closed:
                return False
            if self.given_up:
                self.stats.dropped += 1
                return False
            ticket = self.turnstile.take() if self.turnstile is not None else None
            try:
                self._queue.put_nowait((ticket, event))
            except queue.Full:
                self._turn_done(ticket)
                self.stats.dropped += 1
                if self.stats.dropped in (1, 10, 100) or self.stats.dropped % 1000 == 0:
                    log.warning(
                        "%s: its queue is full (%d waiting); %d event(s) dropped so far",
                        self.label,
                        self._queue.maxsize,
                        self.stats.dropped,
                    )
                return False
            self.stats.submitted += 1
            return True

    def check_timeout(self, now: float) -> None:
        """Give up on a call running past the timeout, and end a pause (called by the
        watchdog)."""
        with self._lock:
            if self._paused_until is not None:
                if now >= self._paused_until and not self._closed:
                    self._resume()
                return
            if self._busy_since is None or now - self._busy_since <= self.timeout_s:
                return
            self.stats.timed_out += 1
            self._busy_since = None
            self._generation += 1
            self._turn_done(self._ticket)  # the calls after it of its key may go
            self._abandoned += 1
            if self._abandoned > MAX_ABANDONED:
                self.pauses += 1
                self._paused_until = now + self.pause_s
                self._leave_behind()
                log.error(
                    "%s: a call ran past its %.3g s timeout again (%d times); this action is "
                    "paused for %.3g s, its events meanwhile are dropped",
                    self.label,
                    self.timeout_s,
                    self._abandoned,
                    self.pause_s,
                )
                self.stats.dropped += self._drain()
                self._stopped.set()  # no worker takes anything during the pause
                return
            log.warning(
                "%s: a call ran past its %.3g s timeout; it is left behind and the action "
                "goes on with the next event",
                self.label,
                self.timeout_s,
            )
            self._leave_behind()
            self._start_worker()

    def close(self, deadline: float) -> None:
        """Stop taking events, let queued ones run until ``deadline``, then close the action."""
        with self._lock:
            self._closed = True
            self._close_deadline = deadline
        if not self.given_up:
            while True:
                try:
                    self._queue.put(_STOP, timeout=max(0.0, deadline - time.monotonic()))
                    break
                except queue.Full:
                    if time.monotonic() >= deadline:
                        break
            # whichever worker takes the stop (the watchdog may replace a hung one meanwhile)
            self._stopped.wait(max(0.0, deadline - time.monotonic()))
        with self._lock:
            self.stats.not_run += self._drain()
            if not self._stopped.is_set():
                # the drain took the stop too: an idle worker that had not got to it yet would
                # wait on the queue for ever (one thread lost per close, a reload's too)
                self._queue.put_nowait(_STOP)
            if self._busy_since is not None:  # still inside a call at the deadline
                self.stats.timed_out += 1
                self._generation += 1
                self._turn_done(self._ticket)
        # the action's close gets what is left of the deadline, no more (--drain is a promise)
        self._close_action(max(0.0, deadline - time.monotonic()))

    # --- internals ----------------------------------------------------------------------------

    def _resume(self) -> None:
        # under self._lock
        log.warning(
            "%s: taking events again after a pause of %.3g s (%d event(s) were dropped)",
            self.label,
            self.pause_s,
            self.stats.dropped,
        )
        self._paused_until = None
        self._abandoned = 0
        self._stopped.clear()
        self._start_worker()

    def left_behind(self) -> list[threading.Thread]:
        """The workers still inside a call the watchdog gave up on."""
        with self._lock:
            return [w for w in self._left_behind if w.is_alive()]

    def _leave_behind(self) -> None:
        # under self._lock: the worker inside the call given up on
        if self._worker is not None:
            self._left_behind = [w for w in self._left_behind if w.is_alive()]
            self._left_behind.append(self._worker)

    def _start_worker(self) -> None:
        self._worker = threading.Thread(
            target=self._run,
            args=(self._generation,),
            name=f"action {self.label}",
            daemon=True,  # a hung action must not keep the process alive
        )
        self._worker.start()

    def _run(self, generation: int) -> None:
        while True:
            item = self._queue.get()
            if item is _STOP:
                self._stopped.set()
                return
            ticket, event = item
            if not self._wait_turn(ticket):
                continue  # the run ended while it waited: not run
            with self._lock:
                self._busy_since = time.monotonic()
                self._ticket = ticket
            ok = False
            try:
                self.action(event)
                ok = True
            except Exception as err:
                error = err
            with self._lock:
                if generation != self._generation:  # the watchdog gave up on this call
                    log.info("%s: a call that timed out has finished after all", self.label)
                    return
                self._busy_since = None
                self._ticket = None
                self._turn_done(ticket)
                if ok:
                    self.stats.ok += 1
                else:
                    self.stats.failed += 1
                    log.warning("%s failed: %s: %s", self.label, type(error).__name__, error)

    def _wait_turn(self, ticket: int | None) -> bool:
        """Wait for the calls before ``ticket`` of this lane's key; False (counted not run) if
        the run's drain ended first. A turn not come in :data:`ORDER_WAIT_S` is taken anyway,
        the turns before it given up on (said in the log): a lost turn holds nothing forever."""
        if ticket is None or self.turnstile is None:
            return True
        waited_until = time.monotonic() + ORDER_WAIT_S
        while True:
            turn = self.turnstile.wait_turn(ticket, _TURN_SLICE_S)
            now = time.monotonic()
            with self._lock:  # a turn come after the drain's end is not taken either
                if self._close_deadline is not None and now >= self._close_deadline:
                    self.stats.not_run += 1
                    self._turn_done(ticket)
                    return False
            if turn:
                return True
            if now >= waited_until:
                log.error(
                    "%s: the calls before this one of `%s` did not end in %.3g s; it goes on",
                    self.label,
                    self.turnstile.key,
                    ORDER_WAIT_S,
                )
                self.turnstile.give_way(ticket)

    def _turn_done(self, ticket: int | None) -> None:
        if ticket is not None and self.turnstile is not None:
            self.turnstile.done(ticket)

    def _drain(self) -> int:
        count = 0
        while True:
            try:
                item = self._queue.get_nowait()
            except queue.Empty:
                return count
            if item is not _STOP:
                self._turn_done(item[0])  # never run: the calls after it may go
                count += 1

    def _close_action(self, timeout: float) -> None:
        close = getattr(self.action, "close", None)
        if close is None:
            return
        done = threading.Event()

        def run() -> None:
            try:
                close()
            except Exception as err:
                log.warning("%s: close failed: %s: %s", self.label, type(err).__name__, err)
            finally:
                done.set()

        threading.Thread(target=run, name=f"close {self.label}", daemon=True).start()
        if not done.wait(timeout):
            log.warning("%s: close did not finish within %.3g s", self.label, timeout)
