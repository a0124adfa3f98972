"""Contact blocks to contact events and touches: where a touch begins and ends.

:class:`TouchTracker` keeps the contact state across blocks, builds the contact events of the
samples in or just after contact (one vectorised pass over long quiet stretches), gives the
positions on a surface whose axes are not the desk's in that surface's (u, v), and opens and
closes the current :class:`~hapticdesk.gestures.touch.Touch` (a touch whose release was not
seen ends without an ``up``: it fires nothing).
"""

from __future__ import annotations

import numpy as np

from hapticdesk.estimator.contacts import (
    UNCERTAINTY_CAP_M,
    ContactBlock,
    ContactEvent,
    contact_events,
)
from hapticdesk.files.profile import DeskProfile, Surface
from hapticdesk.gestures.touch import Touch


def _to_local(
    surface: Surface, x: np.ndarray, y: np.ndarray, z: np.ndarray, on: np.ndarray
) -> None:
    """The points ``on`` of (x, y, z) in the desk frame: their (x, y) rewritten in place as
    ``surface``'s (u, v)."""
    if on.any():
        uv = surface.to_local(np.column_stack([x[on], y[on], z[on]]))
        x[on], y[on] = uv[:, 0], uv[:, 1]


class TouchTracker:
    """Turns contact blocks into contact events and keeps the current :class:`Touch`.

    Positions on a surface whose local axes are not the desk's (x, y) are given in that
    surface's (u, v), the coordinates its layout regions use. State carries across blocks.
    """

    def __init__(self, desk: DeskProfile, position_delay_s: float = 0.0) -> None:
        self.touch: Touch | None = None
        self.position_delay_s = position_delay_s  # see Touch.delay_s
        self.pressed_n = desk.estimation.contact_force_n  # see Touch.pressed_n
        self._in_contact = False
        self._local_surfaces = [(i, s) for i, s in enumerate(desk.surfaces) if not s.is_desk_xy]
        self._after_break = False  # the stream broke off (abort): the next block resumes it
        self._unseen_down = False  # the next down is a contact that was there at the resume

    @property
    def in_contact(self) -> bool:
        """Whether the last sample seen was in contact."""
        return self._in_contact

    def join_contact(self) -> None:
        """Take the stream as in contact already: the contact going on makes no ``down``, so
        no touch, until it ends and a new one begins."""
        self._in_contact = True

    def events(self, block: ContactBlock) -> list[ContactEvent]:
        """The block's contact events (built only from the samples in or just after contact,
        so long quiet stretches cost one vectorised pass)."""
        if len(block) == 0:
            return []
        inc = block.in_contact
        if self._after_break:
            self._after_break = False
            self._unseen_down = bool(inc[0])
        previous = np.concatenate([[self._in_contact], inc[:-1]])
        sub = block.take(np.flatnonzero(inc | previous))
        if self._local_surfaces and len(sub):  # (sub's arrays are copies: taken by index)
            for index, surface in self._local_surfaces:
                _to_local(surface, sub.x, sub.y, sub.z, sub.located & (sub.surface == index))
            index, surface = self._local_surfaces[0]
            if index == 0:  # (multitouch places the second finger on the first surface)
                _to_local(surface, sub.x2, sub.y2, sub.z2, sub.located2)
        events = contact_events(sub, was_in_contact=self._in_contact)
        self._in_contact = bool(inc[-1])
        return events

    def add(self, event: ContactEvent) -> Touch | None:
        """Update the touch with ``event``; returns it (None for a stray event without down).
        After an ``up`` the returned touch is complete and no touch is current."""
        if event.kind == "down":
            self.touch = Touch(event.t, self.position_delay_s, self.pressed_n)
            self.touch.began_unseen, self._unseen_down = self._unseen_down, False
        touch = self.touch
        if touch is not None:
            touch.add(event)
            if event.kind == "up":
                self.touch = None
        return touch

    def end(self, t_end: float) -> ContactEvent | None:
        """An ``up`` for a touch still going when the source stops at ``t_end``: for stroke
        capture, which keeps what was drawn. The gesture engine does not use it: a release
        that was not seen fires nothing (:meth:`abort`)."""
        self._in_contact = False
        if self.touch is None:
            return None
        return ContactEvent(t_end, "up", 0.0, 0.0, -1, 0.0, UNCERTAINTY_CAP_M, "release", False)

    def abort(self) -> Touch | None:
        """The stream broke off: forget the contact state; returns the touch that was open
        (without an ``up``: its release was not seen), or None. A contact already there when
        the stream resumes starts a touch marked :attr:`Touch.began_unseen`."""
        self._in_contact = False
        self._after_break = True
        touch, self.touch = self.touch, None
        return touch
