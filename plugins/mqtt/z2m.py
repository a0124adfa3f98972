"""``action_style: zigbee2mqtt``: gestures as the actions Zigbee2MQTT's remotes send.

Blueprints and automations written for Zigbee2MQTT remotes match ``action`` values such as
``single``, ``double``, ``hold``, ``release``, ``brightness_move_up`` (with ``action_rate``),
``brightness_stop`` and ``brightness_step_up`` (with ``action_step_size`` and
``action_transition_time``). With this style the desk sends exactly those payloads, each with
the region in front (``lamp_single``), the way the desk's own action strings name regions.

Payloads mirrored (zigbee-herdsman-converters, ``src/converters/fromZigbee``):

- ``command_move`` → ``{"action": "brightness_move_up", "action_rate": rate}`` and
  ``command_stop`` → ``{"action": "brightness_stop"}``: the IKEA TRÅDFRI remote E1524/E1810
  and on/off switch E1743 while a brightness button is held;
- ``command_step`` → ``{"action": "brightness_step_up", "action_step_size": n,
  "action_transition_time": s}``: the Philips Hue dimmer RWL021 (legacy converters) per press;
- ``single``/``double``/``hold``/``release`` (the Xiaomi/Aqara multistate buttons, which also
  carry ``duration`` on release as the Hue dimmer carries ``action_duration``).

Brightness is on Zigbee's level scale, 0..254 (a slide's 0..1 value times 254). Gestures that
no remote has (swipes, strokes, press levels) keep the desk's own action string. The default
style (``hapticdesk``) is unchanged: these strings are opt-in, and once shipped never change
(``tests/runtime/test_mqtt_z2m.py`` pins them).
"""

from __future__ import annotations

from typing import Any

from hapticdesk.gestures.event import GestureEvent

LEVEL_MAX = 254  # Zigbee's level cluster: brightness 0..254
SLIDE_MODES = ("step", "move")
STYLES = ("hapticdesk", "zigbee2mqtt")

#: gesture (and phase) -> the Zigbee2MQTT action a button sends for it
BUTTON_ACTIONS = {
    ("tap", None): "single",
    ("double_tap", None): "double",
    ("long_press", None): "hold",
    ("long_press", "repeat"): "hold",
    ("long_press", "end"): "release",
}


class Zigbee2MqttActions:
    """Translates gesture events into Zigbee2MQTT action payloads (stateful: a slide's steps
    and moves are relative to its previous value).

    ``slide``: ``step`` sends ``brightness_step_up/down`` with the step since the last update;
    ``move`` sends ``brightness_move_up/down`` with the rate when the direction changes, and
    ``brightness_stop`` when the slide ends (release or cancel)."""

    def __init__(self, slide: str = "step") -> None:
        if slide not in SLIDE_MODES:
            raise ValueError(f"slide must be one of {SLIDE_MODES}, found {slide!r}")
        self.slide = slide
        self._last: dict[str | None, tuple[float, float]] = {}  # region -> (t, value)
        self._moving: dict[str | None, str] = {}  # region -> "up"/"down"
        self._held: dict[str | None, float] = {}  # region -> when its hold began

    def __call__(self, event: GestureEvent) -> list[dict[str, Any]]:
        """The payloads (zero, one or two) this event gives, each with ``action``."""
        region = event.region or "desk"
        if event.gesture in ("slide", "force") and event.value is not None:
            return [{**p, "action": f"{region}_{p['action']}"} for p in self._continuous(event)]
        name = BUTTON_ACTIONS.get((event.gesture, event.phase))
        if name is None:
            return [{"action": event.action_name}]
        payload: dict[str, Any] = {"action": f"{region}_{name}"}
        if name == "hold" and event.phase is None:
            self._held[event.region] = event.t - (event.hold_s or 0.0)
        elif name == "release":
            began = self._held.pop(event.region, None)
            if began is not None:
                payload["action_duration"] = round(event.t - began, 3)
        return [payload]

    def _continuous(self, event: GestureEvent) -> list[dict[str, Any]]:
        assert event.value is not None
        region = event.region
        if event.phase == "begin":
            self._last[region] = (event.t, event.value)
            self._moving.pop(region, None)
            return []
        if event.phase in ("end", "cancel"):
            self._last.pop(region, None)
            return [{"action": "brightness_stop"}] if self._moving.pop(region, None) else []
        t0, v0 = self._last.get(region, (event.t, event.value))
        self._last[region] = (event.t, event.value)
        step = round((event.value - v0) * LEVEL_MAX)
        if step == 0:
            return []
        direction = "up" if step > 0 else "down"
        dt = max(event.t - t0, 1e-3)
        if self.slide == "step":
            return [
                {
                    "action": f"brightness_step_{direction}",
                    "action_step_size": abs(step),
                    "action_transition_time": round(dt, 2),
                }
            ]
        if self._moving.get(region) == direction:
            return []
        self._moving[region] = direction
        rate = min(255, max(1, round(abs(event.value - v0) * LEVEL_MAX / dt)))  # levels per s
        return [{"action": f"brightness_move_{direction}", "action_rate": rate}]


def style_from_section(section: Any) -> tuple[str, str]:
    """(``action_style``, ``zigbee2mqtt_slide``) of the layout's ``mqtt:`` section, checked
    (ConfigError naming ``file:line:column``)."""
    from hapticdesk.errors import ConfigError

    if section is None:
        return "hapticdesk", "step"
    out = []
    for key, allowed, default in (
        ("action_style", STYLES, "hapticdesk"),
        ("zigbee2mqtt_slide", SLIDE_MODES, "step"),
    ):
        value = section.get(key, default)
        if value not in allowed:
            where = section.where(key) if hasattr(section, "where") else "`mqtt`"
            raise ConfigError(
                where, f"`{key}` of `mqtt` must be one of {', '.join(allowed)}, found {value!r}"
            )
        out.append(str(value))
    return out[0], out[1]
