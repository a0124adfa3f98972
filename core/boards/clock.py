"""The board's stamps into sample times: its own clock, wrap-around, losses, resets, gaps.

Within one *epoch* (from the first sample, a reset or a reconnect on) a sample's time is the
board's clock and nothing else: ``t = t_epoch + (stamp - stamp_epoch) / units`` with the
stamp unwrapped (``wrap``, 2³² by default) — a sequence number counts sample periods, a µs
stamp is the board's ``micros()``. The host's clock never enters within an epoch, so host
jitter and drift between the clocks make no jumps; the host's arrival times only judge
whether a stamp is plausible (it may not run ahead of the time the host saw pass by more
than :data:`SLACK_S`: a reset's stamp going back is a jump of nearly ``wrap``).

- A step of more than one period is a loss: ``steps - 1`` samples (a µs stamp: beyond
  :data:`JUMP_PERIODS` periods, rounded), counted, and the time step is kept as it was —
  never filled in. A step longer than the estimator's ``max_gap_s`` is a gap it flags.
- A stamp that repeats the previous one is dropped. One that jumps is judged by the line
  after it: when that one continues the old sequence, the jumped line was garbled (dropped);
  when it continues from the jump, the board restarted: a new epoch.
- A new epoch (a reset, a hello the host did not ask for, a reconnect) begins after the
  time the host saw pass, and at least ``max_gap_s`` plus a period after the last sample:
  what the board did meanwhile is unknown, so the estimator always sees a gap there.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from hapticdesk.boards.hello import BoardHello
from hapticdesk.boards.lines import OUT_OF_SEQUENCE, REPEAT

#: how far (s) a stamp may run ahead of the time the host saw pass (reads come in bursts)
SLACK_S = 1.0
#: with a µs stamp, a step longer than this many periods has lost samples
JUMP_PERIODS = 1.5


@dataclass(frozen=True)
class ClockEvent:
    """Something the clock saw: ``kind`` ``lost`` (``count`` samples before ``t``), ``gap``
    (``seconds`` without samples before ``t``), ``reset`` (the board restarted: a new epoch
    at ``t``) or ``resume`` (a new epoch after the port was opened again);
    ``line`` the line number it was seen at, ``detail`` the stamps involved."""

    kind: str
    t: float
    line: int
    count: int = 0
    seconds: float = 0.0
    detail: str = ""


@dataclass
class Placement:
    """Where a run of samples went: ``times`` of those kept; per input sample ``dropped``
    (0, or :data:`~hapticdesk.boards.lines.REPEAT` /
    :data:`~hapticdesk.boards.lines.OUT_OF_SEQUENCE`); ``fresh`` (per kept sample) True for
    the first of an epoch or after a gap (no earlier sample to align with); ``held`` how
    many trailing samples wait for the next read (a jumped stamp judged by its successor)."""

    times: np.ndarray
    dropped: np.ndarray
    fresh: np.ndarray
    held: int = 0
    lost: int = 0
    events: list[ClockEvent] = field(default_factory=list)


class BoardClock:
    """Sample times for one board's stamps (module docstring). ``max_gap_s``: the
    estimator's; an epoch starts at least this plus a period after the last sample."""

    def __init__(self, hello: BoardHello, max_gap_s: float) -> None:
        self.hello = hello
        self.units = hello.stamp_units_per_s
        self.period_units = hello.stamp_units_per_s / hello.rate_hz
        self.max_gap_s = max_gap_s
        self.min_epoch_gap_s = max_gap_s + 1.0 / hello.rate_hz
        self._stamp: int | None = None  # the last kept sample's raw stamp
        self._board: int = 0  # its unwrapped stamp
        self._host = 0.0  # its arrival
        self._t = 0.0  # its sample time
        self._epoch_board = 0
        self._epoch_t = 0.0
        self._restart: str | None = "start"  # the next sample begins an epoch, and why
        self._restart_kind = "reset"  # ... as a ClockEvent kind: "reset" or "resume"
        self.epochs = 0

    @property
    def last_t(self) -> float | None:
        """The last sample time given out (None before the first)."""
        return self._t if self.epochs else None

    def restart(self, why: str, *, board_restarted: bool = True) -> None:
        """The next sample begins a new epoch: the board restarted (a hello nobody asked
        for), or not (the port was opened again: a ``resume``)."""
        if self.epochs:
            self._restart = why
            self._restart_kind = "reset" if board_restarted else "resume"

    def place(
        self, stamps: np.ndarray, host_t: np.ndarray, lines: np.ndarray, *, final: bool = False
    ) -> Placement:
        """Times for ``stamps`` (m,) that arrived at ``host_t`` on ``lines``. A last sample
        whose stamp jumped is held for the next call unless ``final``."""
        m = len(stamps)
        wrap = self.hello.wrap
        times = np.empty(m)
        kept = np.zeros(m, bool)
        fresh = np.zeros(m, bool)
        dropped = np.zeros(m, np.int8)
        events: list[ClockEvent] = []
        lost = 0
        held = 0
        i = 0
        while i < m:
            if self._restart is not None:
                self._begin_epoch(int(stamps[i]), float(host_t[i]), int(lines[i]), events)
                times[i], kept[i], fresh[i] = self._t, True, True
                i += 1
                continue
            # the common case, vectorised: every step forward and plausible
            assert self._stamp is not None  # (an epoch has begun)
            step = np.diff(stamps[i:], prepend=self._stamp) % wrap
            host_steps = np.diff(host_t[i:], prepend=self._host)
            ok = (step > 0) & (step <= (host_steps + SLACK_S) * self.units)
            n_ok = m - i if ok.all() else int(np.argmin(ok))
            if n_ok:
                run = slice(i, i + n_ok)
                step = step[:n_ok]
                board = self._board + np.cumsum(step)
                t = self._epoch_t + (board - self._epoch_board) / self.units
                times[run], kept[run] = t, True
                if step.max() > self.period_units:  # (rare) samples lost, maybe a gap
                    lost += self._losses(step, t, lines[run], events)
                    fresh[run] = self._gaps(t, lines[run], events)
                self._stamp, self._board = int(stamps[i + n_ok - 1]), int(board[-1])
                self._host, self._t = float(host_t[i + n_ok - 1]), float(t[-1])
                i += n_ok
                continue
            # a rare event at i: a repeat, a garbled stamp or a restart
            if step[0] == 0:
                dropped[i] = REPEAT
                i += 1
                continue
            if i + 1 == m and not final:
                held = 1
                break
            if i + 1 < m and self._follows(self._stamp, self._host, stamps[i + 1], host_t[i + 1]):
                dropped[i] = OUT_OF_SEQUENCE  # the next one continues the old sequence
                i += 1
                continue
            if i + 1 == m or self._follows(int(stamps[i]), host_t[i], stamps[i + 1], host_t[i + 1]):
                self._restart = f"the stamp jumped from {self._stamp} to {int(stamps[i])}"
                self._restart_kind = "reset"
                continue
            dropped[i] = OUT_OF_SEQUENCE
            i += 1
        return Placement(times[kept], dropped[: m - held], fresh[kept], held, lost, events)

    def _gaps(self, t: np.ndarray, lines: np.ndarray, events: list[ClockEvent]) -> np.ndarray:
        """Which of the samples placed at ``t`` (after the last one given out) come over
        ``max_gap_s`` after the one before: each such gap is said in ``events``."""
        steps_s = np.diff(t, prepend=self._t)
        gaps = steps_s > self.max_gap_s
        for k in np.flatnonzero(gaps):
            events.append(ClockEvent("gap", float(t[k]), int(lines[k]), seconds=steps_s[k]))
        return gaps

    def _follows(self, stamp: int | None, host: float, nxt: int, nxt_host: float) -> bool:
        """Whether stamp ``nxt`` plausibly comes after ``stamp`` (forward, not ahead of the
        host's time)."""
        if stamp is None:
            return False
        step = (int(nxt) - int(stamp)) % self.hello.wrap
        return 0 < step and step / self.units <= float(nxt_host) - float(host) + SLACK_S

    def _begin_epoch(self, stamp: int, host: float, line: int, events: list[ClockEvent]) -> None:
        why = self._restart
        if self.epochs:
            away = max(host - self._host, self.min_epoch_gap_s)
            t = self._t + away
            kind = self._restart_kind
            events.append(ClockEvent(kind, t, line, seconds=away, detail=str(why)))
        else:
            t = 0.0
        self.epochs += 1
        self._restart = None
        self._stamp, self._board, self._host, self._t = stamp, stamp, host, t
        self._epoch_board, self._epoch_t = stamp, t

    def _losses(
        self, step: np.ndarray, t: np.ndarray, lines: np.ndarray, events: list[ClockEvent]
    ) -> int:
        periods = step / self.period_units
        if self.hello.stamp == "seq":
            missing = step - 1
        else:
            missing = np.where(periods > JUMP_PERIODS, np.rint(periods) - 1, 0).astype(np.int64)
        for k in np.flatnonzero(missing > 0):
            events.append(ClockEvent("lost", float(t[k]), int(lines[k]), count=int(missing[k])))
        return int(missing.sum())
