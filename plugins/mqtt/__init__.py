"""The ``mqtt`` action, and the desk as a device on the network.

    mqtt:                                   # optional; defaults shown
      broker: mqtt://localhost:1883         # mqtts:// for TLS
      username: desk
      password_env: DESK_MQTT_PASSWORD      # or password_file: secrets/mqtt.txt
      tls: {ca: ca.crt, cert: desk.crt, key: desk.key}
      client_id: hapticdesk-<desk>            # the desk prefix with - for /
      keepalive: 60
      qos: 2                                # 2: a TOGGLE is delivered exactly once
      retain: false
      discovery: false                      # Home Assistant: true (= entity) or device
      base_topic: hapticdesk                # topics under <base_topic>/<desk>
      prefix: hapticdesk/site1/floor2/study # or the desk's whole prefix (not with base_topic)
      protocol: auto                        # MQTT 5 where the broker speaks it, else 3.1.1
      expiry_s: 60                          # MQTT 5: a command undelivered this long is dropped
      action_style: hapticdesk              # or zigbee2mqtt: lamp_single, brightness_move_up
      zigbee2mqtt_slide: step               # or move (brightness_move_*/brightness_stop)
    desk_name: study                        # in topics; default: the profile's name
    bindings:
      - gesture: tap
        region: lamp
        do: {mqtt: {topic: zigbee2mqtt/desk_lamp/set, payload: {state: TOGGLE}}}

The plugin claims the layout's ``mqtt:`` section (``register_layout_sections``: checked
while the layout loads, so ``hapticdesk check`` refuses what ``run`` would) and provides
``hapticdesk demo`` (``register_commands``). When a run uses MQTT (an ``mqtt`` action, an
``mqtt:`` section or ``--mqtt``), its ``event_sink`` publishes every gesture to
``<prefix>/action`` (by default ``hapticdesk/<desk>``) as a Zigbee2MQTT-style string
(``lamp_tap``) and in full to ``<prefix>/event`` (JSON), with the retained availability
``<prefix>/availability`` (``online``; ``offline`` as last will), and the desk's state JSON
(with ``action``) on ``<prefix>`` itself; a desk whose availability is already ``online``
(another process of the same name) is refused at start. ``discovery: true`` (or ``entity``, or
``device`` for one config per desk) announces the desk to Home Assistant (:mod:`.homeassistant`),
at the start and after every layout switch (:mod:`.announce`); ``action_style: zigbee2mqtt``
sends the actions Zigbee2MQTT's remotes send (:mod:`.z2m`). Its ``control_channel`` listens
on ``<prefix>/set`` (:mod:`.control`).

This module holds the hooks only: the action is :mod:`.action`, the run's connection
:mod:`.desk_link` (over :mod:`.link`), the desk's own topics :mod:`.desk_publisher`, its
sensors :mod:`.sensors`. paho is imported only when the connection is opened.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

from hapticdesk.hookspecs import hookimpl
from hapticdesk.plugins.mqtt.action import OPTIONS, MqttAction, validate
from hapticdesk.plugins.mqtt.announce import LayoutWatch
from hapticdesk.plugins.mqtt.control import SetTopic
from hapticdesk.plugins.mqtt.desk_link import (
    SECTION,
    broker_override,
    desk_state,
    link_for,
    uses_mqtt,
    validate_section,
)
from hapticdesk.plugins.mqtt.desk_publisher import DeskPublisher, announcer_for
from hapticdesk.plugins.mqtt.sensors import SensorPublisher
from hapticdesk.plugins.templating import CHECK_EVENTS
from hapticdesk.runtime.control import ControlQueue
from hapticdesk.runtime.dispatcher import ActionContext
from hapticdesk.runtime.observe import ContactSummary

if TYPE_CHECKING:  # (numpy with it: the hooks load for `hapticdesk --help`)
    from hapticdesk.gestures.layout import Layout


@hookimpl
def event_sink(layout: Layout, context: ActionContext) -> DeskPublisher | None:
    """The desk's own topics, when the run uses MQTT at all."""
    if uses_mqtt(layout.raw, layout.bindings, broker_override(context)):
        return DeskPublisher(context)
    return None


@hookimpl
def contact_sink(layout: Layout, context: ActionContext) -> Callable[[ContactSummary], None] | None:
    """With ``discovery``: force, touch position, resting load and occupancy on the desk's
    state topic, throttled (:mod:`.sensors`), for Home Assistant's sensors, and a look, once
    a block, for another layout in the run (then the desk is announced again); with or
    without it, ``paused`` there when the desk is paused or resumed."""
    if not uses_mqtt(layout.raw, layout.bindings, broker_override(context)):
        return None
    link = link_for(context)
    topic = link.settings.desk_prefix(context.desk_name)
    sensors = SensorPublisher(
        desk_state(context),
        lambda payload: link.publish(topic, payload, qos=0, retain=False),
        sensors=link.settings.discovery,
    )
    if not link.settings.discovery:
        return sensors
    watch = LayoutWatch(context, announcer_for(context).layout_changed)

    def sink(summary: ContactSummary) -> None:
        watch(summary)
        sensors(summary)

    return sink


@hookimpl
def control_channel(control: ControlQueue, layout: Layout, context: ActionContext) -> None:
    """``<prefix>/set``: commands for the running desk (see :mod:`.control`)."""
    if not uses_mqtt(layout.raw, layout.bindings, broker_override(context)):
        return
    link = link_for(context)
    commands = link.handler(link.settings.topics(context.desk_name).set)
    if isinstance(commands, SetTopic):  # subscribed when the link opened (desk_link)
        commands.attach(control)


@hookimpl
def register_layout_sections(register: Callable[..., None]) -> None:
    # the broker's address, credentials and TLS files: the operator's alone (a page that
    # could change the broker would send the password there at the next start)
    register(
        SECTION,
        validate_section,
        "the MQTT broker, credentials, TLS, QoS and topics",
        operator_only=True,
    )


@hookimpl
def register_commands(register: Callable[..., None]) -> None:
    register(
        "demo",
        "hapticdesk.plugins.mqtt.demo",
        "the whole path on a simulated desk and a local broker",
    )


@hookimpl
def register_actions(register: Callable[..., None]) -> None:
    register(
        "mqtt",
        MqttAction,
        "publish to an MQTT broker (templated topic and payload, QoS 0/1/2, TLS)",
        validate=validate,
        check_events=CHECK_EVENTS,
        options=OPTIONS,
    )
