"""The dispatcher: gesture events to actions, off the sensing thread, each action on its own.

Every action use of a layout gets a *lane*: a bounded queue and a worker thread. The sensing
thread only matches bindings and puts events on lanes (never blocks), so a slow action cannot
delay sensing, and one action cannot delay another. Each call runs in its own ``try``; a
watchdog gives up on a call that runs past its timeout, counts it, and starts a fresh worker
for the lane (Python cannot kill the hung thread, it is left behind as a daemon; after
:data:`MAX_ABANDONED` of them the lane pauses for :data:`PAUSE_S`, its events are dropped and
counted meanwhile, and then it takes events again, which the log says). Events within one lane
keep their order. At the end of a run the calls left behind get their timeout once more (at
most half the drain, all together) before the shared connections close: on a starved machine
a call the watchdog gave up on may only be slow, and the connection it publishes on must not
say goodbye before it (a desk's event after its `offline`, seen once in a loaded test run).
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, Protocol

from hapticdesk.gestures.event import GestureEvent

log = logging.getLogger(__name__)

DEFAULT_TIMEOUT_S = 5.0
DEFAULT_LANE_QUEUE = 256
MAX_ABANDONED = 3  # hung calls per lane before the lane pauses
#: the labels whose retired lanes' counts are kept apart; the rest add up under EARLIER_LAYOUTS
MAX_RETIRED_LABELS = 1000
EARLIER_LAYOUTS = "(actions of earlier layouts)"
PAUSE_S = 30.0  # how long a lane that keeps hanging takes no events (a webhook server rebooting)
_STOP = object()


class Action(Protocol):
    """What an action factory returns: called once per matching gesture event.

    Optional: ``close()`` (called once at the end of a run) and ``timeout_s`` (how long one
    call may run before the dispatcher gives up on it; default :data:`DEFAULT_TIMEOUT_S`).
    """

    def __call__(self, event: GestureEvent) -> None: ...


class ActionContext:
    """What an action factory gets besides its options: the desk, the layout, shared resources.

    ``desk_name`` is the desk's name in what actions send (``{desk}`` in templates); the
    :class:`~hapticdesk.files.profile.DeskProfile` is ``profile``. ``settings`` is the
    layout's top-level mapping (a plugin reads its own section there); ``overrides`` holds
    command-line values over a section, by section name (``run --mqtt URL`` gives
    ``{"mqtt": {"broker": URL}}``). :meth:`shared` lets all actions of a run share one
    resource (one MQTT connection); resources are closed at the end, newest first, each with
    ``close(timeout)``: how long it may still take to deliver what it holds; after closing,
    its ``failure`` (text) says what went wrong and ``undelivered`` (int) how many messages
    it was handed but never delivered.
    """

    def __init__(
        self,
        desk_name: str,
        *,
        layout_path: Path | None = None,
        settings: Mapping[str, Any] | None = None,
        overrides: Mapping[str, Mapping[str, Any]] | None = None,
        profile: Any = None,
        layout: Any = None,
    ) -> None:
        self.desk_name = desk_name
        self.layout_path = layout_path
        self.settings: Mapping[str, Any] = settings if settings is not None else {}
        self.overrides: Mapping[str, Mapping[str, Any]] = dict(overrides or {})
        self.profile = profile
        self.layout = layout
        self._resources: dict[str, Any] = {}
        self._lock = threading.Lock()
        # what shared resources said went wrong when they closed (a run then exits non-zero)
        self.failures: list[str] = []
        #: messages the shared resources were handed but could not deliver (a connection's
        #: ``undelivered`` after closing: the broker was never there)
        self.undelivered = 0

    def resolve_path(self, path: str | Path) -> Path:
        """A path from the layout, relative to the layout file's folder."""
        p = Path(path).expanduser()
        if not p.is_absolute() and self.layout_path is not None:
            p = self.layout_path.parent / p
        return p

    def shared(self, key: str, create: Callable[[], Any]) -> Any:
        """The run's resource called ``key``, created by ``create()`` the first time."""
        with self._lock:
            if key not in self._resources:
                self._resources[key] = create()
            return self._resources[key]

    def resource(self, key: str) -> Any:
        """The run's resource called ``key`` if one was created, else None."""
        with self._lock:
            return self._resources.get(key)

    @property
    def desk(self) -> str:
        """The former name of :attr:`desk_name` (kept for plugins written against it)."""
        return self.desk_name

    def close_resources(self, timeout_s: float = 5.0) -> list[str]:
        """Close every shared resource (newest first) within ``timeout_s`` in total; returns
        what each reported. A resource's ``failure`` text after closing (e.g. commands it
        could not deliver) is added to :attr:`failures`."""
        notes: list[str] = []
        deadline = time.monotonic() + timeout_s
        for key, resource in reversed(list(self._resources.items())):
            close = getattr(resource, "close", None)
            if close is None:
                continue
            try:
                result = close(max(0.0, deadline - time.monotonic()))
            except Exception as err:
                log.warning("closing %s failed: %s: %s", key, type(err).__name__, err)
                notes.append(f"{key}: closing failed: {err}")
                continue
            if isinstance(result, str) and result:
                notes.append(result)
            failure = getattr(resource, "failure", None)  # e.g. commands not delivered
            if isinstance(failure, str) and failure:
                self.failures.append(failure)
            undelivered = getattr(resource, "undelivered", 0)
            if isinstance(undelivered, int) and not isinstance(undelivered, bool):
                self.undelivered += max(0, undelivered)
        self._resources.clear()
        return notes


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
        self.stats = LaneStats()
        self._queue: queue.Queue[Any] = queue.Queue(maxsize=queue_size)
        self._lock = threading.Lock()
        self._busy_since: float | None = None
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
            try:
                self._queue.put_nowait(event)
            except queue.Full:
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
            if self._busy_since is not None:  # still inside a call at the deadline
                self.stats.timed_out += 1
                self._generation += 1
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
            with self._lock:
                self._busy_since = time.monotonic()
            ok = False
            try:
                self.action(item)
                ok = True
            except Exception as err:
                error = err
            with self._lock:
                if generation != self._generation:  # the watchdog gave up on this call
                    log.info("%s: a call that timed out has finished after all", self.label)
                    return
                self._busy_since = None
                if ok:
                    self.stats.ok += 1
                else:
                    self.stats.failed += 1
                    log.warning("%s failed: %s: %s", self.label, type(error).__name__, error)

    def _drain(self) -> int:
        count = 0
        while True:
            try:
                item = self._queue.get_nowait()
            except queue.Empty:
                return count
            if item is not _STOP:
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


