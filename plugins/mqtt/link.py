"""One MQTT connection per run, and delivery that loses nothing (its settings: :mod:`.settings`).

Commands (a TOGGLE, a brightness) go through :meth:`MqttLink.publish`, which never blocks:
the message joins a bounded queue and a sender thread hands it to paho when the broker is
there. Delivery is tracked by message id in ``on_publish`` (the ledger: :mod:`.outbox`):

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

While the broker cannot be reached the connection is tried again within a second
(:mod:`.reconnect`, which also says each outage once). A broker that *refuses the login* (bad
user name or password, not authorised) is not retried: that is a configuration error, said
once, and every command is reported as not delivered. Announcements (availability, discovery)
are coalesced by topic and bounded, so a chatty ``homeassistant/status`` cannot grow them. On
every connect the subscriptions go first and the birth (``online``, the discovery configs kept)
only once the broker has granted them: whoever acts on seeing the desk ``online`` (Home
Assistant's select) reaches it (:mod:`.presence`). The password never appears in ``repr`` or
the log.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import Any

from hapticdesk.plugins.mqtt.message import Message, encode_payload
from hapticdesk.plugins.mqtt.oneshot import Refused, first_clean_connect, login_refused
from hapticdesk.plugins.mqtt.outbox import LinkStats, Outbox, delivery_failure, delivery_report
from hapticdesk.plugins.mqtt.paho_clients import connect_lasting, message_expiry, new_client
from hapticdesk.plugins.mqtt.presence import Presence
from hapticdesk.plugins.mqtt.reconnect import (
    RECONNECT_MAX_S,
    RECONNECT_MIN_S,
    OutageLog,
    connect_with_backoff,
    drop_connection,
)
from hapticdesk.plugins.mqtt.settings import MqttSettings

log = logging.getLogger(__name__)

#: a message in flight this long on a live connection lost its acknowledgement: reconnect
ACK_TIMEOUT_S = 10.0


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
        #: what waits and what is in flight; its condition guards the link's state too
        self._outbox = Outbox(settings.queue_size, settings.url)
        self._cond = self._outbox.cond
        self.stats: LinkStats = self._outbox.stats
        self._will = will
        #: what the desk listens to, and its birth on every connect
        self._presence = Presence(self._outbox, birth, birth_again_on)
        self._connected = False
        self._closing = False
        # set when close begins: nothing is taken after it, the goodbye is the last message
        self._sealed = False
        self._ever_connected = threading.Event()
        self._outage = OutageLog(settings.url)
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
            self._outbox.add_command(message)

    def announce(self, topic: str, payload: Any, *, retain: bool = False) -> None:
        """Queue a message that is not a command (the answers on ``set/result``): not counted
        in what was delivered, sent while connected, each one (not coalesced by topic: two
        answers in a row are both news), at most :data:`.outbox.CONTROL_LIMIT` waiting. At
        QoS 0: an answer waits for no acknowledgement, so a flood of them cannot hold the
        commands' window (10,000 answers in flight had stopped every gesture's message for
        good)."""
        message = Message(topic, encode_payload(payload), 0, retain, command=False)
        with self._cond:
            if self._closing or self._sealed:
                return
            self._outbox.add_answer(message)

    def keep_announcing(self, messages: Sequence[Message], *, now: bool = False) -> None:
        """Send ``messages`` (retained announcements: Home Assistant's discovery configs) with
        the birth on every (re)connect and when ``birth_again_on`` comes, in place of those
        kept before; ``now``: also queue them at once (when nothing else has sent them)."""
        with self._cond:
            self._presence.keep(messages, now=now)

    def subscribe(self, topic: str, on_message: Callable[[bytes], None], *, qos: int = 0) -> None:
        """Call ``on_message(payload)`` (on paho's thread: it must not block) for every
        message on ``topic``, subscribed again on every connect. QoS 0 by default: a command
        sent while the desk was away is not kept by the broker to arrive late. Made before
        :meth:`start`, the subscription is granted before the birth is sent."""
        with self._cond:
            self._presence.subscribe(topic, qos, on_message)
            connected = self._connected
        if connected:
            self._client.subscribe(topic, qos=qos)

    def handler(self, topic: str) -> Callable[[bytes], None] | None:
        """What :meth:`subscribe` calls for ``topic`` (None when not subscribed)."""
        with self._cond:
            return self._presence.handler(topic)

    def wait_connected(self, timeout: float) -> bool:
        """True once the first connection is up (for the demo and tests)."""
        return self._ever_connected.wait(timeout)

    def wait_ready(self, timeout: float) -> bool:
        """True once connected with every subscription granted and the birth queued: what is
        announced after this finds the desk listening."""
        return self._presence.ready.wait(timeout)

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
        return delivery_failure(self.settings.url, self.stats, self.refused)

    @property
    def undelivered(self) -> int:
        """After :meth:`close`: commands queued but never delivered (dropped from the full
        queue, or still waiting at the end); the run's summary says so."""
        return self.stats.undelivered

    def flush(self, timeout: float) -> bool:
        """Wait until every queued command is acknowledged; False after ``timeout``."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while not self._outbox.empty:
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
                self._outbox.add_last(goodbye)
            self.flush(min(1.0, max(0.0, deadline - time.monotonic())))
        with self._cond:
            self._closing = True
            lost = self._outbox.lost_commands()
            self.stats.pending = len(lost)
            self._cond.notify_all()
        self._sender.join(max(0.1, min(2.0, deadline - time.monotonic())))
        self._client.disconnect()  # a clean disconnect: the broker does not send the will
        self._client.loop_stop()
        return delivery_report(self.settings.url, self.stats, lost, self.refused, flushed)

    # --- paho callbacks (paho's network thread) ------------------------------------------------

    def _on_connect(self, client: Any, userdata: Any, flags: Any, reason: Any, props: Any) -> None:
        if reason.is_failure:  # paho retries with back-off; say it once per outage
            if login_refused(reason):
                self._refuse(str(reason))
                client.disconnect()  # no retry: the same credentials will be refused again
                return
            self._outage.once(
                logging.ERROR, "MQTT: %s refused the connection: %s", self.settings.url, reason
            )
            return
        with self._cond:
            # connected before the subscriptions are read, under one lock: a subscribe() from
            # now on subscribes itself, one before is in the list (the `set` topic, subscribed
            # in between, had been in neither, and the desk deaf to its commands)
            self._connected = True
            self._outbox.reconnected()
            wanted = self._presence.connected()
        if wanted:
            # the birth waits for the SUBACK (_on_subscribe): said `online` while `set` was
            # not yet subscribed, the desk lost the command Home Assistant sent on seeing it.
            # (The SUBACK is read on this thread, so it cannot come before it is expected.)
            _, mid = client.subscribe(wanted)
            with self._cond:
                self._presence.subscribing(mid, wanted)
        self._outage.connected()
        self._ever_connected.set()

    def _on_disconnect(
        self, client: Any, userdata: Any, flags: Any, reason: Any, props: Any
    ) -> None:
        with self._cond:
            self._connected = False
            self._presence.disconnected()
            waiting = self._outbox.disconnected()
        if not self._closing:
            self._outage.once(
                logging.WARNING,
                "MQTT: lost the connection to %s (%s); reconnecting, %d command(s) are kept "
                "and sent when it is back",
                self.settings.url,
                reason,
                waiting,
            )

    def _on_connect_fail(self, client: Any, userdata: Any) -> None:
        self._outage.once(logging.WARNING, "MQTT: cannot reach %s; retrying", self.settings.url)

    def _on_subscribe(self, client: Any, userdata: Any, mid: int, reasons: Any, props: Any) -> None:
        with self._cond:
            wanted = self._presence.granted(mid)
        if wanted is None:
            return  # a subscribe() made later, while connected
        for (topic, _), reason in zip(wanted, reasons, strict=False):
            if getattr(reason, "is_failure", False):  # e.g. an ACL that denies the topic
                log.warning(
                    "MQTT: %s refused the subscription to %s (%s); messages sent there do "
                    "not reach this desk",
                    self.settings.url,
                    topic,
                    reason,
                )

    def _on_publish(self, client: Any, userdata: Any, mid: int, reason: Any, props: Any) -> None:
        with self._cond:
            self._outbox.acknowledge(mid)

    def _on_message(self, client: Any, userdata: Any, message: Any) -> None:
        self._presence.deliver(message.topic, message.payload)

    def _refuse(self, reason: str) -> None:
        """The broker refused the login: say it once, stop trying, keep nothing waiting."""
        if self.refused is None:
            self._outage.login_refused(reason)
        with self._cond:
            self.refused = reason  # commands still queue (bounded); close() reports them
            self._cond.notify_all()

    # --- the sender thread --------------------------------------------------------------------

    def _persistent_client(self) -> Any:
        mqtt5 = self.protocol == self._mqtt.MQTTv5
        client = new_client(self.settings, mqtt5=mqtt5, clean_session=False, will=self._will)
        client.on_connect = self._on_connect
        client.on_disconnect = self._on_disconnect
        client.on_publish = self._on_publish
        client.on_subscribe = self._on_subscribe
        client.on_message = self._on_message
        client.on_connect_fail = self._on_connect_fail
        client.reconnect_delay_set(RECONNECT_MIN_S, RECONNECT_MAX_S)
        client.max_inflight_messages_set(0)  # outbox.WINDOW limits commands; control adds a few
        return client

    def _run(self) -> None:
        # the clean first connection (see the module docstring), retried with back-off
        started = connect_with_backoff(
            self._try_clean_connect,
            self._cond,
            lambda: self._closing,
            self._outage,
            self.settings.queue_size,
        )
        if isinstance(started, Refused):
            self._refuse(started.reason)
        if started is not True:
            return
        connect_lasting(self._client, self.settings, mqtt5=self.mqtt5)
        self._client.loop_start()
        while True:
            with self._cond:
                message = None
                stalled = 0
                while message is None and not self._closing:
                    # nothing before the birth: between the CONNACK and the SUBACK a command
                    # (the desk's state, say) went out before `online` (CI, once in a run)
                    ready = self._connected and self._presence.ready.is_set()
                    message = self._outbox.next_message(ready)
                    if message is None:
                        self._cond.wait(0.5)
                        stalled = self._stalled()
                        if stalled:
                            break
                if message is None:
                    if self._closing:
                        return
                    drop_connection(self._client, stalled, self.settings.url, ACK_TIMEOUT_S)
                    continue
            self._send(message)

    def _stalled(self) -> int:
        """(under self._cond) How many messages have waited over ACK_TIMEOUT_S for their
        acknowledgement on a live connection, once in ACK_TIMEOUT_S; else 0. A broker may
        drop an acknowledgement (mosquitto does, its queue to us full, under a flood): the
        message then waits in flight for ever, and with the window full every gesture after
        it waited too."""
        return self._outbox.late(ACK_TIMEOUT_S) if self._connected else 0

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
                self._outbox.sent(message, info.mid, resent_later=info.rc == mqtt.MQTT_ERR_NO_CONN)
            else:  # QoS 0 without a connection, or paho's own queue full: ours keeps it
                self._outbox.put_back(message)
                self._connected = self._connected and info.rc != mqtt.MQTT_ERR_NO_CONN
                self._cond.wait(0.05)

    @property
    def _expiry(self) -> Any:
        """MQTT 5 publish properties of a command: its expiry (None on 3.1.1 or without)."""
        if self.protocol != self._mqtt.MQTTv5 or not self.settings.expiry_s:
            return None
        return message_expiry(self.settings.expiry_s)

    def _try_clean_connect(self) -> str | Refused | None:
        """The clean first connection (:func:`.oneshot.first_clean_connect`); under
        ``protocol: auto`` the link speaks 3.1.1 from then on if the broker does not speak 5."""
        mqtt = self._mqtt
        first = first_clean_connect(self.settings, self.protocol == mqtt.MQTTv5)
        if not first.mqtt5 and self.protocol == mqtt.MQTTv5:
            self.protocol = mqtt.MQTTv311
            self._client = self._persistent_client()
        return first.error
