"""Short connections beside the desk's own: the clean first connection that clears a session
an earlier process left half-finished (see :mod:`.link`), and the probe that asks the broker
for a retained message (the duplicate-desk check, the stale discovery sweep). Each connects,
waits for one answer, and disconnects."""

from __future__ import annotations

import os
import ssl
import threading
import time
from dataclasses import dataclass
from typing import Any

from hapticdesk.plugins.mqtt.settings import MqttSettings, apply_login

# CONNACK reason codes of a refused login: MQTT 3.1.1 return codes 4 and 5, MQTT 5 134 and 135
LOGIN_REFUSED = {4, 5, 134, 135}


@dataclass(frozen=True)
class Refused:
    """The broker refused the login (not worth retrying)."""

    reason: str


def login_refused(reason: Any) -> bool:
    """A CONNACK reason (paho's ReasonCode or a 3.1.1 return code) that refuses the login."""
    return getattr(reason, "value", reason) in LOGIN_REFUSED


def clean_connect(client: Any, s: MqttSettings, mqtt5: bool) -> str | Refused | None:
    """Connect ``client`` (a new paho client, clean session) and disconnect again: None when
    the broker accepted, :class:`Refused` for a refused login, else what went wrong."""
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


def retained_payload(settings: MqttSettings, topic: str, timeout_s: float = 3.0) -> bytes | None:
    """The retained message on ``topic`` (None when there is none, or the broker cannot be
    asked within ``timeout_s``). Asked under a client id of its own: connecting with the
    desk's would push a running desk of the same name off the broker."""
    import paho.mqtt.client as mqtt

    client = mqtt.Client(
        mqtt.CallbackAPIVersion.VERSION2,
        client_id=f"{settings.client_id[:100]}-probe-{os.getpid()}",
        clean_session=True,
        protocol=mqtt.MQTTv311,
    )
    apply_login(client, settings)
    subscribed, answered = threading.Event(), threading.Event()
    found: list[bytes] = []

    def on_connect(c: Any, u: Any, flags: Any, reason: Any, props: Any) -> None:
        if reason.is_failure:
            answered.set()
        else:
            c.subscribe(topic, qos=1)

    def on_subscribe(c: Any, u: Any, mid: Any, reasons: Any, props: Any) -> None:
        subscribed.set()

    def on_message(c: Any, u: Any, message: Any) -> None:
        if message.retain:
            found.append(bytes(message.payload))
            answered.set()

    client.on_connect, client.on_subscribe, client.on_message = on_connect, on_subscribe, on_message
    deadline = time.monotonic() + timeout_s
    try:
        client.connect(settings.host, settings.port, settings.keepalive)
    except (OSError, ssl.SSLError, ValueError):
        return None
    client.loop_start()
    try:
        if subscribed.wait(timeout_s):
            # the broker sends a retained message right after the SUBACK
            answered.wait(min(0.5, max(0.0, deadline - time.monotonic())))
        return found[0] if found else None
    finally:
        client.disconnect()
        client.loop_stop()
