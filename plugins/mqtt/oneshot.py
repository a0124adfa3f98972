"""Short connections beside the desk's own: the clean first connection that clears a session
an earlier process left half-finished (see :mod:`.link`) and finds which MQTT the broker
speaks, and the probe that asks the broker
for a retained message (the duplicate-desk check, the stale discovery sweep). Each connects,
waits for one answer, and disconnects."""

from __future__ import annotations

import logging
import os
import ssl
import threading
import uuid
from dataclasses import dataclass
from typing import Any, NamedTuple

from hapticdesk.plugins.mqtt.paho_clients import new_client
from hapticdesk.plugins.mqtt.settings import MqttSettings

log = logging.getLogger(__name__)

# CONNACK reason codes of a refused login: MQTT 3.1.1 return codes 4 and 5, MQTT 5 134 and 135
LOGIN_REFUSED = {4, 5, 134, 135}


@dataclass(frozen=True)
class Refused:
    """The broker refused the login (not worth retrying)."""

    reason: str


def login_refused(reason: Any) -> bool:
    """A CONNACK reason (paho's ReasonCode or a 3.1.1 return code) that refuses the login."""
    return getattr(reason, "value", reason) in LOGIN_REFUSED


class FirstConnect(NamedTuple):
    """How the clean first connection went: ``error`` None when the broker accepted (else
    :class:`Refused` or what went wrong), and whether it speaks MQTT 5."""

    error: str | Refused | None
    mqtt5: bool


def first_clean_connect(settings: MqttSettings, mqtt5: bool) -> FirstConnect:
    """The clean first connection of a desk, under its own client id, in MQTT 5 first when
    ``mqtt5``; under ``protocol: auto`` a broker that turns MQTT 5 down (CONNACK 1,
    unacceptable protocol version) is asked again in 3.1.1, which is then used."""
    first = clean_connect(settings, mqtt5)
    if (
        settings.protocol == "auto"
        and mqtt5
        and isinstance(first, str)
        and "Unsupported protocol version" in first  # paho's reading of a 3.1.1 refusal
        and clean_connect(settings, False) is None
    ):
        log.warning(
            "MQTT: %s does not speak MQTT 5 (%s); using 3.1.1 (no message expiry)",
            settings.url,
            first,
        )
        return FirstConnect(None, False)
    return FirstConnect(first, mqtt5)


def clean_connect(s: MqttSettings, mqtt5: bool) -> str | Refused | None:
    """Connect a new client (the desk's id, a clean session, no last will) and disconnect
    again: None when the broker accepted, :class:`Refused` for a refused login, else what
    went wrong."""
    client = new_client(s, mqtt5=mqtt5, clean_session=True)
    answered = threading.Event()
    outcome: list[Any] = []

    def on_connect(c: Any, u: Any, flags: Any, reason: Any, props: Any) -> None:
        outcome.append(reason)
        answered.set()

    def on_disconnect(c: Any, u: Any, flags: Any, reason: Any, props: Any) -> None:
        # e.g. TLS without the client certificate the broker requires
        outcome.append(f"the broker closed the connection ({reason})")
        answered.set()

    client.on_connect = on_connect
    client.on_disconnect = on_disconnect
    try:
        if mqtt5:
            client.connect(s.host, s.port, s.keepalive, clean_start=True)
        else:
            client.connect(s.host, s.port, s.keepalive)
    except (OSError, ssl.SSLError, ValueError) as err:
        return f"{type(err).__name__}: {err}"
    client.loop_start()
    try:
        if not answered.wait(10.0):
            return "no answer to CONNECT within 10 s"
        if isinstance(outcome[0], str):
            return outcome[0]
        if outcome[0].is_failure:
            if login_refused(outcome[0]):
                return Refused(str(outcome[0]))
            return f"refused: {outcome[0]}"
        return None
    finally:
        client.disconnect()
        client.loop_stop()


class RetainedSweep:
    """What the broker retains on ``patterns``: subscribed, then a probe of our own sent
    after them; when the probe comes back, every retained message has come before it."""

    def __init__(self, patterns: list[str], node: str) -> None:
        self.patterns = patterns
        # a root of its own: subscribers to the desk's topics (hapticdesk/#) never see it
        self.probe = f"hapticdesk-sweep/{node}/{uuid.uuid4().hex}"
        self.found: dict[str, bytes] = {}
        self.done = threading.Event()

    def on_connect(self, c: Any, u: Any, flags: Any, reason: Any, props: Any) -> None:
        if not reason.is_failure:
            c.subscribe([*((p, 1) for p in self.patterns), (self.probe, 1)])

    def on_subscribe(self, c: Any, u: Any, mid: Any, reasons: Any, props: Any) -> None:
        c.publish(self.probe, b"", qos=1)

    def on_message(self, c: Any, u: Any, message: Any) -> None:
        if message.topic == self.probe:
            self.done.set()
        elif message.retain and message.payload and not self.done.is_set():
            self.found[message.topic] = bytes(message.payload)


def retained_payload(settings: MqttSettings, topic: str, timeout_s: float = 3.0) -> bytes | None:
    """The retained message on ``topic`` (None when there is none, or the broker cannot be
    asked within ``timeout_s``). Asked under a client id of its own: connecting with the
    desk's would push a running desk of the same name off the broker. Known to be complete
    when the sweep's own probe comes back (:class:`RetainedSweep`), not after a guessed wait."""
    probe_id = f"{settings.client_id[:100]}-probe-{os.getpid()}"
    client = new_client(settings, mqtt5=False, clean_session=True, client_id=probe_id)
    sweep = RetainedSweep([topic], probe_id)

    def on_connect(c: Any, u: Any, flags: Any, reason: Any, props: Any) -> None:
        sweep.on_connect(c, u, flags, reason, props)
        if reason.is_failure:  # (refused: there is nothing to wait for)
            sweep.done.set()

    client.on_connect = on_connect
    client.on_subscribe = sweep.on_subscribe
    client.on_message = sweep.on_message
    try:
        client.connect(settings.host, settings.port, settings.keepalive)
    except (OSError, ssl.SSLError, ValueError):
        return None
    client.loop_start()
    try:
        sweep.done.wait(timeout_s)
        return sweep.found.get(topic)
    finally:
        client.disconnect()
        client.loop_stop()
