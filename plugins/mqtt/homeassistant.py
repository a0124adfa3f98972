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

Stale configs (a binding removed since the last run) are cleared by :mod:`.stale`.
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
from hapticdesk.plugins.mqtt.discovery import (
    DeviceTrigger,
    details_of,
    device_triggers,
    object_id,
)

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


@dataclass(frozen=True)
class DeskTopics:
    """The desk's own topics (docs/reference/mqtt.md)."""

    prefix: str  # <base>/<desk>: the state JSON

    @property
    def action(self) -> str:
        return f"{self.prefix}/action"

    @property
    def event(self) -> str:
        return f"{self.prefix}/event"

    @property
    def availability(self) -> str:
        return f"{self.prefix}/availability"


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
    identifiers (default: from its name; see ``plugins/mqtt/__init__.py`` ``ha_node``)."""
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

    def entity(component: str, name: str, config: dict[str, Any]) -> DeviceTrigger:
        common = {
            "unique_id": f"hapticdesk_{node}_{name}",
            "device": device,
            "origin": ORIGIN,
            "qos": qos,
        }
        return DeviceTrigger(f"{prefix}/{component}/{node}/{name}/config", {**common, **config})

    types = event_types(bindings)
    if types:
        out.append(
            entity(
                "event",
                "gesture",
                {
                    "name": "Gesture",
                    "state_topic": topics.event,
                    "event_types": types,
                    "value_template": event_template(types),
                    "availability_topic": topics.availability,
                },
            )
        )
    if sensors:
        for component, name, config in SENSORS:
            out.append(
                entity(
                    component,
                    name,
                    {
                        **config,
                        "state_topic": topics.prefix,
                        "availability_topic": topics.availability,
                    },
                )
            )
    out.append(
        entity(
            "binary_sensor",
            "connectivity",
            {
                # no availability of its own: offline must show as "disconnected", not unknown
                "name": "Connected",
                "state_topic": topics.availability,
                "payload_on": "online",
                "payload_off": "offline",
                "device_class": "connectivity",
                "entity_category": "diagnostic",
            },
        )
    )
    return out
