"""Contact observers: plugins that watch the contact state, not only gestures.

The runtime hands each ``contact_sink`` (:mod:`hapticdesk.hookspecs`) one
:class:`ContactSummary` per block on the sensing thread: the block's last sample and the
estimator's zero, a handful of floats, so the cost per block is independent of its length. A
sink that raises is logged and dropped; sensing goes on.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class ContactSummary:
    """The contact state at the end of one block.

    ``force_n``: the external force (fast path), newtons; ``x``/``y``: the contact point in
    the desk frame, metres, None when not located; ``zero_force_n``: the magnitude of the
    force the estimator's zero holds (the desk's weight and whatever rests on it), None
    before the tare; ``paused``: the run does not send gestures."""

    t: float
    in_contact: bool
    force_n: float
    x: float | None
    y: float | None
    zero_force_n: float | None
    #: gestures are not sent (a ``pause`` from ``/set``, the browser UI or Python)
    paused: bool = False


def summarize(contacts: Any, zero: Any, paused: bool = False) -> ContactSummary:
    """The summary of a non-empty :class:`~hapticdesk.estimator.contacts.ContactBlock` and
    the estimator's zero ((6,) or None)."""
    located = bool(contacts.located[-1])
    force = float(contacts.force_n[-1])
    zero_force = None if zero is None else math.sqrt(sum(float(v) ** 2 for v in zero[:3]))
    return ContactSummary(
        t=float(contacts.t[-1]),
        in_contact=bool(contacts.in_contact[-1]),
        force_n=force if math.isfinite(force) else 0.0,
        x=float(contacts.x[-1]) if located else None,
        y=float(contacts.y[-1]) if located else None,
        zero_force_n=zero_force if zero_force is not None and math.isfinite(zero_force) else None,
        paused=paused,
    )


class ContactObservers:
    """The run's contact sinks, each called in its own ``try``."""

    def __init__(self, sinks: Sequence[tuple[str, Callable[[ContactSummary], Any]]]) -> None:
        self.sinks = list(sinks)

    def __bool__(self) -> bool:
        return bool(self.sinks)

    def __call__(self, contacts: Any, zero: Any, paused: bool = False) -> None:
        if not self.sinks or len(contacts.t) == 0:
            return
        summary = summarize(contacts, zero, paused)
        for name, sink in list(self.sinks):
            try:
                sink(summary)
            except Exception:
                log.exception("the contact sink of plugin `%s` failed; it is dropped", name)
                self.sinks.remove((name, sink))
