"""The desk's presence on the broker: what it listens to, and its birth on every connect.

The subscriptions are asked for first; the birth (``online`` and the announcements kept
with it: Home Assistant's discovery configs) is queued only once the broker has granted
them, so whoever acts on seeing the desk ``online`` (Home Assistant's select) reaches it.
The birth goes again, without waiting, when ``again_on`` comes (``homeassistant/status`` =
``online``: Home Assistant forgets non-retained state when it restarts).

Called by :class:`~.link.MqttLink` with its condition held (:attr:`.outbox.Outbox.cond`),
except :meth:`Presence.deliver`, on paho's thread.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Sequence

from hapticdesk.plugins.mqtt.message import Message
from hapticdesk.plugins.mqtt.outbox import Outbox

log = logging.getLogger(__name__)

#: (topic, QoS) pairs of one SUBSCRIBE
Topics = list[tuple[str, int]]


class Presence:
    """The subscriptions and the birth of a link whose messages wait in ``outbox``."""

    def __init__(
        self, outbox: Outbox, birth: Sequence[Message], again_on: tuple[str, bytes] | None
    ) -> None:
        self._outbox = outbox
        self._birth = list(birth)
        self._kept: list[Message] = []  # announcements added while running (discovery)
        self._again_on = again_on
        self._subscriptions: dict[str, tuple[int, Callable[[bytes], None]]] = {}
        #: connected, the subscriptions granted and the birth queued (cleared on a disconnect)
        self.ready = threading.Event()
        #: the SUBSCRIBE (message id, topics) whose SUBACK lets the birth go
        self._after: tuple[int, Topics] | None = None

    def subscribe(self, topic: str, qos: int, on_message: Callable[[bytes], None]) -> None:
        """Listen to ``topic`` from the next connect on."""
        self._subscriptions[topic] = (qos, on_message)

    def handler(self, topic: str) -> Callable[[bytes], None] | None:
        """What is called for a message on ``topic`` (None when not subscribed)."""
        subscribed = self._subscriptions.get(topic)
        return None if subscribed is None else subscribed[1]

    def keep(self, messages: Sequence[Message], *, now: bool) -> None:
        """Announce ``messages`` with the birth from now on, in place of those kept before;
        ``now``: also queue them at once, when the birth has gone already."""
        self._kept = list(messages)
        if now and self.ready.is_set():
            self._outbox.add_announcements(self._kept)

    def connected(self) -> Topics:
        """The topics to subscribe to on this connect; with none the birth goes at once."""
        wanted = [(topic, qos) for topic, (qos, _) in self._subscriptions.items()]
        if self._again_on is not None:
            wanted.append((self._again_on[0], 1))
        if not wanted:
            self._born()
        return wanted

    def subscribing(self, mid: int, wanted: Topics) -> None:
        """``wanted`` asked for as SUBSCRIBE ``mid``: its SUBACK lets the birth go."""
        self._after = (mid, wanted)

    def granted(self, mid: int) -> Topics | None:
        """The SUBACK of ``mid`` came: the birth goes, and the topics asked for are returned
        (None for a SUBSCRIBE made later, while connected)."""
        if self._after is None or self._after[0] != mid:
            return None
        wanted = self._after[1]
        self._after = None
        self._born()
        return wanted

    def disconnected(self) -> None:
        """The connection dropped: the desk is not ready until the next birth."""
        self.ready.clear()
        self._after = None

    def deliver(self, topic: str, payload: bytes) -> None:
        """(paho's thread) A message that came: to its subscriber, or the birth again when it
        is ``again_on``."""
        subscribed = self._subscriptions.get(topic)
        if subscribed is not None:
            try:
                subscribed[1](payload)
            except Exception:  # a subscriber's bug must not take paho's thread down
                log.exception("MQTT: handling a message on %s failed", topic)
            return
        if self._again_on and payload == self._again_on[1]:
            with self._outbox.cond:
                self._outbox.add_announcements(self._birth + self._kept)

    def _born(self) -> None:
        """Queue the birth and the kept announcements: the desk is ready."""
        self._outbox.add_announcements(self._birth + self._kept)
        self.ready.set()
