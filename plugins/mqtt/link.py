"""One MQTT connection per run, and delivery that loses nothing (its settings: :mod:`.settings`).

Commands (a TOGGLE, a brightness) go through :meth:`MqttLink.publish`, which never blocks:
the message joins a bounded queue and a sender thread hands it to paho when the broker is
there. Delivery is tracked by message id in ``on_publish``:

- While the broker is away, commands wait in *our* queue. paho's ``publish`` returns
  ``MQTT_ERR_NO_CONN`` when the connection is gone; for QoS 1 and 2 paho then keeps the message
  itself and sends it after reconnecting (``Client._out_messages``), so such a message is
  tracked as in flight and is *not* queued again: nothing is sent twice. A QoS 0 message is
  dropped by paho in that case and goes back to the front of our queue.
- Messages in flight when the connection drops are resent by paho on reconnect. With QoS 2
  and a persistent session (``clean_session=False``) the broker recognises them, so a TOGGLE
  never fires twice (with QoS 1 a resend can arrive twice; that is MQTT's at-least-once). New
  commands wait until those resends are acknowledged, so the order is kept.
- A persistent session could hold a half-finished QoS 2 exchange left by an earlier process
  that crashed, and the broker would then drop our new message with the same id. So the very
  first connection is a clean one, which clears that session, before the persistent one.
- When the queue is full the **oldest** command is dropped (and counted and logged): after a
  long outage the latest commands are the ones that still say what the person wants now.

While the broker cannot be reached the connection is tried again every
:data:`RECONNECT_MAX_S` at most (a local attempt costs a refused SYN), so a broker that comes
back is used within a second; publishing does not shorten or lengthen that wait. A broker that
*refuses the login* (bad user name or password, not authorised) is not retried: that is a
configuration error, said once, and every command is reported as not delivered.
Announcements (availability, discovery) are coalesced by topic and bounded, so a chatty
``homeassistant/status`` cannot grow them. On every connect the subscriptions go first and the
birth (``online``, the discovery configs kept) only once the broker has granted them: whoever
acts on seeing the desk ``online`` (Home Assistant's select) reaches it. The password never
appears in ``repr`` or the log.
"""

from __future__ import annotations

import contextlib
import logging
import math
import socket
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Any

from hapticdesk.plugins.mqtt.message import Message, encode_payload
from hapticdesk.plugins.mqtt.oneshot import Refused, clean_connect, login_refused
from hapticdesk.plugins.mqtt.settings import MqttSettings, apply_login

log = logging.getLogger(__name__)

WINDOW = 20  # commands in flight at once (paho's default maximum)
#: a message in flight this long on a live connection lost its acknowledgement: reconnect
ACK_TIMEOUT_S = 10.0
# retry a lost broker quickly: the 30 s back-off left a returned broker unused
RECONNECT_MIN_S, RECONNECT_MAX_S = 0.1, 0.5
CONTROL_LIMIT = 1000  # announcements waiting at most (they are coalesced by topic first)
SESSION_NEVER_EXPIRES = 0xFFFFFFFF  # MQTT 5: keep the session as 3.1.1's clean_session=False


@dataclass
class LinkStats:
    queued: int = 0  # commands handed to publish()
    delivered: int = 0  # acknowledged by the broker (QoS 0: written to the socket)
    dropped: int = 0  # pushed out of a full queue
    pending: int = 0  # queued or in flight when the link closed


