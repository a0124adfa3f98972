"""Actions that share an ``order_key`` are called in the gestures' order, across their lanes;
a slow, hung, dropped or never-run call of the key holds the others back no longer than it
lasts or is given up on."""

from __future__ import annotations

import threading
import time

import pytest

from hapticdesk.gestures.event import GestureEvent
from hapticdesk.runtime.dispatcher import ActionContext, Dispatcher, Route
from hapticdesk.runtime.lane import Lane
from hapticdesk.runtime.ordering import Turnstile


def tap(i: int, region: str) -> GestureEvent:
    return GestureEvent(float(i), "tap", region, 0.0, 0.0)


class Device:
    """Where the actions' calls land: (action, event time) in the order they arrive."""

    def __init__(self) -> None:
        self.calls: list[tuple[str, float]] = []
        self.lock = threading.Lock()

    def action(self, name: str, *, delay_s: float = 0.0, key: str | None = None) -> object:
        device = self

        class Command:
            order_key = key
            timeout_s = 0.3

            def __call__(self, event: GestureEvent) -> None:
                time.sleep(delay_s)
                with device.lock:
                    device.calls.append((name, event.t))

        return Command()


def two_buttons(device: Device, slow_s: float, key: str | None) -> Dispatcher:
    """`on` (slow) bound to one region, `off` (fast) to another: two actions, two lanes."""
    dispatcher = Dispatcher(watchdog_interval_s=0.01)
    on = device.action("on", delay_s=slow_s, key=key)
    off = device.action("off", key=key)
    dispatcher.add_route(Route("on", lambda e: e.region == "on", [Lane("on", on)]))
    dispatcher.add_route(Route("off", lambda e: e.region == "off", [Lane("off", off)]))
    return dispatcher


@pytest.mark.parametrize("key", [None, "lamp"])
def test_two_actions_of_one_key_reach_the_device_in_the_gestures_order(key):
    device = Device()
    dispatcher = two_buttons(device, slow_s=0.1, key=key)
    dispatcher.submit(tap(1, "on"))
    dispatcher.submit(tap(2, "off"))  # a moment later, on the other action's lane
    report = dispatcher.close(5.0)
    assert report.totals.ok == 2
    if key is None:  # each action on its own: the fast one lands first (what was fixed)
        assert device.calls == [("off", 2.0), ("on", 1.0)]
    else:
        assert device.calls == [("on", 1.0), ("off", 2.0)]


def test_many_gestures_keep_their_order_across_three_actions():
    device = Device()
    dispatcher = Dispatcher()
    actions = {name: device.action(name, delay_s=d, key="lamp") for name, d in
               [("a", 0.003), ("b", 0.0), ("c", 0.001)]}  # fmt: skip
    for name, action in actions.items():
        dispatcher.add_route(
            Route(name, lambda e, n=name: e.region == n, [Lane(name, action)])  # type: ignore[misc]
        )
    sent = [(name, float(i)) for i, name in enumerate("abcacbbca" * 6)]
    for name, t in sent:
        dispatcher.submit(GestureEvent(t, "tap", name, 0.0, 0.0))
    report = dispatcher.close(10.0)
    assert report.totals.ok == len(sent)
    assert device.calls == sent


def test_a_hung_call_holds_the_key_back_only_until_it_is_given_up_on():
    device = Device()
    dispatcher = two_buttons(device, slow_s=2.0, key="lamp")  # `on` hangs past its 0.3 s
    start = time.monotonic()
    dispatcher.submit(tap(1, "on"))
    dispatcher.submit(tap(2, "off"))
    deadline = start + 1.5
    while ("off", 2.0) not in device.calls and time.monotonic() < deadline:
        time.sleep(0.01)
    waited = time.monotonic() - start
    assert device.calls == [("off", 2.0)]  # `on` is still hung, `off` went after its timeout
    assert 0.3 <= waited < 1.5
    report = dispatcher.close(0.5)
    assert report.lanes["on"].timed_out == 1 and report.lanes["off"].ok == 1


