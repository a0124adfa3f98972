"""Turns in gesture order for actions that share a device: a turnstile per ``order_key``.

Every action runs on a lane of its own (lane.py), so two gestures a moment apart, bound to two
different actions, can reach their device crossed: the second action's worker may wake before
the first's (a stroke's "on" and the next tap's "off", 1 ms apart in a fast replay, once left a
lamp on). An action that declares ``order_key`` (the same text for every action whose calls must
keep the gestures' order, e.g. all that publish on one MQTT connection) takes a ticket from its
key's :class:`Turnstile` when the dispatcher hands it an event, on the sensing thread, so the
tickets follow the gestures' order; its worker waits for its turn before the call and gives the
turn on after it. A ticket is also given on when its event is dropped or never run, and when the
watchdog gives up on its call, so a slow or hung action holds the others of its key back for
at most its own timeout. Actions without a key wait for nothing.

No wait can go round in a circle: each lane's queue holds its tickets in increasing order, so
the smallest ticket not yet done is always at the front of a lane whose worker is free to run it.
"""

from __future__ import annotations

import threading


class Turnstile:
    """Tickets in the order they are taken; a ticket's turn comes when every earlier one is done."""

    def __init__(self, key: str) -> None:
        self.key = key
        self._turn = threading.Condition()
        self._next = 0  # the next ticket to hand out
        self._serving = 0  # every ticket below this one is done
        self._done_early: set[int] = set()  # done, but an earlier ticket is not yet

    def take(self) -> int:
        """The next ticket (on the thread that orders: the dispatcher's submit)."""
        with self._turn:
            ticket = self._next
            self._next += 1
            return ticket

    def wait_turn(self, ticket: int, timeout_s: float) -> bool:
        """Wait until every ticket before ``ticket`` is done; False if ``timeout_s`` passed."""
        with self._turn:
            return self._turn.wait_for(lambda: self._serving >= ticket, timeout_s)

    def done(self, ticket: int) -> None:
        """``ticket``'s call ended (or will never run); the turns after it may go. Saying it
        twice is harmless (a call the watchdog gave up on that ends after all)."""
        with self._turn:
            if ticket < self._serving:
                return
            self._done_early.add(ticket)
            self._move_on()

    def give_way(self, ticket: int) -> None:
        """Give up on every ticket before ``ticket`` (they took too long): its turn now."""
        with self._turn:
            if ticket <= self._serving:
                return
            self._serving = ticket
            self._done_early = {t for t in self._done_early if t >= ticket}
            self._move_on()

    def _move_on(self) -> None:
        # (under self._turn) past every ticket done early that is next, then the waiters look
        while self._serving in self._done_early:
            self._done_early.remove(self._serving)
            self._serving += 1
        self._turn.notify_all()
