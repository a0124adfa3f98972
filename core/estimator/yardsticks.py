"""The idle desk's own unsteadiness: the yardsticks an object put down is judged against.

How much a still, unloaded desk's windows spread, and how far their force means stray over
as many windows in a row as an object waits (``n_object``): each the median
(``IDLE_QUANTILE``) of the idle desk's own, over the tare's windows and then every idle still
window (the last ``IDLE_WINDOWS``). A median of a few windows is steady, a high quantile of
them is not. :mod:`hapticdesk.estimator.still_objects` compares a load's windows with them.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

IDLE_QUANTILE = 0.5
IDLE_WINDOWS = 64


class IdleMean(NamedTuple):
    """One idle window's force mean (3) and its number (``window_index``: which are in a row)."""

    number: int
    force: list[float]


class Yardsticks:
    """The idle desk's windows so far and the yardsticks from them (``quiet_spread``,
    ``quiet_wander``; 0 before any)."""

    def __init__(self, wander_windows: int) -> None:
        """``wander_windows``: the windows in a row a wander is taken over."""
        self.wander_windows = wander_windows
        self.quiet_spread = 0.0
        self.quiet_wander = 0.0
        self.spreads: list[float] = []  # the last IDLE_WINDOWS of each
        self.wanders: list[float] = []
        self.tail: list[IdleMean] = []  # the last windows' means, for the next wander

    def forget(self) -> None:
        """Forget the windows' spreads and wanders (more came than are kept: those the
        kernel's log kept are the ones that count)."""
        self.spreads, self.wanders = [], []

    def restart(self) -> None:
        """Start again from nothing (at the tare)."""
        self.spreads, self.wanders, self.tail = [], [], []

    def add(self, spread: float, force: list[float], index: int) -> None:
        """One more window of the idle desk (``index``: its number): its spread, and how far
        the force means of the last ``wander_windows`` in a row strayed. :meth:`update` then
        makes the yardsticks (once for several windows)."""
        self.spreads.append(spread)
        tail = [m for m in self.tail if index - m.number < self.wander_windows]
        tail.append(IdleMean(index, force))
        self.tail = tail
        if len(tail) == self.wander_windows:  # (that many in a row: none was left out)
            self.wanders.append(wander([m.force for m in tail]))
        for values in (self.spreads, self.wanders):
            if len(values) > IDLE_WINDOWS:
                del values[0]

    def update(self) -> None:
        """The quiet spread and wander: quantiles of the idle desk's last windows."""
        if self.spreads:
            self.quiet_spread = quantile(self.spreads, IDLE_QUANTILE)
        if self.wanders:
            self.quiet_wander = quantile(self.wanders, IDLE_QUANTILE)


def wander(means: Sequence[Sequence[float]]) -> float:
    """How far window means strayed: the widest range of any component over ``means`` (one
    measure for an object's windows and the idle desk's yardstick, so they compare)."""
    return max(max(c) - min(c) for c in zip(*means, strict=True))


def quantile(values: list[float], q: float) -> float:
    """The ``q`` quantile of ``values`` by nearest rank (plain floats: a window's end is hot)."""
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))]
