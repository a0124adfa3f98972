"""The dispatcher: actions off the sensing thread, each isolated, failures and hangs counted."""

from __future__ import annotations

import threading
import time

from hapticdesk.gestures.event import GestureEvent
from hapticdesk.runtime.dispatcher import ActionContext, Dispatcher, Route
from hapticdesk.runtime.lane import MAX_ABANDONED, Lane


def tap(i: int, region: str = "lamp") -> GestureEvent:
    return GestureEvent(float(i), "tap", region, 0.0, 0.0)


class Recorder:
    def __init__(self) -> None:
        self.seen: list[float] = []
        self.done = threading.Event()
        self.expect = 0

    def __call__(self, event: GestureEvent) -> None:
        self.seen.append(event.t)
        if len(self.seen) >= self.expect:
            self.done.set()


def test_events_go_to_matching_routes_in_order():
    lamp, fan = Recorder(), Recorder()
    dispatcher = Dispatcher()
    dispatcher.add_route(Route("lamp", lambda e: e.region == "lamp", [Lane("lamp", lamp)]))
    dispatcher.add_route(Route("fan", lambda e: e.region == "fan", [Lane("fan", fan)]))
    for i in range(50):
        dispatcher.submit(tap(i, "lamp" if i % 5 else "fan"))
    report = dispatcher.close(5.0)
    assert lamp.seen == [float(i) for i in range(50) if i % 5]
    assert fan.seen == [float(i) for i in range(0, 50, 5)]
    assert report.events == 50
    assert report.totals.ok == 50 and report.totals.failed == 0


def test_a_failing_action_is_counted_and_the_others_keep_going(caplog):
    good = Recorder()

    def broken(event: GestureEvent) -> None:
        raise ConnectionError("lamp unreachable")

    dispatcher = Dispatcher()
    dispatcher.add_route(Route("b", lambda e: True, [Lane("broken", broken), Lane("good", good)]))
    for i in range(5):
        dispatcher.submit(tap(i))
    report = dispatcher.close(5.0)
    assert good.seen == [0.0, 1.0, 2.0, 3.0, 4.0]
    assert report.lanes["broken"].failed == 5
    assert report.lanes["good"].ok == 5
    assert "broken failed: ConnectionError: lamp unreachable" in caplog.text


def test_a_hanging_call_is_timed_out_and_the_action_goes_on():
    release = threading.Event()
    seen: list[float] = []

    def sometimes_hangs(event: GestureEvent) -> None:
        if event.t == 1.0:
            release.wait(30)  # hangs until the test ends
        seen.append(event.t)

    others = Recorder()
    others.expect = 4
    dispatcher = Dispatcher(watchdog_interval_s=0.01)
    lane = Lane("hangs", sometimes_hangs, timeout_s=0.1)
    dispatcher.add_route(Route("r", lambda e: True, [lane, Lane("others", others)]))
    for i in range(4):
        dispatcher.submit(tap(i))
    assert others.done.wait(5)  # the hang did not hold back the other action
    report = dispatcher.close(5.0)
    release.set()
    assert others.seen == [0.0, 1.0, 2.0, 3.0]
    assert seen == [0.0, 2.0, 3.0]  # the events after the hung one still ran, in order
    assert report.lanes["hangs"].timed_out == 1
    assert report.lanes["hangs"].ok == 3


def test_a_slow_call_given_up_on_still_finishes_within_the_drain_before_the_end():
    # on a starved machine a call the watchdog gave up on may only be slow: what it sends
    # (the desk's event on the shared MQTT link) must go before the run closes that link
    finished: list[float] = []

    def slow(event: GestureEvent) -> None:
        time.sleep(0.45)
        finished.append(event.t)

    dispatcher = Dispatcher(watchdog_interval_s=0.01)
    dispatcher.add_route(Route("r", lambda e: True, [Lane("slow", slow, timeout_s=0.3)]))
    dispatcher.submit(tap(1))
    time.sleep(0.35)  # the watchdog has given up on the call
    report = dispatcher.close(5.0)
    assert report.lanes["slow"].timed_out == 1
    assert finished == [1.0]  # it finished before close returned


def test_a_hung_call_holds_the_end_for_its_timeout_once_more_and_no_longer():
    release = threading.Event()
    dispatcher = Dispatcher(watchdog_interval_s=0.01)
    hung = Lane("hung", lambda e: release.wait(30), timeout_s=0.3)
    dispatcher.add_route(Route("r", lambda e: True, [hung]))
    dispatcher.submit(tap(1))
    time.sleep(0.4)  # the watchdog has given up on it
    started = time.monotonic()
    dispatcher.close(5.0)
    waited = time.monotonic() - started
    release.set()
    assert 0.25 <= waited < 1.5  # the drain's other 4.7 s are left for the shared connections