@dataclass
class Route:
    """A binding: which events it takes, and the lanes of its actions."""

    label: str
    matches: Callable[[GestureEvent], bool]
    lanes: list[Lane] = field(default_factory=list)


@dataclass
class DispatchReport:
    """Totals over all lanes, and the per-lane counts by label."""

    events: int = 0
    totals: LaneStats = field(default_factory=LaneStats)
    lanes: dict[str, LaneStats] = field(default_factory=dict)


class Dispatcher:
    """Routes gesture events to lanes; a watchdog enforces every lane's timeout."""

    def __init__(self, *, watchdog_interval_s: float = 0.05) -> None:
        self.routes: list[Route] = []
        self.sinks: list[Lane] = []  # lanes that see every event (plugins' event sinks)
        self.events = 0
        self.match_errors = 0
        #: lanes of routes a reload replaced, while they finish what they hold
        self.retired: list[Lane] = []
        #: the counts of retired lanes once finished, by label (a reload's successor shares
        #: it), at most MAX_RETIRED_LABELS of them: 751 reloads had kept every lane of every
        #: layout, 20 kB each
        self.retired_stats: dict[str, LaneStats] = {}
        self._retiring: list[threading.Thread] = []
        self._retired_lock = threading.Lock()
        self._closed = threading.Event()
        self._interval = watchdog_interval_s
        self._watchdog = threading.Thread(target=self._watch, name="action watchdog", daemon=True)
        self._watchdog.start()

    @property
    def lanes(self) -> list[Lane]:
        """The lanes taking events: every route's, then the sinks."""
        return [lane for route in self.routes for lane in route.lanes] + self.sinks

    def replace_routes(self, routes: list[Route], drain_s: float) -> None:
        """Use ``routes`` from now on (a layout reload), on the thread that calls
        :meth:`submit`. The old routes' lanes finish what they hold within ``drain_s`` on a
        thread of their own (this never blocks) and still count in :meth:`close`'s report."""
        old = [lane for route in self.routes for lane in route.lanes]
        self.routes = list(routes)
        with self._retired_lock:
            self.retired.extend(old)
        deadline = time.monotonic() + drain_s

        def retire() -> None:
            for lane in old:
                lane.close(deadline)
            with self._retired_lock:  # only their counts are kept
                for lane in old:
                    self.retired.remove(lane)
                    self._keep_counts(lane)

        thread = threading.Thread(target=retire, name="retire old actions", daemon=True)
        thread.start()
        self._retiring = [t for t in self._retiring if t.is_alive()] + [thread]

    def _keep_counts(self, lane: Lane) -> None:
        # under self._retired_lock
        label = lane.label
        if label not in self.retired_stats and len(self.retired_stats) >= MAX_RETIRED_LABELS:
            label = EARLIER_LAYOUTS
        self.retired_stats.setdefault(label, LaneStats()).add(lane.stats)

    def add_route(self, route: Route) -> None:
        self.routes.append(route)

    def add_sink(self, lane: Lane) -> None:
        self.sinks.append(lane)

    def submit(self, event: GestureEvent) -> None:
        """Hand ``event`` to every matching action. Never blocks; called on the sensing thread."""
        self.events += 1
        for route in self.routes:
            try:
                matched = route.matches(event)
            except Exception as err:  # a recognizer or binding bug must not stop sensing
                self.match_errors += 1
                log.warning("%s: matching failed: %s: %s", route.label, type(err).__name__, err)
                continue
            if matched:
                for lane in route.lanes:
                    lane.submit(event)
        for lane in self.sinks:
            lane.submit(event)

    def close(self, timeout_s: float = 5.0) -> DispatchReport:
        """Let queued calls run for up to ``timeout_s`` in total, then close every action."""
        deadline = time.monotonic() + timeout_s
        for lane in self.lanes:
            lane.close(deadline)
        self._wait_for_left_behind(deadline)
        for thread in self._retiring:
            thread.join(max(0.0, deadline - time.monotonic()))
        self._closed.set()
        self._watchdog.join(1.0)
        report = DispatchReport(events=self.events)
        with self._retired_lock:
            counted = [(lane.label, lane.stats) for lane in self.retired + self.lanes]
            counted += list(self.retired_stats.items())
        for label, stats in counted:
            # a lane a reload replaced and its successor share a label: their counts add up
            report.lanes.setdefault(label, LaneStats()).add(stats)
            report.totals.add(stats)
        return report

    def _wait_for_left_behind(self, deadline: float) -> None:
        """Calls the watchdog gave up on may be slow rather than hung (a starved machine):
        they get the longest of their lanes' timeouts once more, all together, and at most
        half of what is left of the drain, which the shared connections need to deliver the
        other actions' commands."""
        waiting = [(worker, lane.timeout_s) for lane in self.lanes for worker in lane.left_behind()]
        if not waiting:
            return
        now = time.monotonic()
        budget = min(max(timeout for _, timeout in waiting), max(0.0, deadline - now) / 2)
        for worker, _ in waiting:
            worker.join(max(0.0, now + budget - time.monotonic()))

    def _watch(self) -> None:
        while not self._closed.wait(self._interval):
            now = time.monotonic()
            with self._retired_lock:
                lanes = self.retired + self.lanes
            for lane in lanes:
                lane.check_timeout(now)
