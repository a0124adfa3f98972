"""``action_style: zigbee2mqtt``: the desk's payloads equal those of Zigbee2MQTT remotes for
the same gestures, and the action strings, once shipped, never change."""

from __future__ import annotations

import json

import pytest

from hapticdesk.gestures.event import GestureEvent
from hapticdesk.plugins.mqtt.z2m import Zigbee2MqttActions

from .test_mqtt_homeassistant import hold_file
from .test_runtime_mqtt import run_layout, write_layout

# What Zigbee2MQTT publishes for real remotes (zigbee-herdsman-converters fromZigbee):
# command_move / command_stop (IKEA TRÅDFRI remote E1524/E1810, on/off switch E1743 held),
# command_step (Philips Hue dimmer RWL021, legacy), and the multistate buttons.
TRADFRI_MOVE_UP = {"action": "brightness_move_up", "action_rate": 83}
TRADFRI_MOVE_DOWN = {"action": "brightness_move_down", "action_rate": 83}
TRADFRI_STOP = {"action": "brightness_stop"}
HUE_STEP_UP = {"action": "brightness_step_up", "action_step_size": 30, "action_transition_time": 1}
HUE_STEP_DOWN = {**HUE_STEP_UP, "action": "brightness_step_down"}
BUTTON_SINGLE = {"action": "single"}
BUTTON_DOUBLE = {"action": "double"}
BUTTON_HOLD = {"action": "hold"}
BUTTON_RELEASE = {"action": "release", "action_duration": 1.2}


def same_shape(desk: dict, remote: dict, region: str) -> None:
    """The desk's payload is the remote's: the region in front of the action, the same keys,
    the same types of values."""
    assert desk["action"] == f"{region}_{remote['action']}"
    assert desk.keys() == remote.keys()
    for key in remote:
        assert isinstance(desk[key], type(remote[key]) if key != "action_transition_time"
                          else (int, float)), key  # fmt: skip


def slide(t: float, value: float, phase: str | None = None) -> GestureEvent:
    return GestureEvent(t, "slide", "dimmer", 0.0, 0.0, value=value, phase=phase)


def test_a_slide_in_move_mode_is_a_tradfri_held_button():
    z2m = Zigbee2MqttActions("move")
    out = [
        z2m(slide(0.0, 0.2, "begin")),
        z2m(slide(0.1, 0.3)),  # up: move
        z2m(slide(0.2, 0.5)),  # still up: nothing new
        z2m(slide(0.3, 0.4)),  # down: move down
        z2m(slide(0.4, 0.4, "end")),
    ]
    assert [len(o) for o in out] == [0, 1, 0, 1, 1]
    same_shape(out[1][0], TRADFRI_MOVE_UP, "dimmer")
    assert out[1][0]["action_rate"] == 254  # 0.1 of 254 levels in 0.1 s, at most 255
    same_shape(out[3][0], TRADFRI_MOVE_DOWN, "dimmer")
    same_shape(out[4][0], TRADFRI_STOP, "dimmer")


def test_a_slide_in_step_mode_is_a_hue_dimmer_step():
    z2m = Zigbee2MqttActions("step")
    assert z2m(slide(0.0, 0.5, "begin")) == []
    (up,) = z2m(slide(0.25, 0.6))
    same_shape(up, HUE_STEP_UP, "dimmer")
    assert (up["action_step_size"], up["action_transition_time"]) == (25, 0.25)
    (down,) = z2m(slide(0.5, 0.2))
    same_shape(down, HUE_STEP_DOWN, "dimmer")
    assert down["action_step_size"] == round(0.4 * 254)
    assert z2m(slide(0.6, 0.2)) == []  # no change, no step
    assert z2m(slide(0.7, 0.2, "end")) == []  # steps need no stop


def test_buttons_are_single_double_hold_release():
    z2m = Zigbee2MqttActions()
    same_shape(z2m(GestureEvent(1.0, "tap", "lamp", 0, 0))[0], BUTTON_SINGLE, "lamp")
    same_shape(z2m(GestureEvent(2.0, "double_tap", "lamp", 0, 0))[0], BUTTON_DOUBLE, "lamp")
    same_shape(
        z2m(GestureEvent(3.8, "long_press", "lamp", 0, 0, hold_s=0.8))[0], BUTTON_HOLD, "lamp"
    )
    end = GestureEvent(4.2, "long_press", "lamp", 0, 0, hold_s=0.8, phase="end")
    (release,) = z2m(end)
    same_shape(release, BUTTON_RELEASE, "lamp")
    assert release["action_duration"] == pytest.approx(1.2)  # held from 3.0 s to 4.2 s


