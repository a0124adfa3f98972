"""What waits to go to the broker and what is in flight: the ledger of one MQTT link.

Commands wait in a bounded queue whose **oldest** goes when it is full (counted and logged);
announcements and answers wait in a bounded control queue, announcements coalesced by topic.
A message handed to paho is in flight under its message id until ``on_publish`` says the
broker acknowledged it (an acknowledgement may come before the id is registered: it is kept
for then). While paho resends what was in flight after a reconnect, new commands wait, so
the order is kept. :class:`~.link.MqttLink` drives it; the why of each rule is in its
docstring.

Every method is called with :attr:`Outbox.cond` held: the link guards its connection state
under the same condition, so a message is taken and the connection read in one step.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass

from hapticdesk.plugins.mqtt.message import Message

log = logging.getLogger(__name__)

WINDOW = 20  # commands in flight at once (paho's default maximum)
CONTROL_LIMIT = 1000  # announcements waiting at most (they are coalesced by topic first)


@dataclass
class LinkStats:
    queued: int = 0  # commands handed to publish()
    delivered: int = 0  # acknowledged by the broker (QoS 0: written to the socket)
    dropped: int = 0  # pushed out of a full queue
    pending: int = 0  # queued or in flight when the link closed

    @property
    def undelivered(self) -> int:
        """After the link closed: commands queued but never delivered (dropped from the full
        queue, or still waiting at the end)."""
        return self.pending + self.dropped


class Outbox:
    """The commands and control messages of a link to ``url``: waiting (at most
    ``queue_size`` commands) and in flight."""

    def __init__(self, queue_size: int, url: str) -> None:
        self.cond = threading.Condition()
        self.stats = LinkStats()
        self.queue_size = queue_size
        self.url = url
        self.queue: deque[Message] = deque()
        self.control: deque[Message] = deque()
        self.inflight: dict[int, Message] = {}
        self.resuming = False  # waiting for paho's resends before sending new commands
        self._sent_at: dict[int, float] = {}  # when each message in flight was sent
        self._early_acks: set[int] = set()
        self._unstalled_at = -math.inf

    @property
    def empty(self) -> bool:
        """Nothing waiting and nothing in flight."""
        return not (self.queue or self.control or self.inflight)

    # --- what waits -----------------------------------------------------------------------

    def add_command(self, message: Message) -> None:
        """Queue a command; when the queue is full the oldest goes."""
        if len(self.queue) >= self.queue_size:
            old = self.queue.popleft()
            self.stats.dropped += 1
            n = self.stats.dropped
            if n in (1, 10, 100) or n % 1000 == 0:
                log.warning(
                    "MQTT: %d commands are waiting for %s (the queue is full); the oldest "
                    "is dropped (%s), %d dropped so far",
                    len(self.queue) + 1,
                    self.url,
                    old.topic,
                    n,
                )
        self.queue.append(message)
        self.stats.queued += 1
        self.cond.notify_all()

    def add_answer(self, message: Message) -> None:
        """Queue a control message, each one (not coalesced), at most
        :data:`CONTROL_LIMIT` waiting."""
        self.control.append(message)
        while len(self.control) > CONTROL_LIMIT:
            self.control.popleft()
        self.cond.notify_all()

    def add_last(self, message: Message) -> None:
        """Queue the link's goodbye after everything else."""
        self.control.append(message)
        self.cond.notify_all()

    def add_announcements(self, messages: Sequence[Message]) -> None:
        """Queue announcements: one per topic, the newest, bounded."""
        topics = {m.topic for m in messages}
        kept = [m for m in self.control if m.topic not in topics]
        kept.extend(messages)
        if len(kept) > CONTROL_LIMIT:
            log.warning(
                "MQTT: %d announcements waiting; the oldest %d are dropped",
                len(kept),
                len(kept) - CONTROL_LIMIT,
            )
            kept = kept[-CONTROL_LIMIT:]
        self.control = deque(kept)
        self.cond.notify_all()

    def next_message(self, connected: bool) -> Message | None:
        """The next message to send now: control first, then a command while the window has
        room and paho is not resending; None when nothing may go."""
        if connected and self.control:
            return self.control.popleft()
        if connected and not self.resuming and self.queue and len(self.inflight) < WINDOW:
            return self.queue.popleft()
        return None

    def put_back(self, message: Message) -> None:
        """A message paho did not take: first in its queue again."""
        (self.queue if message.command else self.control).appendleft(message)

    # --- what is in flight ----------------------------------------------------------------

    def sent(self, message: Message, mid: int, *, resent_later: bool) -> None:
        """``message`` handed to paho as ``mid``; ``resent_later``: paho keeps it to send on
        reconnecting (no connection now)."""
        if mid in self._early_acks:
            self._early_acks.discard(mid)
            self._acknowledged(message)
            return
        self.inflight[mid] = message
        self._sent_at[mid] = time.monotonic()
        if resent_later:
            self.resuming = True

    def acknowledge(self, mid: int) -> None:
        """The broker acknowledged ``mid`` (paho's ``on_publish``)."""
        message = self.inflight.pop(mid, None)
        self._sent_at.pop(mid, None)
        if message is None:  # acknowledged before it was registered
            self._early_acks.add(mid)
            return
        self._acknowledged(message)

    def _acknowledged(self, message: Message) -> None:
        if message.command:
            self.stats.delivered += 1
        if not self.inflight:
            self.resuming = False
        self.cond.notify_all()

    def late(self, timeout_s: float) -> int:
        """How many messages have waited over ``timeout_s`` for their acknowledgement, once
        in ``timeout_s``; else 0 (the link asks only while connected)."""
        now = time.monotonic()
        if now - self._unstalled_at < timeout_s:
            return 0
        late = [mid for mid in self.inflight if now - self._sent_at.get(mid, now) > timeout_s]
        if late:
            self._unstalled_at = now
        return len(late)

    def reconnected(self) -> None:
        """Connected again: paho resends what is in flight before new commands go."""
        self.resuming = bool(self.inflight)

    def disconnected(self) -> int:
        """The connection dropped: a QoS 0 message not yet written is gone (at most once; paho
        resends QoS 1 and 2). The commands still waiting or in flight."""
        for mid in [mid for mid, m in self.inflight.items() if m.qos == 0]:
            self._sent_at.pop(mid, None)
            if self.inflight.pop(mid).command:
                self.stats.dropped += 1
        self.cond.notify_all()
        return len(self.queue) + len(self.inflight)

    def lost_commands(self) -> list[Message]:
        """The commands in flight or waiting (when the link closes)."""
        return [m for m in list(self.inflight.values()) + list(self.queue) if m.command]


