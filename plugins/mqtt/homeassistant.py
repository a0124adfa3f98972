"""The desk as a Home Assistant device: every discovery config it publishes.

Per-component discovery (``<prefix>/<component>/<node>/<object>/config``, retained), each
config with ``origin`` (this software) and ``device`` (the desk):

- ``device_automation``: one trigger per bound gesture (:mod:`.discovery`);
- ``event`` ``gesture``: every gesture, with ``event_types`` the layout's action strings and
  the gesture's fields (value, level, hold_s, x, y, …) as the event's attributes, so a slide's
  value reaches Home Assistant (its ``value_template`` adds ``event_type`` to the event JSON);
- ``sensor`` ``force``/``x``/``y``/``resting_load`` and ``binary_sensor`` ``occupancy``, read
  from the desk's state JSON on ``<base>/<desk>`` (``state_class: measurement``);
- ``binary_sensor`` ``connectivity`` on the retained availability topic (online/offline, the
  last will), so Home Assistant sees the desk go offline. The entities above also take that
  topic as their ``availability_topic``; device triggers have no availability in Home
  Assistant's schema.

:func:`discovery_for` gathers a run's configs, the desk's controls (:mod:`.control`) with
them; stale configs (a binding removed since the last run) are cleared by :mod:`.announce`.
Keys follow Home Assistant's MQTT integration docs (event, sensor, binary_sensor, device
trigger, "MQTT Discovery"); tests/runtime/test_mqtt_homeassistant.py checks every payload
against a table of the documented keys.
"""

from __future__ import annotations

import json
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from hapticdesk import __version__
from hapticdesk.gestures.event import GestureEvent
from hapticdesk.plugins.mqtt.control import control_entities
from hapticdesk.plugins.mqtt.discovery import (
    DeviceTrigger,
    details_of,
    device_triggers,
    object_id,
)
from hapticdesk.plugins.mqtt.settings import DEFAULT_BASE_TOPIC, DeskTopics, MqttSettings
from hapticdesk.runtime.dispatcher import ActionContext

ORIGIN = {"name": "hapticdesk", "sw_version": __version__}

#: the desk's state JSON (on ``<base>/<desk>``) keys the sensors read
SENSORS: list[tuple[str, str, dict[str, Any]]] = [
    # (component, object id, config without the common keys)
    (
        "sensor",
        "force",
        {
            "name": "Force",
            "unit_of_measurement": "N",
            "state_class": "measurement",
            "suggested_display_precision": 1,
            "value_template": "{{ value_json.force_n }}",
        },
    ),
    (
        "sensor",
        "x",
        {
            "name": "Touch x",
            "device_class": "distance",
            "unit_of_measurement": "m",
            "state_class": "measurement",
            "suggested_display_precision": 3,
            "value_template": "{{ value_json.x }}",
        },
    ),
    (
        "sensor",
        "y",
        {
            "name": "Touch y",
            "device_class": "distance",
            "unit_of_measurement": "m",
            "state_class": "measurement",
            "suggested_display_precision": 3,
            "value_template": "{{ value_json.y }}",
        },
    ),
    (
        "sensor",
        "resting_load",
        {
            "name": "Resting load",
            "unit_of_measurement": "N",
            "state_class": "measurement",
            "suggested_display_precision": 1,
            "value_template": "{{ value_json.resting_load_n }}",
        },
    ),
    (
        "binary_sensor",
        "occupancy",
        {
            "name": "Desk in use",
            "device_class": "occupancy",
            "payload_on": "ON",
            "payload_off": "OFF",
            "value_template": "{{ 'ON' if value_json.occupancy else 'OFF' }}",
        },
    ),
]


def discovery_for(
    context: ActionContext, settings: MqttSettings, layouts: list[str] | None = None
) -> list[Any]:
    """The run's Home Assistant discovery configs, one per trigger and entity: the gestures,
    sensors and connectivity (:func:`discovery_configs`) and the desk's controls
    (:mod:`.control`); each has ``topic``, ``config`` and ``payload``. ``layouts``: the
    select's options (default: the current layout's names; a run keeps those it started
    with, as the runtime does)."""
    desk = context.desk_name
    node = ha_node(settings, desk)
    model = f"hapticdesk on {getattr(context.profile, 'name', 'a desk')}"
    topics = settings.topics(desk)
    configs: list[Any] = discovery_configs(
        getattr(context.layout, "bindings", []),
        desk=desk,
        model=model,
        topics=topics,
        prefix=settings.discovery_prefix,
        qos=min(settings.qos, 1),
        node=node,
    )
    controls = control_entities(
        desk=desk,
        set_topic=topics.set,
        state_topic=topics.prefix,
        availability_topic=topics.availability,
        layouts=layout_names(context.layout) if layouts is None else layouts,
        device=device_info(desk, model, node),
        prefix=settings.discovery_prefix,
        node=node,
        origin=ORIGIN,
    )
    return configs + controls


def ha_node(settings: MqttSettings, desk: str) -> str:
    """The desk's node id in Home Assistant (discovery topics, device identifier).

    From the desk's name under the default ``hapticdesk/<desk>`` topics, as always; from the
    desk's whole topic prefix when ``prefix`` or another ``base_topic`` is set, so two desks
    of one name on two floors (``hapticdesk/site1/floor2/study``, ``…/floor3/study``, given
    either way) are two devices, not one."""
    if settings.prefix is None and settings.base_topic == DEFAULT_BASE_TOPIC:
        return object_id(desk)
    return object_id(settings.desk_prefix(desk))