def test_a_dropped_event_does_not_hold_the_key_back():
    device = Device()
    dispatcher = Dispatcher()
    on = device.action("on", delay_s=0.1, key="lamp")
    off = device.action("off", key="lamp")
    dispatcher.add_route(Route("on", lambda e: e.region == "on", [Lane("on", on, queue_size=1)]))
    dispatcher.add_route(Route("off", lambda e: e.region == "off", [Lane("off", off)]))
    for i in range(4):  # the first runs, the second waits in the queue, the rest are dropped
        dispatcher.submit(tap(i, "on"))
    dispatcher.submit(tap(9, "off"))
    report = dispatcher.close(5.0)
    assert report.lanes["on"].dropped >= 1
    assert device.calls[-1] == ("off", 9.0)
    assert len(device.calls) == report.lanes["on"].ok + 1


def test_a_call_waiting_for_its_turn_when_the_run_ends_is_counted_not_run():
    device = Device()
    dispatcher = Dispatcher(watchdog_interval_s=10.0)  # no watchdog: `on` is never given up
    on = device.action("on", delay_s=1.0, key="lamp")
    off = device.action("off", key="lamp")
    dispatcher.add_route(Route("on", lambda e: e.region == "on", [Lane("on", on, timeout_s=5)]))
    dispatcher.add_route(Route("off", lambda e: e.region == "off", [Lane("off", off)]))
    dispatcher.submit(tap(1, "on"))
    dispatcher.submit(tap(2, "off"))
    time.sleep(0.05)
    start = time.monotonic()
    report = dispatcher.close(0.3)
    assert time.monotonic() - start < 1.0  # the drain is a promise
    time.sleep(1.2)  # `on` ends after the run: `off`, behind it, never runs
    assert ("off", 2.0) not in device.calls
    assert report.lanes["off"].not_run == 1


def test_a_reloaded_layout_s_actions_wait_for_the_old_ones_of_their_key():
    device = Device()
    dispatcher = Dispatcher()
    old = device.action("old", delay_s=0.1, key="lamp")
    dispatcher.add_route(Route("old", lambda e: True, [Lane("old", old)]))
    dispatcher.submit(tap(1, "desk"))
    new = device.action("new", key="lamp")
    dispatcher.replace_routes([Route("new", lambda e: True, [Lane("new", new)])], drain_s=2.0)
    dispatcher.submit(tap(2, "desk"))
    dispatcher.close(5.0)
    assert device.calls == [("old", 1.0), ("new", 2.0)]


def test_a_turn_lost_is_given_way_to():
    turns = Turnstile("lamp")
    first, second, third = turns.take(), turns.take(), turns.take()
    turns.done(third)  # done early: its turn comes after the second's
    assert not turns.wait_turn(second, 0.01)
    turns.give_way(second)  # the first never said done
    assert turns.wait_turn(second, 0.0)
    turns.done(second)
    assert turns.wait_turn(third + 1, 0.0)  # the third, done early, is passed too
    turns.done(first)  # late and twice: harmless
    turns.done(first)
    assert turns.wait_turn(third + 1, 0.0)


def test_log_lines_keep_the_gestures_order_across_bindings(capsys):
    # each binding's `log` runs on its own lane: at --speed 0 a later tap's line came out
    # before an earlier one's (b2 before b1); they print to one standard output, so they
    # share an order key
    from hapticdesk.plugins.log import LogAction

    class SlowFirst(LogAction):  # (the first gesture's line takes a moment to make)
        def __call__(self, event: GestureEvent) -> None:
            if event.region == "b1":
                time.sleep(0.1)
            super().__call__(event)

    dispatcher = Dispatcher(watchdog_interval_s=0.01)
    for region in ("b1", "b2"):
        action = SlowFirst({"message": "{{ region }}"}, ActionContext("desk"))
        lane = Lane(region, action)
        dispatcher.add_route(Route(region, lambda e, r=region: e.region == r, [lane]))  # type: ignore[misc]
    dispatcher.submit(tap(1, "b1"))
    dispatcher.submit(tap(2, "b2"))
    assert dispatcher.close(5.0).totals.ok == 2
    assert capsys.readouterr().out.splitlines() == ["[desk] b1", "[desk] b2"]
