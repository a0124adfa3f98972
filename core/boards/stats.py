"""What a board's stream held: counts for the run's summary, and notices naming each line.

Every garbled line is counted by reason and named (its line number, why, its first bytes);
every loss by how many samples; every reset and gap with the time it happened. A user's log
shows the first :data:`NAMED_PER_KIND` of each kind one by one and then one line per
:data:`ROLLUP_S` saying how many more; :attr:`SerialStats.notices` keeps the most recent
:data:`NOTICES_KEPT` of them all, so a stream of garbage cannot grow memory.
"""

from __future__ import annotations

import collections
import logging
import time
from dataclasses import dataclass, field

from hapticdesk.boards.lines import REASONS

log = logging.getLogger("hapticdesk.boards")

NOTICES_KEPT = 1000
NAMED_PER_KIND = 10
ROLLUP_S = 10.0


@dataclass(frozen=True)
class BoardNotice:
    """Something about the stream a user should know: ``kind`` garbled, lost, gap, reset,
    port, silent, hello; ``t`` the sample time it concerns (s; None before the first)."""

    kind: str
    t: float | None
    message: str


@dataclass
class SerialStats:
    """Counts of everything read from one board (the run's summary)."""

    bytes: int = 0
    lines: int = 0
    samples: int = 0  # given out
    sample_lines: int = 0  # lines read as samples (given out, or dropped by the clock)
    hellos: int = 0
    comments: int = 0
    before_hello: int = 0  # sample lines before the first hello (unreadable yet, skipped)
    garbled: dict[int, int] = field(default_factory=dict)  # reason code -> lines
    lost: int = 0  # samples missing from the sequence (garbled lines' included)
    loss_runs: int = 0  # places where samples were missing
    gaps: int = 0  # steps longer than the estimator's max_gap_s (a reset's included)
    resets: int = 0  # the board's clock restarted
    reconnects: int = 0  # the port was lost and opened again
    missing_values: int = 0  # empty fields (a channel the board could not read), NaN
    unaligned: int = 0  # samples with offsets given as read (first of an epoch or after a gap)
    notices: collections.deque[BoardNotice] = field(
        default_factory=lambda: collections.deque(maxlen=NOTICES_KEPT)
    )
    _told: collections.Counter[str] = field(default_factory=collections.Counter)
    _untold: collections.Counter[str] = field(default_factory=collections.Counter)
    _rollup_at: float = 0.0

    @property
    def garbled_lines(self) -> int:
        return sum(self.garbled.values())

    def notice(self, kind: str, t: float | None, message: str) -> None:
        """Keep a notice and log it (the first few of a kind, then counted; see module)."""
        self.notices.append(BoardNotice(kind, t, message))
        if self._told[kind] < NAMED_PER_KIND:
            self._told[kind] += 1
            log.warning("%s", message)
            if self._told[kind] == NAMED_PER_KIND:
                log.warning("further %s notices are counted, one log line per %g s", kind, ROLLUP_S)
            return
        self._untold[kind] += 1
        now = time.monotonic()
        if now - self._rollup_at >= ROLLUP_S:
            self._rollup_at = now
            said = ", ".join(f"{n} {k}" for k, n in sorted(self._untold.items()))
            log.warning("since the last report: %s (see the run's summary)", said)
            self._untold.clear()

    def summary(self) -> list[str]:
        """Lines for the run's report: the totals, then only what is not perfectly normal."""
        lines = [
            f"{self.lines} lines, {self.samples} samples given out"
            + (f" ({self.sample_lines} sample lines read)" if self.sample_lines else "")
        ]
        if self.garbled:
            why = ", ".join(
                f"{REASONS[code]} {n}"
                for code, n in sorted(self.garbled.items(), key=lambda x: -x[1])
            )
            lines.append(f"{self.garbled_lines} garbled lines dropped ({why})")
        if self.lost:
            lines.append(
                f"{self.lost} samples lost in {self.loss_runs} sequence gaps (garbled lines "
                "included); their time was kept empty, never filled in"
            )
        for value, label in (
            (self.resets, "board resets (the board's clock restarted; carried on after a gap)"),
            (self.reconnects, "reconnects (the port was lost and opened again)"),
            (self.gaps, "gaps longer than the estimator's max_gap_s (it restarted its filters)"),
            (self.before_hello, "sample lines before the board's hello (skipped)"),
            (self.missing_values, "empty fields (channels the board could not read: NaN)"),
            (self.unaligned, "samples given unaligned (no earlier reading to align with)"),
        ):
            if value:
                lines.append(f"{value} {label}")
        return lines
