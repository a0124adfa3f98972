"""Lanes that keep hanging, slow ``close``, and option values the run must refuse (issue 11)."""

from __future__ import annotations

import logging
import subprocess
import sys
import threading
import time

import pytest

from hapticdesk.gestures.event import GestureEvent
from hapticdesk.runtime.dispatcher import Dispatcher, Route
from hapticdesk.runtime.lane import MAX_ABANDONED, Lane


def tap(i: int) -> GestureEvent:
    return GestureEvent(float(i), "tap", "lamp", 0.0, 0.0)


class Webhook:
    """Hangs while ``down`` is set (a server that accepts and never answers), else records."""

    def __init__(self) -> None:
        self.down = threading.Event()
        self.down.set()
        self.seen: list[float] = []

    def __call__(self, event: GestureEvent) -> None:
        if self.down.is_set():
            time.sleep(30)
        self.seen.append(event.t)


def test_a_lane_that_kept_hanging_takes_events_again_after_a_pause(caplog):
    hook = Webhook()
    lane = Lane("binding 1 → http", hook, timeout_s=0.1, pause_s=0.6)
    dispatcher = Dispatcher(watchdog_interval_s=0.01)
    dispatcher.add_route(Route("b", lambda e: True, [lane]))
    with caplog.at_level(logging.WARNING):
        for i in range(MAX_ABANDONED + 1):  # each one hangs and is given up on
            dispatcher.submit(tap(i))
            time.sleep(0.2)
        assert lane.given_up
        dispatcher.submit(tap(100))  # during the pause: dropped, counted
        hook.down.clear()  # the server is back
        time.sleep(0.8)
        assert not lane.given_up
        dispatcher.submit(tap(200))
        report = dispatcher.close(3.0)
    assert hook.seen == [200.0]
    stats = report.lanes["binding 1 → http"]
    assert (stats.timed_out, stats.ok, stats.dropped) == (MAX_ABANDONED + 1, 1, 1)
    assert "paused for 0.6 s" in caplog.text
    assert "taking events again after a pause of 0.6 s" in caplog.text


class SlowClose:
    def __call__(self, event: GestureEvent) -> None:
        pass

    def close(self) -> None:
        time.sleep(3)


def test_slow_close_of_many_actions_stays_within_the_drain_time():
    dispatcher = Dispatcher()
    lanes = [Lane(f"slow {i}", SlowClose()) for i in range(4)]
    dispatcher.add_route(Route("b", lambda e: True, lanes))
    dispatcher.submit(tap(0))
    started = time.monotonic()
    dispatcher.close(1.0)
    took = time.monotonic() - started
    assert took < 1.25, took


@pytest.mark.parametrize(
    ("option", "value", "expected"),
    [
        ("--action-timeout", "nan", "expected a finite number of seconds"),
        ("--action-timeout", "0", "expected a number of seconds above 0"),
        ("--drain", "inf", "expected a finite number of seconds"),
        ("--drain", "-1", "expected a finite number of seconds >= 0"),
        ("--drain", "1e10", "expected at most 86400 seconds"),  # (overflowed the wait)
        ("--action-timeout", "1e10", "expected at most 86400 seconds"),
    ],
)
def test_time_options_must_be_finite_seconds(tmp_path, option, value, expected):
    layout = tmp_path / "layout.yaml"
    layout.write_text("desk: kitamura2017\nregions: {}\nbindings: []\n")
    done = subprocess.run(
        [sys.executable, "-m", "hapticdesk", "run", "--layout", str(layout),
         "--source", "replay:none.csv", option, value],
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert done.returncode == 2
    assert f"argument {option}: {expected}" in done.stderr
