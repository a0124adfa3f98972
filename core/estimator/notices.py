"""What the estimator did on its own that a user should know about (a tare, a gap, ...)."""

from __future__ import annotations

import logging
from dataclasses import dataclass

log = logging.getLogger("hapticdesk.estimator")


@dataclass(frozen=True)
class Notice:
    """Something the estimator did on its own that a user should know about."""

    t: float
    kind: str  # tare, tare_refused, absorbed, drift, gap, stuck, live, time_back, jump…
    message: str


#: notices kept (a day of drift and gap notices would otherwise grow for the whole run)
NOTICES_KEPT = 1000


class NoticeList(list[Notice]):
    """The estimator's notices, oldest first, at most :data:`NOTICES_KEPT` of them.

    ``dropped`` counts those let go from the front, so a reader that remembers how many it
    has seen (``dropped + len``) keeps its place across a :meth:`trim`."""

    def __init__(self) -> None:
        super().__init__()
        self.dropped = 0

    @property
    def total(self) -> int:
        """How many notices there have been in all."""
        return self.dropped + len(self)

    def since(self, total_seen: int) -> list[Notice]:
        """The notices after the first ``total_seen`` (those dropped meanwhile are skipped)."""
        return self[max(0, total_seen - self.dropped) :]

    def trim(self) -> None:
        """Let the oldest go beyond :data:`NOTICES_KEPT`."""
        extra = len(self) - NOTICES_KEPT
        if extra > 0:
            del self[:extra]
            self.dropped += extra


def add_notice(
    notices: list[Notice], t: float, kind: str, message: str, level: int = logging.INFO
) -> None:
    """Append a notice and log it (a :class:`NoticeList` then lets its oldest go)."""
    notices.append(Notice(t, kind, message))
    if isinstance(notices, NoticeList):
        notices.trim()
    log.log(level, "t=%.3f s: %s", t, message)
