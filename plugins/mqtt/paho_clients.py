"""Making paho clients, one way for every connection the plugin opens (the desk's own, its
clean first connection, the duplicate-desk probe, the discovery sweep): paho's callback API,
the protocol and the session's start, the layout's login and TLS files, and MQTT 5's
properties (a session that never expires, a message that does).

paho is imported here, when a connection is made (a layout without MQTT never loads it).
"""

from __future__ import annotations

import ssl
from typing import TYPE_CHECKING, Any

from hapticdesk.plugins.mqtt.settings import MqttSettings

if TYPE_CHECKING:
    from hapticdesk.plugins.mqtt.message import Message

SESSION_NEVER_EXPIRES = 0xFFFFFFFF  # MQTT 5: keep the session as 3.1.1's clean_session=False


def new_client(
    settings: MqttSettings,
    *,
    mqtt5: bool,
    clean_session: bool,
    client_id: str | None = None,
    will: Message | None = None,
) -> Any:
    """A paho client with the layout's login (``client_id``: the layout's by default). In
    MQTT 5 the session's start is given to ``connect`` instead (``clean_start``)."""
    import paho.mqtt.client as mqtt

    client = mqtt.Client(
        mqtt.CallbackAPIVersion.VERSION2,
        client_id=settings.client_id if client_id is None else client_id,
        clean_session=None if mqtt5 else clean_session,
        protocol=mqtt.MQTTv5 if mqtt5 else mqtt.MQTTv311,
    )
    apply_login(client, settings)
    if will is not None:
        client.will_set(will.topic, will.payload, qos=will.qos, retain=will.retain)
    return client


def apply_login(client: Any, settings: MqttSettings) -> None:
    """The layout's user name, password and TLS files on a paho client."""
    if settings.username is not None:
        client.username_pw_set(settings.username, settings.password)
    if settings.tls:
        client.tls_set(
            ca_certs=str(settings.ca) if settings.ca else None,
            certfile=str(settings.cert) if settings.cert else None,
            keyfile=str(settings.key) if settings.key else None,
            cert_reqs=ssl.CERT_REQUIRED,
        )


def message_expiry(seconds: int) -> Any:
    """MQTT 5 PUBLISH properties: the broker drops the message after ``seconds``."""
    from paho.mqtt.packettypes import PacketTypes
    from paho.mqtt.properties import Properties

    properties = Properties(PacketTypes.PUBLISH)
    properties.MessageExpiryInterval = seconds
    return properties


def lasting_session() -> Any:
    """MQTT 5 CONNECT properties: a session the broker keeps however long the desk is away."""
    from paho.mqtt.packettypes import PacketTypes
    from paho.mqtt.properties import Properties

    session = Properties(PacketTypes.CONNECT)
    session.SessionExpiryInterval = SESSION_NEVER_EXPIRES
    return session


def connect_lasting(client: Any, settings: MqttSettings, *, mqtt5: bool) -> None:
    """Start connecting ``client`` (made with ``clean_session=False``) to the layout's broker,
    asking it to keep the session (:func:`lasting_session` on MQTT 5) so that what is in flight
    when the connection drops is sent again on reconnect."""
    s = settings
    if mqtt5:
        client.connect_async(
            s.host, s.port, s.keepalive, clean_start=False, properties=lasting_session()
        )
    else:
        client.connect_async(s.host, s.port, s.keepalive)