def delivery_failure(url: str, stats: LinkStats, refused: str | None) -> str | None:
    """Why a closed link's commands were not delivered (None when all were): the login
    ``refused``, or how many were not."""
    if refused is not None:
        return f"{url} refused the login ({refused})"
    if stats.undelivered:
        return f"{stats.undelivered} MQTT command(s) not delivered to {url}"
    return None


def delivery_report(
    url: str, stats: LinkStats, lost: list[Message], refused: str | None, flushed: bool
) -> str:
    """The run's line about a closed link: how many messages were delivered, dropped, and
    which commands were not (``lost``), and why (the login ``refused``, or the broker away
    when it could not be ``flushed``)."""
    line = f"MQTT {url}: {stats.delivered} of {stats.queued} messages delivered" + (
        f", {stats.dropped} dropped from the full queue" if stats.dropped else ""
    )
    if refused is not None:
        return line + f", {len(lost)} NOT delivered: the broker refused the login ({refused})"
    if flushed or not lost:
        return line
    # one entry per topic (the first payload and how many more): a light's command is not
    # hidden behind the desk's own state and event messages
    by_topic: dict[str, list[Message]] = {}
    for m in lost:
        by_topic.setdefault(m.topic, []).append(m)
    shown = "; ".join(
        f"{topic} {group[0].payload[:60].decode('utf-8', 'replace')}"
        + (f" (and {len(group) - 1} more)" if len(group) > 1 else "")
        for topic, group in list(by_topic.items())[:5]
    )
    more = " …" if len(by_topic) > 5 else ""
    return line + f", {len(lost)} NOT delivered (broker away): {shown}{more}"
