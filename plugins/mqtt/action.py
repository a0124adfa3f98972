"""The ``mqtt`` action: publish a templated payload to a templated topic on the run's
connection (:mod:`.desk_link`), at the layout's QoS or its own."""

from __future__ import annotations

from typing import Any, NamedTuple

from hapticdesk.errors import ConfigError, Position
from hapticdesk.files.marked_values import as_flag
from hapticdesk.gestures.event import GestureEvent
from hapticdesk.plugins.action_options import options_mapping, text, where
from hapticdesk.plugins.mqtt.desk_link import link_for
from hapticdesk.plugins.mqtt.settings import qos_of
from hapticdesk.plugins.templating import (
    Template,
    TemplatedValue,
    compile_template,
    compile_value,
    event_variables,
)
from hapticdesk.runtime.dispatcher import ActionContext

#: the form the browser UI's designer shows for the action's options
OPTIONS = {
    "topic": {"kind": "text", "required": True, "help": "e.g. zigbee2mqtt/lamp/set"},
    "payload": {"kind": "mapping", "help": 'JSON, e.g. {"state": "TOGGLE"}'},
    "qos": {"kind": "integer", "choices": [0, 1, 2], "help": "the layout's by default"},
    "retain": {"kind": "bool", "choices": [True, False], "help": "keep on the broker"},
}


class MqttOptions(NamedTuple):
    """An ``mqtt`` action's options, checked: its topic and payload compiled, its QoS and
    ``retain`` (None: the layout's ``mqtt:`` decides)."""

    topic: Template
    payload: TemplatedValue | None
    qos: int | None
    retain: bool | None


def parse_options(options: Any, position: Position | str) -> MqttOptions:
    """An ``mqtt`` action's options, checked; ConfigError if wrong."""
    m = options_mapping(
        options, position, "`mqtt`", {"topic", "payload", "qos", "retain"}, {"topic"}
    )
    topic = text(m, "topic", "`mqtt`")
    compiled = compile_template(topic, m.where("topic"), "`topic` of `mqtt`")
    if compiled.compiled is None:
        _check_topic(topic, m.where("topic"))
    payload = (
        compile_value(m["payload"], m.where("payload"), "`payload` of `mqtt`")
        if "payload" in m
        else None
    )
    qos = qos_of(m, "`mqtt`", -1)
    retain = as_flag(m.get("retain"))
    if "retain" in m and not isinstance(retain, bool):
        raise ConfigError(m.where("retain"), "`retain` of `mqtt` must be true or false")
    return MqttOptions(compiled, payload, None if qos < 0 else qos, retain)


def validate(options: Any, position: Position | str) -> None:
    parse_options(options, position)


def _check_topic(topic: str, where: Position | str) -> None:
    if not topic or any(c in topic for c in "+#\0"):
        raise ConfigError(
            where, f"an MQTT topic to publish to must not be empty or hold + or #, found {topic!r}"
        )


class MqttAction:
    """Publishes the rendered payload to the rendered topic on the run's connection."""

    timeout_s = 2.0  # publishing only queues; it never waits for the broker
    #: every `mqtt` action of a run publishes on the run's one connection in the order of the
    #: gestures (each on its own lane, two gestures a moment apart could cross at a device)
    order_key = "mqtt"

    def __init__(self, options: Any, context: ActionContext) -> None:
        parsed = parse_options(options, where(options, "`mqtt`"))
        self.topic, self.payload = parsed.topic, parsed.payload
        self.qos, self.retain = parsed.qos, parsed.retain
        self.desk = context.desk_name
        self.link = link_for(context)

    def __call__(self, event: GestureEvent) -> None:
        variables = event_variables(event, self.desk)
        topic = self.topic.render(variables)
        _check_topic(topic, f"topic template {self.topic.text!r}")
        if self.payload is None:
            payload: Any = {**event.to_dict(), "action": event.action_name}
        else:
            payload = self.payload.render(variables)
        self.link.publish(topic, payload, qos=self.qos, retain=self.retain)
