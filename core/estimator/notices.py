"""What the estimator did on its own that a user should know about (a tare, a gap, ...)."""

from __future__ import annotations

import logging
from dataclasses import dataclass

log = logging.getLogger("hapticdesk.estimator")


@dataclass(frozen=True)
class Notice:
    """Something the estimator did on its own that a user should know about."""

    t: float
    kind: str  # tare, tare_refused, absorbed, drift, gap, stuck, live
    message: str


def add_notice(
    notices: list[Notice], t: float, kind: str, message: str, level: int = logging.INFO
) -> None:
    """Append a notice and log it."""
    notices.append(Notice(t, kind, message))
    log.log(level, "t=%.3f s: %s", t, message)
