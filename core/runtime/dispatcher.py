"""The dispatcher: gesture events to actions, off the sensing thread, each action on its own.

Every action use of a layout gets a *lane* (lane.py: a bounded queue and a worker thread). The
sensing thread only matches bindings (:class:`Route`) and puts events on lanes (never blocks);
actions that declare the same ``order_key`` take their turns in the gestures' order
(ordering.py: one turnstile per key, shared by a reload's new lanes and the old);
the dispatcher's watchdog thread asks each lane to give up on a call past its timeout, and
:class:`ActionContext` is what every action factory shares of a run. At the end of a run the
calls left behind get their timeout once more (at most half the drain, all together) before
the shared connections close: on a starved machine a call the watchdog gave up on may only be
slow, and the connection it publishes on must not say goodbye before it (a desk's event after
its `offline`, seen once in a loaded test run).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

from hapticdesk.gestures.event import GestureEvent
from hapticdesk.runtime.lane import Lane, LaneStats
from hapticdesk.runtime.ordering import Turnstile

log = logging.getLogger(__name__)

#: the labels whose retired lanes' counts are kept apart; the rest add up under EARLIER_LAYOUTS
MAX_RETIRED_LABELS = 1000
EARLIER_LAYOUTS = "(actions of earlier layouts)"


class Action(Protocol):
    """What an action factory returns: called once per matching gesture event.

    Optional: ``close()`` (called once at the end of a run), ``timeout_s`` (how long one
    call may run before the dispatcher gives up on it; default
    :data:`~hapticdesk.runtime.lane.DEFAULT_TIMEOUT_S`) and ``order_key`` (a text: actions
    with the same key are called in the order of the gestures that matched them, each after
    the calls before it of that key have ended or been given up on; e.g. every action that
    commands the same device).
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
        self._turnstiles: dict[str, Turnstile] = {}  # by order_key
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
        for route in routes:
            self._order(route.lanes)
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
        self._order(route.lanes)
        self.routes.append(route)

    def add_sink(self, lane: Lane) -> None:
        self._order([lane])
        self.sinks.append(lane)

    def _order(self, lanes: list[Lane]) -> None:
        # before the lanes take their first event, so that every ticket is in submit order
        for lane in lanes:
            key = lane.order_key
            if key is not None:
                lane.turnstile = self._turnstiles.setdefault(key, Turnstile(key))

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
