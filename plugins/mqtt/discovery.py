"""Home Assistant MQTT discovery of the desk's gestures as device triggers.

One retained config per bound region and gesture, the way Zigbee2MQTT announces a remote's
buttons: ``<prefix>/device_automation/<node>/<object>/config`` with ``automation_type:
trigger``, a ``type`` (``button_short_press`` …, or the gesture's own name), the region as
``subtype``, and the desk's action topic and action string. Home Assistant then offers "lamp
tapped" in its automation editor with nothing typed by hand.

Every trigger listens on the desk's event topic and renders the desk's action string from the
event's JSON with a ``value_template`` (Home Assistant compares the rendered value with
``payload``), so an automation finds the gesture's data in ``trigger.payload_json`` (``x``,
``y``, ``value``, ``level``, ``force_n``, ``hold_s``, ``seq``). What one action string cannot
tell apart gets its own trigger:

- long-press tiers (``hold_s`` 0.8 and 1.5 both give ``lamp_long_press``): one trigger per
  tier, payload ``lamp_long_press_1.5s``, rendered from the event's ``hold_s`` (hold for N
  seconds); a binding's ``repeat: true`` adds a trigger for the repeats while held;
- continuous gestures (``slide``, ``force``) trigger at their ``begin`` and ``end`` only; their
  updates go to the event entity, which carries the value (:mod:`.homeassistant`).

Every template renders from keys every event has, or tests for the key first: Home Assistant
renders each trigger's template on every message of the topic, and warns for each missing key.

Press levels are distinct action strings already (``lamp_press_firm``). The action strings
themselves never change (docs/reference/mqtt.md).
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from hapticdesk.gestures.event import GestureEvent

#: Home Assistant's own trigger types where a gesture has one
TRIGGER_TYPES = {
    "tap": "button_short_press",
    "double_tap": "button_double_press",
    "long_press": "button_long_press",
}
CONTINUOUS = ("slide", "force")  # gestures whose updates are values, not triggers
_DETAIL_KEYS = ("shape", "direction", "level")
_OBJECT_ID = re.compile(r"[^A-Za-z0-9_-]")
# renders the tier of a long press as its trigger payload (lamp_long_press_1.5s); an event
# without hold_s (a tap) renders its bare action, which no tier trigger matches
TIER_TEMPLATE = (
    "{{ value_json.action ~ ('_' ~ value_json.hold_s ~ 's' if value_json.hold_s is defined"
    " else '') }}"
)
# the desk's own action string in the event's JSON (every event has it)
ACTION_TEMPLATE = "{{ value_json.action }}"


def object_id(text: str) -> str:
    """A discovery topic level: letters, digits, ``_`` and ``-`` only."""
    return _OBJECT_ID.sub("_", text)


@dataclass(frozen=True)
class DeviceTrigger:
    """One discovery config: where it goes and what it says."""

    topic: str
    config: dict[str, Any]

    @property
    def payload(self) -> bytes:
        return json.dumps(self.config, sort_keys=True).encode("utf-8")


@dataclass(frozen=True)
class TriggerSpec:
    """What one trigger matches: the action string, its type and subtype, and the hold tier
    when the region has several (then it matches on the event topic)."""

    action: str
    kind: str
    subtype: str
    hold_s: float | None = None

    @property
    def payload(self) -> str:
        return self.action if self.hold_s is None else f"{self.action}_{float(self.hold_s)}s"


def details_of(binding: Any) -> list[dict[str, str]]:
    options = getattr(binding, "options", {}) or {}
    for key in _DETAIL_KEYS:
        names = options.get(key)
        if names:
            return [{key: name} for name in names]
    if binding.gesture == "press" and isinstance(options.get("levels"), dict):
        return [{"level": name} for name in options["levels"]]
    return [{}]


def _phases(binding: Any) -> list[tuple[str | None, str | None]]:
    """(phase, Home Assistant type or None) of the events a binding's trigger fires on."""
    options = getattr(binding, "options", {}) or {}
    if binding.gesture in CONTINUOUS:
        wanted = options.get("phase") or ("begin", "end")
        return [(p, None) for p in ("begin", "end") if p in wanted]
    if binding.gesture != "long_press":
        return [(None, TRIGGER_TYPES.get(binding.gesture))]
    if options.get("release"):
        return [("end", "button_long_release")]
    phases: list[tuple[str | None, str | None]] = [(None, "button_long_press")]
    if options.get("repeat"):
        # hold to dim: the repeats are their own trigger (Home Assistant has no type for it)
        phases.append(("repeat", "button_long_press_repeat"))
    return phases


def binding_actions(binding: Any, tiers: Iterable[float] = ()) -> list[TriggerSpec]:
    """The triggers of one binding; ``tiers``: the hold tiers bound in its region."""
    options = getattr(binding, "options", {}) or {}
    tiers = sorted(set(tiers))
    hold = None
    if binding.gesture == "long_press" and len(tiers) > 1 and "hold_s" in options:
        hold = float(options["hold_s"])
    out = []
    for phase, trigger_type in _phases(binding):
        for detail in details_of(binding):
            event = GestureEvent(
                0.0, binding.gesture, binding.region, 0.0, 0.0, phase=phase, **detail
            )
            kind = trigger_type or "_".join(
                [binding.gesture, *detail.values(), *([phase] if phase else [])]
            )
            if hold is not None and hold != tiers[0]:
                # the lowest tier keeps Home Assistant's own type; the others name their tier
                kind = f"{kind}_{hold}s"
            out.append(TriggerSpec(event.action_name, kind, binding.region or "desk", hold))
    return out


def trigger_specs(bindings: Iterable[Any]) -> list[TriggerSpec]:
    """Every trigger of a layout, one per distinct payload (the first binding wins)."""
    bindings = list(bindings)
    tiers: dict[str | None, set[float]] = {}
    for b in bindings:
        if b.gesture == "long_press" and "hold_s" in (b.options or {}):
            tiers.setdefault(b.region, set()).add(float(b.options["hold_s"]))
    seen: dict[str, TriggerSpec] = {}
    for binding in bindings:
        for spec in binding_actions(binding, tiers.get(binding.region, ())):
            seen.setdefault(object_id(spec.payload), spec)
    return list(seen.values())


def device_triggers(
    bindings: Iterable[Any],
    *,
    device: dict[str, Any],
    origin: dict[str, Any],
    event_topic: str,
    node: str,
    prefix: str = "homeassistant",
    qos: int = 1,
) -> list[DeviceTrigger]:
    """The device-trigger discovery configs of a layout's bindings.

    Device triggers take no ``availability`` (Home Assistant's schema has none); the desk's
    connectivity is its own binary sensor (:mod:`.homeassistant`). Every trigger matches the
    desk's own action string in the event's JSON (see the module docstring), whatever the
    action topic carries (``action_style: zigbee2mqtt`` sends ``lamp_single`` there)."""
    out = []
    for spec in trigger_specs(bindings):
        config: dict[str, Any] = {
            "automation_type": "trigger",
            "type": spec.kind,
            "subtype": spec.subtype,
            "topic": event_topic,
            "value_template": ACTION_TEMPLATE if spec.hold_s is None else TIER_TEMPLATE,
            "payload": spec.payload,
            "qos": qos,
            "device": device,
            "origin": origin,
        }
        out.append(
            DeviceTrigger(
                f"{prefix}/device_automation/{node}/{object_id(spec.payload)}/config", config
            )
        )
    return out
