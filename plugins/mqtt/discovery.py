"""Home Assistant MQTT discovery of the desk's gestures as device triggers.

One retained config per bound region and gesture, the way Zigbee2MQTT announces a remote's
buttons: ``<prefix>/device_automation/<node>/<object>/config`` with ``automation_type:
trigger``, a ``type`` (``button_short_press`` …, or the gesture's own name), the region as
``subtype``, and the desk's action topic and action string. Home Assistant then offers "lamp
tapped" in its automation editor with nothing typed by hand.
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from hapticdesk import __version__
from hapticdesk.gestures.event import GestureEvent

#: Home Assistant's own trigger types where a gesture has one
TRIGGER_TYPES = {
    "tap": "button_short_press",
    "double_tap": "button_double_press",
    "long_press": "button_long_press",
}
_DETAIL_KEYS = ("shape", "direction", "level")
_OBJECT_ID = re.compile(r"[^A-Za-z0-9_-]")


@dataclass(frozen=True)
class DeviceTrigger:
    """One discovery config: where it goes and what it says."""

    topic: str
    config: dict[str, Any]

    @property
    def payload(self) -> bytes:
        return json.dumps(self.config, sort_keys=True).encode("utf-8")


def binding_actions(binding: Any) -> list[tuple[str, str, str]]:
    """(action string, trigger type, subtype) for each event a binding reacts to."""
    options = getattr(binding, "options", {}) or {}
    details: list[dict[str, str]] = [{}]
    for key in _DETAIL_KEYS:
        names = options.get(key)
        if names:
            details = [{key: name} for name in names]
            break
    phase = None
    trigger_type = TRIGGER_TYPES.get(binding.gesture)
    if binding.gesture == "long_press" and options.get("release"):
        phase, trigger_type = "end", "button_long_release"
    phases = [(phase, trigger_type)]
    if binding.gesture == "long_press" and options.get("repeat"):
        # hold to dim: the repeats are their own trigger (Home Assistant has no type for it)
        phases.append(("repeat", "button_long_press_repeat"))
    out = []
    for phase, trigger_type in phases:
        for detail in details:
            event = GestureEvent(
                0.0, binding.gesture, binding.region, 0.0, 0.0, phase=phase, **detail
            )
            kind = trigger_type or "_".join([binding.gesture, *detail.values()])
            out.append((event.action_name, kind, binding.region or "desk"))
    return out


def device_triggers(
    bindings: Iterable[Any],
    *,
    desk: str,
    model: str,
    action_topic: str,
    prefix: str = "homeassistant",
    qos: int = 1,
) -> list[DeviceTrigger]:
    """The discovery configs of a layout's bindings (one per distinct action string)."""
    node = _OBJECT_ID.sub("_", desk)
    device = {
        "identifiers": [f"hapticdesk_{node}"],
        "name": desk,
        "model": model,
        "manufacturer": "hapticdesk",
        "sw_version": __version__,
    }
    seen: dict[str, DeviceTrigger] = {}
    for binding in bindings:
        for action, kind, subtype in binding_actions(binding):
            object_id = _OBJECT_ID.sub("_", action)
            if object_id in seen:
                continue
            seen[object_id] = DeviceTrigger(
                f"{prefix}/device_automation/{node}/{object_id}/config",
                {
                    "automation_type": "trigger",
                    "type": kind,
                    "subtype": subtype,
                    "topic": action_topic,
                    "payload": action,
                    "qos": qos,
                    "device": device,
                },
            )
    return list(seen.values())