class MqttLink:
    """The run's MQTT connection. Start it, :meth:`publish`, :meth:`close`."""

    def __init__(
        self,
        settings: MqttSettings,
        *,
        will: Message | None = None,
        birth: Sequence[Message] = (),
        birth_again_on: tuple[str, bytes] | None = None,
    ) -> None:
        """``will``: the last will (and what :meth:`close` publishes); ``birth``: published on
        every (re)connect; ``birth_again_on``: (topic, payload) that asks for the birth again
        (Home Assistant's ``homeassistant/status`` = ``online``)."""
        import paho.mqtt.client as mqtt

        self._mqtt = mqtt
        self.settings = settings
        self.stats = LinkStats()
        self._will = will
        self._birth = list(birth)
        self._kept: list[Message] = []  # announcements added while running (discovery)
        self._birth_again_on = birth_again_on
        self._subscriptions: dict[str, tuple[int, Callable[[bytes], None]]] = {}
        self._cond = threading.Condition()
        self._queue: deque[Message] = deque()
        self._control: deque[Message] = deque()
        self._inflight: dict[int, Message] = {}
        self._sent_at: dict[int, float] = {}  # when each message in flight was sent
        self._unstalled_at = -math.inf
        self._early_acks: set[int] = set()
        self._connected = False
        self._resuming = False  # waiting for paho's resends before sending new commands
        self._closing = False
        # set when close begins: nothing is taken after it, the goodbye is the last message
        self._sealed = False
        self._ever_connected = threading.Event()
        #: connected, the subscriptions granted and the birth queued (cleared on a disconnect)
        self._ready = threading.Event()
        #: the SUBSCRIBE (message id, topics) whose SUBACK lets the birth go
        self._birth_after: tuple[int, list[tuple[str, int]]] | None = None
        self._outage_logged = False
        self.refused: str | None = None  # why the broker refused the login, if it did
        #: paho's protocol constant in use: MQTT 5 until the broker turns it down (``auto``)
        self.protocol = mqtt.MQTTv311 if settings.protocol == "3.1.1" else mqtt.MQTTv5
        self._client = self._persistent_client()
        self._sender = threading.Thread(target=self._run, name="mqtt sender", daemon=True)

    # --- public ------------------------------------------------------------------------------

    def start(self) -> MqttLink:
        self._sender.start()
        return self

    def publish(
        self, topic: str, payload: Any, *, qos: int | None = None, retain: bool | None = None
    ) -> None:
        """Queue a command. Never blocks; when the queue is full the oldest command goes."""
        message = Message(
            topic,
            encode_payload(payload),
            self.settings.qos if qos is None else qos,
            self.settings.retain if retain is None else retain,
        )
        with self._cond:
            if self._closing or self._sealed:
                raise RuntimeError("the MQTT link is closed")
            if len(self._queue) >= self.settings.queue_size:
                old = self._queue.popleft()
                self.stats.dropped += 1
                n = self.stats.dropped
                if n in (1, 10, 100) or n % 1000 == 0:
                    log.warning(
                        "MQTT: %d commands are waiting for %s (the queue is full); the oldest "
                        "is dropped (%s), %d dropped so far",
                        len(self._queue) + 1,
                        self.settings.url,
                        old.topic,
                        n,
                    )
            self._queue.append(message)
            self.stats.queued += 1
            self._cond.notify_all()

    def announce(self, topic: str, payload: Any, *, retain: bool = False) -> None:
        """Queue a message that is not a command (the answers on ``set/result``): not counted
        in what was delivered, sent while connected, each one (not coalesced by topic: two
        answers in a row are both news), at most :data:`CONTROL_LIMIT` waiting. At QoS 0: an
        answer waits for no acknowledgement, so a flood of them cannot hold the commands'
        window (10,000 answers in flight had stopped every gesture's message for good)."""
        message = Message(topic, encode_payload(payload), 0, retain, command=False)
        with self._cond:
            if self._closing or self._sealed:
                return
            self._control.append(message)
            while len(self._control) > CONTROL_LIMIT:
                self._control.popleft()
            self._cond.notify_all()

    def keep_announcing(self, messages: Sequence[Message], *, now: bool = False) -> None:
        """Send ``messages`` (retained announcements: Home Assistant's discovery configs) with
        the birth on every (re)connect and when ``birth_again_on`` comes, in place of those
        kept before; ``now``: also queue them at once (when nothing else has sent them)."""
        with self._cond:
            self._kept = list(messages)
            if now and self._ready.is_set():
                self._announce(self._kept)

    def subscribe(self, topic: str, on_message: Callable[[bytes], None], *, qos: int = 0) -> None:
        """Call ``on_message(payload)`` (on paho's thread: it must not block) for every
        message on ``topic``, subscribed again on every connect. QoS 0 by default: a command
        sent while the desk was away is not kept by the broker to arrive late. Made before
        :meth:`start`, the subscription is granted before the birth is sent."""
        with self._cond:
            self._subscriptions[topic] = (qos, on_message)
            connected = self._connected
        if connected:
            self._client.subscribe(topic, qos=qos)

    def handler(self, topic: str) -> Callable[[bytes], None] | None:
        """What :meth:`subscribe` calls for ``topic`` (None when not subscribed)."""
        with self._cond:
            subscribed = self._subscriptions.get(topic)
        return None if subscribed is None else subscribed[1]

    def wait_connected(self, timeout: float) -> bool:
        """True once the first connection is up (for the demo and tests)."""
        return self._ever_connected.wait(timeout)

    def wait_ready(self, timeout: float) -> bool:
        """True once connected with every subscription granted and the birth queued: what is
        announced after this finds the desk listening."""
        return self._ready.wait(timeout)

    @property
    def connected(self) -> bool:
        return self._connected

    @property
    def mqtt5(self) -> bool:
        """Whether the link speaks MQTT 5 (``protocol: auto`` finds out when it connects)."""
        return bool(self.protocol == self._mqtt.MQTTv5)

    @property
    def failure(self) -> str | None:
        """After :meth:`close`: why commands were not delivered (None when all were)."""
        s = self.stats
        if self.refused is not None:
            return f"{self.settings.url} refused the login ({self.refused})"
        if s.pending or s.dropped:
            return f"{s.pending + s.dropped} MQTT command(s) not delivered to {self.settings.url}"
        return None

    @property
    def undelivered(self) -> int:
        """After :meth:`close`: commands queued but never delivered (dropped from the full
        queue, or still waiting at the end); the run's summary says so."""
        return self.stats.pending + self.stats.dropped

    def flush(self, timeout: float) -> bool:
        """Wait until every queued command is acknowledged; False after ``timeout``."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while self._queue or self._control or self._inflight:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return False
                self._cond.wait(min(remaining, 0.1))
        return True

    def close(self, timeout: float = 5.0) -> str:
        """Deliver what is queued (up to ``timeout``), say goodbye, disconnect; a report line."""
        deadline = time.monotonic() + timeout
        if self._closing or (not self._sender.is_alive() and self.refused is None):
            return ""
        with self._cond:
            self._sealed = True  # (a call the dispatcher gave up on must not follow the goodbye)
        flushed = self.refused is None and self.flush(timeout)
        if self._will is not None and self._connected:
            # at the commands' QoS when theirs is 2: a QoS 2 message reaches a subscriber only
            # when it is released, so a QoS 1 "offline" right after the last event (both
            # acknowledged by the broker) overtook it at mosquitto_sub once in a while
            goodbye = replace(self._will, qos=max(self._will.qos, self.settings.qos))
            with self._cond:
                self._control.append(goodbye)
                self._cond.notify_all()
            self.flush(min(1.0, max(0.0, deadline - time.monotonic())))
        with self._cond:
            self._closing = True
            lost = [m for m in list(self._inflight.values()) + list(self._queue) if m.command]
            self.stats.pending = len(lost)
            self._cond.notify_all()
        self._sender.join(max(0.1, min(2.0, deadline - time.monotonic())))
        self._client.disconnect()  # a clean disconnect: the broker does not send the will
        self._client.loop_stop()
        s = self.stats
        line = f"MQTT {self.settings.url}: {s.delivered} of {s.queued} messages delivered" + (
            f", {s.dropped} dropped from the full queue" if s.dropped else ""
        )
        if self.refused is not None:
            line += f", {len(lost)} NOT delivered: the broker refused the login ({self.refused})"
        elif not flushed and lost:
            # one entry per topic (the first payload and how many more): a light's command
            # is not hidden behind the desk's own state and event messages
            by_topic: dict[str, list[Message]] = {}
            for m in lost:
                by_topic.setdefault(m.topic, []).append(m)
            shown = "; ".join(
                f"{topic} {group[0].payload[:60].decode('utf-8', 'replace')}"
                + (f" (and {len(group) - 1} more)" if len(group) > 1 else "")
                for topic, group in list(by_topic.items())[:5]
            )
            line += f", {len(lost)} NOT delivered (broker away): {shown}" + (
                " …" if len(by_topic) > 5 else ""
            )
        return line

    # --- paho callbacks (paho's network thread) ------------------------------------------------

    def _on_connect(self, client: Any, userdata: Any, flags: Any, reason: Any, props: Any) -> None:
        if reason.is_failure:  # paho retries with back-off; say it once per outage
            if login_refused(reason):
                self._refuse(str(reason))
                client.disconnect()  # no retry: the same credentials will be refused again
                return
            if not self._outage_logged:
                log.error("MQTT: %s refused the connection: %s", self.settings.url, reason)
                self._outage_logged = True
            return
        with self._cond:
            # connected before the subscriptions are read, under one lock: a subscribe() from
            # now on subscribes itself, one before is in the list (the `set` topic, subscribed
            # in between, had been in neither, and the desk deaf to its commands)
            self._connected = True
            self._resuming = bool(self._inflight)
            wanted = [(topic, qos) for topic, (qos, _) in self._subscriptions.items()]
            if self._birth_again_on is not None:
                wanted.append((self._birth_again_on[0], 1))
            if not wanted:
                self._born()
        if wanted:
            # the birth waits for the SUBACK (_on_subscribe): said `online` while `set` was
            # not yet subscribed, the desk lost the command Home Assistant sent on seeing it.
            # (The SUBACK is read on this thread, so it cannot come before _birth_after is set.)
            _, mid = client.subscribe(wanted)
            with self._cond:
                self._birth_after = (mid, wanted)
        if self._outage_logged:
            log.warning("MQTT: connected to %s again", self.settings.url)
            self._outage_logged = False
        else:
            log.info("MQTT: connected to %s", self.settings.url)
        self._ever_connected.set()

    def _on_disconnect(
        self, client: Any, userdata: Any, flags: Any, reason: Any, props: Any
    ) -> None:
        self._ready.clear()
        with self._cond:
            self._connected = False
            self._birth_after = None
            # paho resends QoS 1/2 messages after reconnecting; a QoS 0 message that was not
            # yet written is gone (at most once), so stop waiting for it
            for mid in [mid for mid, m in self._inflight.items() if m.qos == 0]:
                self._sent_at.pop(mid, None)
                if self._inflight.pop(mid).command:
                    self.stats.dropped += 1
            waiting = len(self._queue) + len(self._inflight)
            self._cond.notify_all()
        if not self._closing and not self._outage_logged:
            log.warning(
                "MQTT: lost the connection to %s (%s); reconnecting, %d command(s) are kept "
                "and sent when it is back",
                self.settings.url,
                reason,
                waiting,
            )
            self._outage_logged = True

    def _on_connect_fail(self, client: Any, userdata: Any) -> None:
        if not self._outage_logged:
            log.warning("MQTT: cannot reach %s; retrying", self.settings.url)
            self._outage_logged = True

    def _on_subscribe(self, client: Any, userdata: Any, mid: int, reasons: Any, props: Any) -> None:
        with self._cond:
            if self._birth_after is None or self._birth_after[0] != mid:
                return  # a subscribe() made later, while connected
            wanted = self._birth_after[1]
            self._birth_after = None
            self._born()
        for (topic, _), reason in zip(wanted, reasons, strict=False):
            if getattr(reason, "is_failure", False):  # e.g. an ACL that denies the topic
                log.warning(
                    "MQTT: %s refused the subscription to %s (%s); messages sent there do "
                    "not reach this desk",
                    self.settings.url,
                    topic,
                    reason,
                )

    def _born(self) -> None:
        """(under self._cond) Send the birth and the kept announcements: the desk is ready."""
        self._announce(self._birth + self._kept)
        self._ready.set()

    def _on_publish(self, client: Any, userdata: Any, mid: int, reason: Any, props: Any) -> None:
        with self._cond:
            message = self._inflight.pop(mid, None)
            self._sent_at.pop(mid, None)
            if message is None:  # acknowledged before _run registered it
                self._early_acks.add(mid)
                return
            self._acknowledged(message)

    def _on_message(self, client: Any, userdata: Any, message: Any) -> None:
        handler = self._subscriptions.get(message.topic)
        if handler is not None:
            try:
                handler[1](message.payload)
            except Exception:  # a subscriber's bug must not take paho's thread down
                log.exception("MQTT: handling a message on %s failed", message.topic)
            return
        if self._birth_again_on and message.payload == self._birth_again_on[1]:
            with self._cond:
                self._announce(self._birth + self._kept)

    def _announce(self, messages: Sequence[Message]) -> None:
        """Queue announcements (under ``self._cond``): one per topic, the newest, bounded."""
        topics = {m.topic for m in messages}
        kept = [m for m in self._control if m.topic not in topics]
        kept.extend(messages)
        if len(kept) > CONTROL_LIMIT:
            log.warning(
                "MQTT: %d announcements waiting; the oldest %d are dropped",
                len(kept),
                len(kept) - CONTROL_LIMIT,
            )
            kept = kept[-CONTROL_LIMIT:]
        self._control = deque(kept)
        self._cond.notify_all()

    def _refuse(self, reason: str) -> None:
        """The broker refused the login: say it once, stop trying, keep nothing waiting."""
        if self.refused is None:
            log.error(
                "MQTT: %s refused the login (%s); check `username` and the password "
                "(`password_env`/`password_file`) of the layout's `mqtt:`; MQTT commands are "
                "not delivered in this run",
                self.settings.url,
                reason,
            )
        with self._cond:
            self.refused = reason  # commands still queue (bounded); close() reports them
            self._cond.notify_all()

    # --- the sender thread --------------------------------------------------------------------

    def _persistent_client(self) -> Any:
        client = self._new_client(clean_session=False)
        client.on_connect = self._on_connect
        client.on_disconnect = self._on_disconnect
        client.on_publish = self._on_publish
        client.on_subscribe = self._on_subscribe
        client.on_message = self._on_message
        client.on_connect_fail = self._on_connect_fail
        client.reconnect_delay_set(RECONNECT_MIN_S, RECONNECT_MAX_S)
        client.max_inflight_messages_set(0)  # our WINDOW limits commands; control adds a few
        return client

    def _run(self) -> None:
        if not self._clean_start():
            return
        s = self.settings
        if self.protocol == self._mqtt.MQTTv5:
            from paho.mqtt.packettypes import PacketTypes
            from paho.mqtt.properties import Properties

            session = Properties(PacketTypes.CONNECT)
            session.SessionExpiryInterval = SESSION_NEVER_EXPIRES
            self._client.connect_async(
                s.host, s.port, s.keepalive, clean_start=False, properties=session
            )
        else:
            self._client.connect_async(s.host, s.port, s.keepalive)
        self._client.loop_start()
        while True:
            with self._cond:
                message = None
                stalled = 0
                while message is None and not self._closing:
                    if self._connected and self._control:
                        message = self._control.popleft()
                    elif (
                        self._connected
                        and not self._resuming
                        and self._queue
                        and len(self._inflight) < WINDOW
                    ):
                        message = self._queue.popleft()
                    else:
                        self._cond.wait(0.5)
                        stalled = self._stalled()
                        if stalled:
                            break
                if message is None:
                    if self._closing:
                        return
                    self._reconnect(stalled)
                    continue
            self._send(message)

    def _stalled(self) -> int:
        """(under self._cond) How many messages have waited over ACK_TIMEOUT_S for their
        acknowledgement on a live connection, once in ACK_TIMEOUT_S; else 0. A broker may
        drop an acknowledgement (mosquitto does, its queue to us full, under a flood): the
        message then waits in flight for ever, and with the window full every gesture after
        it waited too."""
        now = time.monotonic()
        if not self._connected or now - self._unstalled_at < ACK_TIMEOUT_S:
            return 0
        late = [mid for mid in self._inflight if now - self._sent_at.get(mid, now) > ACK_TIMEOUT_S]
        if late:
            self._unstalled_at = now
        return len(late)

    def _reconnect(self, stalled: int) -> None:
        """Drop the connection under paho (it reconnects by itself): on the resumed session
        it sends what is in flight again, as MQTT has a client do only then."""
        log.warning(
            "MQTT: %d message(s) to %s unacknowledged for %g s; reconnecting to send them again",
            stalled,
            self.settings.url,
            ACK_TIMEOUT_S,
        )
        sock = self._client.socket()
        if sock is not None:
            with contextlib.suppress(OSError):
                sock.shutdown(socket.SHUT_RDWR)

    def _send(self, message: Message) -> None:
        try:
            info = self._client.publish(
                message.topic,
                message.payload,
                message.qos,
                message.retain,
                properties=self._expiry if message.command else None,
            )
        except ValueError as err:  # e.g. a topic with a wildcard: this message can never go
            log.error("MQTT: cannot publish to %r: %s; the message is dropped", message.topic, err)
            return
        mqtt = self._mqtt
        with self._cond:
            if info.rc == mqtt.MQTT_ERR_SUCCESS or (
                info.rc == mqtt.MQTT_ERR_NO_CONN and message.qos > 0
            ):
                # in flight; with NO_CONN paho keeps a QoS 1/2 message and sends it on reconnect
                if info.mid in self._early_acks:
                    self._early_acks.discard(info.mid)
                    self._acknowledged(message)
                else:
                    self._inflight[info.mid] = message
                    self._sent_at[info.mid] = time.monotonic()
                    if info.rc == mqtt.MQTT_ERR_NO_CONN:
                        self._resuming = True
            else:  # QoS 0 without a connection, or paho's own queue full: ours keeps it
                (self._queue if message.command else self._control).appendleft(message)
                self._connected = self._connected and info.rc != mqtt.MQTT_ERR_NO_CONN
                self._cond.wait(0.05)

    def _acknowledged(self, message: Message) -> None:
        # under self._cond
        if message.command:
            self.stats.delivered += 1
        if not self._inflight:
            self._resuming = False
        self._cond.notify_all()

    def _clean_start(self) -> bool:
        """Connect once with a clean session (see the module docstring), retrying with back-off."""
        delay = RECONNECT_MIN_S
        while True:
            error = self._try_clean_connect()
            if error is None:
                return True
            if isinstance(error, Refused):
                self._refuse(error.reason)
                return False
            if not self._outage_logged:
                log.warning(
                    "MQTT: cannot connect to %s (%s); commands are kept (up to %d) and sent "
                    "when it can be reached",
                    self.settings.url,
                    error,
                    self.settings.queue_size,
                )
                self._outage_logged = True
            # wait the whole delay: a publish also notifies the condition, and must neither
            # shorten this wait nor (as it did) make the back-off climb to its maximum
            retry_at = time.monotonic() + delay
            with self._cond:
                while not self._closing and time.monotonic() < retry_at:
                    self._cond.wait(retry_at - time.monotonic())
                if self._closing:
                    return False
            delay = min(delay * 2, RECONNECT_MAX_S)

    @property
    def _expiry(self) -> Any:
        """MQTT 5 publish properties of a command: its expiry (None on 3.1.1 or without)."""
        if self.protocol != self._mqtt.MQTTv5 or not self.settings.expiry_s:
            return None
        from paho.mqtt.packettypes import PacketTypes
        from paho.mqtt.properties import Properties

        properties = Properties(PacketTypes.PUBLISH)
        properties.MessageExpiryInterval = self.settings.expiry_s
        return properties

    def _try_clean_connect(self) -> str | Refused | None:
        """A clean connection, in MQTT 5 first under ``protocol: auto``: a broker that turns
        MQTT 5 down (CONNACK 1, unacceptable protocol version) is asked again in 3.1.1, which
        is then used."""
        mqtt = self._mqtt
        first = self._try_clean_connect_in(self.protocol)
        if (
            self.settings.protocol == "auto"
            and self.protocol == mqtt.MQTTv5
            and isinstance(first, str)
            and "Unsupported protocol version" in first  # paho's reading of a 3.1.1 refusal
        ):
            if self._try_clean_connect_in(mqtt.MQTTv311) is None:
                log.warning(
                    "MQTT: %s does not speak MQTT 5 (%s); using 3.1.1 (no message expiry)",
                    self.settings.url,
                    first,
                )
                self.protocol = mqtt.MQTTv311
                self._client = self._persistent_client()
                return None
        return first

    def _try_clean_connect_in(self, protocol: int) -> str | Refused | None:
        client = self._new_client(clean_session=True, with_will=False, protocol=protocol)
        return clean_connect(client, self.settings, protocol == self._mqtt.MQTTv5)

    def _new_client(
        self, *, clean_session: bool, with_will: bool = True, protocol: int | None = None
    ) -> Any:
        """A paho client; in MQTT 5 the session's start is given to ``connect`` instead."""
        mqtt = self._mqtt
        s = self.settings
        protocol = self.protocol if protocol is None else protocol
        client = mqtt.Client(
            mqtt.CallbackAPIVersion.VERSION2,
            client_id=s.client_id,
            clean_session=None if protocol == mqtt.MQTTv5 else clean_session,
            protocol=protocol,
        )
        apply_login(client, s)
        if with_will and self._will is not None:
            w = self._will
            client.will_set(w.topic, w.payload, qos=w.qos, retain=w.retain)
        return client
