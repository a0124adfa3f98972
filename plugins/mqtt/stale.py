"""Clearing the desk's stale Home Assistant discovery configs (a binding removed or renamed
since the last run would otherwise leave a ghost trigger or entity).

:func:`sweep_stale` subscribes to ``<prefix>/+/<node>/+/config``, collects what the broker
retains there, and publishes an empty retained payload to each config this run does not
publish (Home Assistant removes the entity; the broker forgets the message). It knows it has
seen every retained config when a probe it sent after subscribing comes back: the broker sends
retained messages while it handles the SUBSCRIBE, before the probe. It uses its own short
connection, so the run's link (and its counts of delivered commands) is not involved.
"""

from __future__ import annotations

import logging
import ssl
import threading
import uuid
from collections.abc import Sequence
from typing import Any

from hapticdesk.plugins.mqtt.settings import MqttSettings, apply_login

log = logging.getLogger(__name__)

SWEEP_TIMEOUT_S = 5.0


def sweep_stale(settings: MqttSettings, prefix: str, node: str, wanted: Sequence[str]) -> list[str]:
    """Clear this desk's retained discovery configs that are not in ``wanted``; the topics
    cleared. Bounded by :data:`SWEEP_TIMEOUT_S`; a broker that cannot be reached clears
    nothing (said in the log) and the run goes on."""
    import paho.mqtt.client as mqtt

    wanted_set = set(wanted)
    pattern = f"{prefix}/+/{node}/+/config"
    # a root of its own: subscribers to the desk's topics (hapticdesk/#) never see the probe
    probe = f"hapticdesk-sweep/{node}/{uuid.uuid4().hex}"
    found: set[str] = set()
    done = threading.Event()
    client = mqtt.Client(
        mqtt.CallbackAPIVersion.VERSION2,
        client_id=f"{settings.client_id}-sweep"[:128],
        clean_session=True,
        protocol=mqtt.MQTTv311,
    )
    apply_login(client, settings)

    def on_connect(c: Any, u: Any, flags: Any, reason: Any, props: Any) -> None:
        if not reason.is_failure:
            c.subscribe([(pattern, 1), (probe, 1)])

    def on_subscribe(c: Any, u: Any, mid: Any, reasons: Any, props: Any) -> None:
        c.publish(probe, b"", qos=1)

    def on_message(c: Any, u: Any, message: Any) -> None:
        if message.topic == probe:
            done.set()
        elif message.retain and message.payload:
            found.add(message.topic)

    client.on_connect = on_connect
    client.on_subscribe = on_subscribe
    client.on_message = on_message
    try:
        client.connect(settings.host, settings.port, settings.keepalive)
    except (OSError, ssl.SSLError, ValueError) as err:
        log.warning("MQTT: stale discovery configs not checked (%s)", err)
        return []
    client.loop_start()
    try:
        if not done.wait(SWEEP_TIMEOUT_S):
            log.warning("MQTT: stale discovery configs not checked (no answer in time)")
            return []
        stale = sorted(found - wanted_set)
        infos = [client.publish(topic, b"", qos=1, retain=True) for topic in stale]
        for info in infos:
            info.wait_for_publish(SWEEP_TIMEOUT_S)
        if stale:
            log.info("MQTT: cleared %d stale discovery config(s): %s", len(stale), stale)
        return stale
    finally:
        client.disconnect()
        client.loop_stop()


def start_sweep(
    settings: MqttSettings, prefix: str, node: str, wanted: Sequence[str]
) -> threading.Thread:
    """:func:`sweep_stale` in its own thread (it never holds up sensing)."""

    def run() -> None:
        try:
            sweep_stale(settings, prefix, node, wanted)
        except Exception:  # a broker quirk must not end the run; the next run tries again
            log.exception("MQTT: clearing stale discovery configs failed")

    thread = threading.Thread(target=run, name="mqtt discovery sweep", daemon=True)
    thread.start()
    return thread
