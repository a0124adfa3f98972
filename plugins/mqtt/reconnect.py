"""How the MQTT link gets its broker back, and says so once an outage.

While the broker cannot be reached the connection is tried again every
:data:`RECONNECT_MAX_S` at most (a local attempt costs a refused SYN), so a broker that comes
back is used within a second; publishing does not shorten or lengthen that wait
(:func:`connect_with_backoff`, the clean first connection; paho's own reconnects take the same
delays). A connection whose acknowledgements stalled is dropped under paho
(:func:`drop_connection`), which then resends what is in flight on the resumed session.
:class:`OutageLog` says each outage once, and the return after it.
"""

from __future__ import annotations

import contextlib
import logging
import socket
import threading
import time
from collections.abc import Callable
from typing import Any

from hapticdesk.plugins.mqtt.oneshot import Refused

# the link's own logger: what is said here is the link's state (and filtered with it)
log = logging.getLogger("hapticdesk.plugins.mqtt.link")

# retry a lost broker quickly: the 30 s back-off left a returned broker unused
RECONNECT_MIN_S, RECONNECT_MAX_S = 0.1, 0.5


class OutageLog:
    """Says the first failure of an outage (and nothing more until the broker is back), then
    that the broker is back; a refused login (never retried) is said by the link once."""

    def __init__(self, url: str) -> None:
        self.url = url
        self.said = False  # an outage was said and the broker is not back yet

    def once(self, level: int, message: str, *args: object) -> None:
        """Log ``message`` unless this outage was said already."""
        if not self.said:
            log.log(level, message, *args)
            self.said = True

    def connected(self) -> None:
        """The connection is up: said as a return after an outage, else as news."""
        if self.said:
            log.warning("MQTT: connected to %s again", self.url)
            self.said = False
        else:
            log.info("MQTT: connected to %s", self.url)

    def login_refused(self, reason: str) -> None:
        """The broker refused the login: not retried, so said once as the error it is."""
        log.error(
            "MQTT: %s refused the login (%s); check `username` and the password "
            "(`password_env`/`password_file`) of the layout's `mqtt:`; MQTT commands are "
            "not delivered in this run",
            self.url,
            reason,
        )


def connect_with_backoff(
    attempt: Callable[[], str | Refused | None],
    cond: threading.Condition,
    closing: Callable[[], bool],
    outage: OutageLog,
    queue_size: int,
) -> bool | Refused:
    """Call ``attempt`` (None: connected; else what went wrong) until it connects (True), the
    broker refuses the login (its :class:`Refused`: not retried) or ``closing()`` (False),
    waiting RECONNECT_MIN_S, doubling up to RECONNECT_MAX_S, between tries. The wait is on
    ``cond`` (so a close ends it) and lasts its whole delay: a publish also notifies the
    condition, and must neither shorten this wait nor (as it did) make the back-off climb to
    its maximum."""
    delay = RECONNECT_MIN_S
    while True:
        error = attempt()
        if error is None:
            return True
        if isinstance(error, Refused):
            return error
        outage.once(
            logging.WARNING,
            "MQTT: cannot connect to %s (%s); commands are kept (up to %d) and sent "
            "when it can be reached",
            outage.url,
            error,
            queue_size,
        )
        retry_at = time.monotonic() + delay
        with cond:
            while not closing() and time.monotonic() < retry_at:
                cond.wait(retry_at - time.monotonic())
            if closing():
                return False
        delay = min(delay * 2, RECONNECT_MAX_S)


def drop_connection(client: Any, stalled: int, url: str, ack_timeout_s: float) -> None:
    """Drop the connection under paho (it reconnects by itself): on the resumed session it
    sends what is in flight again, as MQTT has a client do only then; ``stalled`` messages
    waited ``ack_timeout_s`` for their acknowledgement."""
    log.warning(
        "MQTT: %d message(s) to %s unacknowledged for %g s; reconnecting to send them again",
        stalled,
        url,
        ack_timeout_s,
    )
    sock = client.socket()
    if sock is not None:
        with contextlib.suppress(OSError):
            sock.shutdown(socket.SHUT_RDWR)
