"""What a running desk shows: the latest contact sample and the run's counts, for the status
line and for plugins that watch the run from their own thread (the browser UI)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, NamedTuple

from hapticdesk.estimator.contacts import FLAG_NOT_TARED

if TYPE_CHECKING:
    from hapticdesk.estimator.contacts import ContactBlock


class LiveSample(NamedTuple):
    """One contact sample as a watcher sees it."""

    t: float
    x: float | None  # None: not located (no contact, or the position is not yet known)
    y: float | None
    force_n: float
    phase: int
    surface: int  # the surface's index, or -1


@dataclass
class LiveStatus:
    """What the status line shows; written by the sensing thread, read by the watcher."""

    t: float = 0.0
    in_contact: bool = False
    x: float = 0.0
    y: float = 0.0
    force_n: float = 0.0
    last_gesture: str = ""
    gestures: int = 0
    tared: bool = False
    paused: bool = False
    #: the block's last sample, replaced whole (one assignment, so a reader on another thread
    #: never sees half of one)
    sample: LiveSample | None = None
    #: how many blocks have been sensed; a reader sees whether ``sample`` is new
    blocks: int = 0

    def line(self) -> str:
        where = f"x {self.x:+.3f} y {self.y:+.3f} m" if self.in_contact else "—"
        tare = "" if self.tared else " (taring: keep the desk still)"
        tare += " (paused: gestures not sent)" if self.paused else ""
        last = self.last_gesture or "none yet"
        return (
            f"t {self.t:7.2f} s  {'●' if self.in_contact else '○'} {where}  "
            f"F {self.force_n:5.1f} N  gestures {self.gestures}  last: {last}{tare}"
        )

    def update(self, contacts: ContactBlock) -> None:
        """Take the last sample of a block the estimator gave (on the sensing thread)."""
        self.t = float(contacts.t[-1])
        self.in_contact = bool(contacts.in_contact[-1])
        self.force_n = float(contacts.force_n[-1])
        located = bool(contacts.located[-1])
        if located:
            self.x, self.y = float(contacts.x[-1]), float(contacts.y[-1])
        self.tared = not bool(contacts.flags[-1] & FLAG_NOT_TARED)
        self.sample = LiveSample(
            self.t,
            float(contacts.x[-1]) if located else None,
            float(contacts.y[-1]) if located else None,
            self.force_n,
            int(contacts.phase[-1]),
            int(contacts.surface[-1]),
        )
        self.blocks += 1
