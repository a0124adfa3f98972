"""Pacing: a finite source (recording, simulation, CAN log) delivered on its own sample clock.

Blocks are held back until their last sample's time has come on the wall clock (scaled by
``speed``), as a live source would deliver them. The source base owns it
(:meth:`hapticdesk.runtime.source.Source.paced`), so every finite source plugin (``replay``,
``sim``) plays the same way.
"""

from __future__ import annotations

import threading
import time

from hapticdesk.errors import ConfigError

#: replay speeds (times real time) a person would ask for; beyond them a typing mistake
MIN_SPEED, MAX_SPEED = 1e-3, 1e6
#: one wait at most this long (s); a longer pause is waited in pieces
LONGEST_WAIT_S = 60.0


def check_speed(speed: float) -> float:
    """``--speed``: 0 (as fast as possible) or :data:`MIN_SPEED` to :data:`MAX_SPEED` times
    real time (ConfigError otherwise, NaN too): 1e-300 overflowed the clock, 1e-9 would wait
    for ever. Every command that paces samples takes it through here."""
    if not (speed == 0 or MIN_SPEED <= speed <= MAX_SPEED):
        raise ConfigError(
            "--speed",
            f"must be 0 (as fast as possible) or {MIN_SPEED:g} to {MAX_SPEED:g} times real "
            f"time, found {speed:g}",
        )
    return speed


class Pacer:
    """Holds blocks back until their sample time has come: wall = start + (t - t0) / speed.

    ``speed`` 0 never waits. :meth:`wall_time` maps a sample time to the wall clock
    (``time.perf_counter``), which is how the latency benchmark knows when a tap really ended.
    """

    def __init__(self, speed: float, stop: threading.Event) -> None:
        self.speed = check_speed(speed)
        self._stop = stop
        self.t0: float | None = None
        self.started_at: float | None = None

    def wait_for(self, t: float) -> bool:
        """Wait until sample time ``t`` has come; False when stopped meanwhile."""
        if self.t0 is None:
            self.t0, self.started_at = t, time.perf_counter()
        if self.speed == 0:
            return not self._stop.is_set()
        delay = self.wall_time(t) - time.perf_counter()
        while delay > 0:  # in pieces: a wait longer than the clock can hold overflows
            if self._stop.wait(min(delay, LONGEST_WAIT_S)):
                return False
            delay = self.wall_time(t) - time.perf_counter()
        return not self._stop.is_set()

    def wall_time(self, t: float) -> float:
        assert self.t0 is not None and self.started_at is not None, "not started"
        return self.started_at + (t - self.t0) / (self.speed or float("inf"))