def layout_names(layout: Any) -> list[str]:
    """The names a run can switch among (``default`` and the layout's ``layouts:``), or none."""
    named = getattr(layout, "named_layouts", {}) or {}
    return ["default", *named] if named else []


def device_info(desk: str, model: str, node: str | None = None) -> dict[str, Any]:
    """The ``device`` every config of this desk carries (one device in Home Assistant);
    ``node`` (default: from the desk's name) makes its identifier."""
    return {
        "identifiers": [f"hapticdesk_{node or object_id(desk)}"],
        "name": desk,
        "model": model,
        "manufacturer": "hapticdesk",
        "sw_version": __version__,
    }


#: phases a recognizer emits whatever a binding filters (DeskPublisher sends every event)
PHASES = {
    "long_press": (None, "repeat", "end", "cancel"),
    "slide": (None, "begin", "end", "cancel"),
    "force": (None, "begin", "end", "cancel"),
}


def event_types(bindings: Iterable[Any]) -> list[str]:
    """Every action string the desk can publish for the layout's bindings (the event
    entity's ``event_types``).

    A recognizer reports a gesture in a region only where that gesture is bound to the region;
    anywhere else it reports no region (``desk``), and only when a binding of that gesture has
    no region. So a swipe bound without a region gives ``desk_swipe_up`` and never
    ``lamp_swipe_up``, and a stroke bound on ``pad`` gives ``pad_stroke_circle`` and never
    ``desk_stroke_circle``. A recognizer emits all its phases, and details (shape, direction,
    level) or none."""
    types: set[str] = set()
    for b in bindings:
        for detail in [{}, *details_of(b)]:
            for phase in PHASES.get(b.gesture, (None,)):
                event = GestureEvent(0.0, b.gesture, b.region, 0.0, 0.0, phase=phase, **detail)
                types.add(event.action_name)
    return sorted(types)


def event_template(types: Iterable[str]) -> str:
    """The event entity's ``value_template``: the event's JSON with ``event_type`` (Home
    Assistant's key) set to its ``action``, and nothing for an action not in ``types``.

    Home Assistant drops an event whose type is not listed, and warns for each one; the desk
    publishes every gesture its recognizers see (a swipe is also a ``stroke`` of shape
    ``line``, a shape no binding asked for), so those render empty, which Home Assistant
    ignores without a word."""
    listed = json.dumps(sorted(types))
    return (
        f"{{% if value_json.action in {listed} %}}"
        "{{ dict(value_json, event_type=value_json.action) | tojson }}{% endif %}"
    )


def discovery_configs(
    bindings: Iterable[Any],
    *,
    desk: str,
    model: str,
    topics: DeskTopics,
    prefix: str = "homeassistant",
    qos: int = 1,
    sensors: bool = True,
    node: str | None = None,
) -> list[DeviceTrigger]:
    """Every discovery config of the desk (device triggers, event entity, sensors,
    connectivity), as (topic, config) pairs. ``node``: the desk's node id in the topics and
    identifiers (default: from its name; see :func:`ha_node`)."""
    bindings = list(bindings)
    node = node or object_id(desk)
    device = device_info(desk, model, node)
    out = device_triggers(
        bindings,
        device=device,
        origin=ORIGIN,
        event_topic=topics.event,
        node=node,
        prefix=prefix,
        qos=qos,
    )
    entities = _Entities(node, device, prefix, qos)
    types = event_types(bindings)
    if types:
        out.append(entities.config("event", "gesture", _gesture_event(types, topics)))
    if sensors:
        for component, name, config in SENSORS:
            read = {"state_topic": topics.prefix, "availability_topic": topics.availability}
            out.append(entities.config(component, name, {**config, **read}))
    out.append(entities.config("binary_sensor", "connectivity", _connectivity(topics)))
    return out


@dataclass(frozen=True)
class _Entities:
    """What every entity config of one desk shares: its node id, device, discovery prefix
    and QoS."""

    node: str
    device: dict[str, Any]
    prefix: str
    qos: int

    def config(self, component: str, name: str, config: dict[str, Any]) -> DeviceTrigger:
        """The entity ``name`` of ``component`` with ``config`` and the common keys."""
        common = {
            "unique_id": f"hapticdesk_{self.node}_{name}",
            "device": self.device,
            "origin": ORIGIN,
            "qos": self.qos,
        }
        topic = f"{self.prefix}/{component}/{self.node}/{name}/config"
        return DeviceTrigger(topic, {**common, **config})


def _gesture_event(types: list[str], topics: DeskTopics) -> dict[str, Any]:
    """The event entity every gesture of the layout reaches Home Assistant through."""
    return {
        "name": "Gesture",
        "state_topic": topics.event,
        "event_types": types,
        "value_template": event_template(types),
        "availability_topic": topics.availability,
    }


def _connectivity(topics: DeskTopics) -> dict[str, Any]:
    """The binary sensor of the retained availability (online, or the last will's offline)."""
    return {
        # no availability of its own: offline must show as "disconnected", not unknown
        "name": "Connected",
        "state_topic": topics.availability,
        "payload_on": "online",
        "payload_off": "offline",
        "device_class": "connectivity",
        "entity_category": "diagnostic",
    }