def test_calls_left_behind_get_at_most_half_the_drain_together():
    # a hung webhook (7 s timeout) against a 1 s drain, beside two others: the shared
    # connections closed after the dispatcher still get half the drain
    release = threading.Event()
    dispatcher = Dispatcher(watchdog_interval_s=0.01)
    for name, timeout in (("webhook", 0.3), ("exec", 0.2), ("other", 0.1)):
        lane = Lane(name, lambda e: release.wait(30), timeout_s=timeout)
        dispatcher.add_route(Route(name, lambda e: True, [lane]))
    dispatcher.submit(tap(1))
    time.sleep(0.5)  # the watchdog has given up on all three
    for lane in dispatcher.lanes:
        lane.timeout_s = 7.0  # as long as an http action's
    started = time.monotonic()
    dispatcher.close(1.0)
    waited = time.monotonic() - started
    release.set()
    assert 0.4 <= waited < 0.75


def test_an_action_that_keeps_hanging_is_given_up_and_its_events_dropped():
    release = threading.Event()
    dispatcher = Dispatcher(watchdog_interval_s=0.01)
    lane = Lane("stuck", lambda e: release.wait(30), timeout_s=0.05)
    dispatcher.add_route(Route("r", lambda e: True, [lane]))
    submitted = 0
    while not lane.given_up:
        dispatcher.submit(tap(submitted))
        submitted += 1
        time.sleep(0.02)
    assert dispatcher.submit(tap(999)) is None  # never blocks, even now
    report = dispatcher.close(1.0)
    release.set()
    stats = report.lanes["stuck"]
    assert stats.timed_out == MAX_ABANDONED + 1
    assert stats.dropped >= 1
    assert stats.ok == 0


def test_a_full_lane_drops_and_counts_without_blocking():
    release = threading.Event()
    lane = Lane("slow", lambda e: release.wait(30), queue_size=3)
    results = [lane.submit(tap(i)) for i in range(10)]
    # one call running, three waiting: the rest are refused at once
    assert results.count(False) >= 6
    assert lane.stats.dropped == results.count(False)
    release.set()
    lane.close(deadline=time.monotonic() + 5)
    assert lane.stats.ok + lane.stats.dropped == 10


def test_events_still_queued_at_the_end_are_reported_not_run():
    release = threading.Event()
    dispatcher = Dispatcher()
    dispatcher.add_route(
        Route("r", lambda e: True, [Lane("slow", lambda e: release.wait(30), timeout_s=60)])
    )
    for i in range(5):
        dispatcher.submit(tap(i))
    report = dispatcher.close(0.2)
    release.set()
    stats = report.lanes["slow"]
    assert stats.not_run == 4  # one was running when time was up
    assert stats.timed_out == 1


def test_a_failing_binding_match_does_not_stop_dispatch():
    good = Recorder()

    def bad_match(event: GestureEvent) -> bool:
        raise ValueError("bug")

    dispatcher = Dispatcher()
    dispatcher.add_route(Route("bad", bad_match, [Lane("never", good)]))
    dispatcher.add_route(Route("ok", lambda e: True, [Lane("good", good)]))
    dispatcher.submit(tap(1))
    dispatcher.close(5.0)
    assert good.seen == [1.0]
    assert dispatcher.match_errors == 1


def test_actions_are_closed_and_shared_resources_released():
    closed: list[str] = []

    class Closing(Recorder):
        def close(self) -> None:
            closed.append("action")

    class Resource:
        def close(self, timeout: float) -> str:
            closed.append("resource")
            return "resource report"

    context = ActionContext("study")
    assert context.shared("r", Resource) is context.shared("r", Resource)
    dispatcher = Dispatcher()
    dispatcher.add_route(Route("r", lambda e: True, [Lane("closing", Closing())]))
    dispatcher.close(5.0)
    assert context.close_resources() == ["resource report"]
    assert closed == ["action", "resource"]


def test_a_dispatcher_closed_at_once_leaves_no_worker_behind():
    # a close with no drain time (a scene built and released without running, a reload's old
    # lanes on a starved machine) empties the queue before the idle workers take their stop:
    # they must still end, not wait on the queue for ever (one thread lost per close)
    before = set(threading.enumerate())
    for _ in range(5):
        dispatcher = Dispatcher()
        for name in ("lamp", "fan", "blind"):
            dispatcher.add_route(Route(name, lambda e: True, [Lane(name, Recorder())]))
        dispatcher.close(0.0)
    deadline = time.monotonic() + 5.0
    while time.monotonic() < deadline:
        left = [t for t in threading.enumerate() if t not in before and t.is_alive()]
        if not left:
            break
        time.sleep(0.02)
    assert left == []