# Shipped action strings: never rename one (DESIGN.md); add new ones below.
PINNED = [
    (GestureEvent(0, "tap", "lamp", 0, 0), "lamp_single"),
    (GestureEvent(0, "tap", None, 0, 0), "desk_single"),
    (GestureEvent(0, "double_tap", "lamp", 0, 0), "lamp_double"),
    (GestureEvent(0, "long_press", "lamp", 0, 0, hold_s=0.8), "lamp_hold"),
    (GestureEvent(0, "long_press", "lamp", 0, 0, hold_s=0.8, phase="repeat"), "lamp_hold"),
    (GestureEvent(0, "long_press", "lamp", 0, 0, hold_s=0.8, phase="end"), "lamp_release"),
    (GestureEvent(0, "swipe", "lamp", 0, 0, direction="up"), "lamp_swipe_up"),
    (GestureEvent(0, "press", "lamp", 0, 0, level="firm"), "lamp_press_firm"),
    (GestureEvent(0, "stroke", None, 0, 0, shape="circle"), "desk_stroke_circle"),
]


@pytest.mark.parametrize(("event", "action"), PINNED, ids=[a for _, a in PINNED])
def test_zigbee2mqtt_action_strings_are_pinned(event, action):
    assert [p["action"] for p in Zigbee2MqttActions()(event)] == [action]


@pytest.mark.parametrize(
    ("mode", "actions"),
    [
        ("step", ["dimmer_brightness_step_up", "dimmer_brightness_step_down"]),
        ("move", ["dimmer_brightness_move_up", "dimmer_brightness_move_down",
                  "dimmer_brightness_stop"]),
    ],
)  # fmt: skip
def test_slide_action_strings_are_pinned(mode, actions):
    z2m = Zigbee2MqttActions(mode)
    events = [slide(0, 0.5, "begin"), slide(0.1, 0.7), slide(0.2, 0.3), slide(0.3, 0.3, "end")]
    assert [p["action"] for e in events for p in z2m(e)] == actions


def test_zigbee2mqtt_style_over_mosquitto(broker, subscribe, tmp_path, paper_desk):
    live = subscribe("hapticdesk/study/#")
    bindings = [
        {"gesture": "tap", "region": "lamp", "do": {"log": {}}},
        {"gesture": "long_press", "region": "lamp", "hold_s": 0.8, "do": {"log": {}}},
    ]
    triggers = subscribe("homeassistant/device_automation/#")
    section = {"action_style": "zigbee2mqtt", "discovery": True}
    layout = write_layout(tmp_path, bindings, section, desk_name="study")
    report, events = run_layout(layout, hold_file(tmp_path, paper_desk), broker.url)
    assert report.error is None
    assert [e["gesture"] for e in events] == ["tap", "long_press", "long_press"]
    messages = live.wait_until(lambda m: sum(t.endswith("/event") for _, t, _ in m) == 3)
    actions = [p for _, t, p in messages if t == "hapticdesk/study/action"]
    assert actions == ["lamp_single", "lamp_hold", "lamp_release"]
    states = [json.loads(p) for _, t, p in messages if t == "hapticdesk/study"]
    states = [s for s in states if "action" in s]  # (discovery's sensors share the topic)
    assert [s["action"] for s in states] == actions  # the state JSON carries the action
    assert states[2]["action_duration"] > 0.8
    # the full event keeps the desk's own action strings (the event entity's types)
    full = [json.loads(p)["action"] for _, t, p in messages if t == "hapticdesk/study/event"]
    assert full == ["lamp_tap", "lamp_long_press", "lamp_long_press_end"]
    # Home Assistant's device triggers fire on what the desk sent: they had matched
    # `lamp_tap` on the action topic, where this style sends `lamp_single` (never fired)
    import jinja2

    configs = [json.loads(p) for _, _, p in triggers.wait_for(2)]
    assert {c["payload"] for c in configs} == {"lamp_tap", "lamp_long_press"}
    sent = [(t, p) for _, t, p in messages]
    for config in configs:
        assert config["topic"] == "hapticdesk/study/event"
        render = jinja2.Template(config["value_template"]).render
        fired = [p for t, p in sent if t == config["topic"]]
        assert any(render(value_json=json.loads(p)) == config["payload"] for p in fired)
