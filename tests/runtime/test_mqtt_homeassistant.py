"""The desk as a Home Assistant device: every discovery payload against the documented keys,
the templates rendered as Home Assistant renders them (Jinja), stale configs cleared, all
against a real mosquitto."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import jinja2
import pytest

from hapticdesk.files.recording_io import write_recording
from hapticdesk.plugins.mqtt.homeassistant import DeskTopics, discovery_configs, event_types

from .taps import Tap, tap_recording
from .test_runtime_mqtt import run_layout, write_layout

# --- Home Assistant's documented discovery keys ------------------------------------------------
# From home-assistant.io/integrations/{event,sensor,binary_sensor,device_trigger}.mqtt and
# "MQTT Discovery" (device, origin, availability). required, allowed (beyond the common ones).
ENTITY_COMMON = {
    "availability", "availability_mode", "availability_template", "availability_topic",
    "payload_available", "payload_not_available", "device", "enabled_by_default", "encoding",
    "entity_category", "entity_picture", "icon", "json_attributes_template",
    "json_attributes_topic", "name", "object_id", "default_entity_id", "origin", "platform",
    "qos", "unique_id",
}  # fmt: skip
SCHEMA: dict[str, tuple[set[str], set[str]]] = {
    "event": ({"state_topic", "event_types"}, ENTITY_COMMON | {"device_class", "value_template"}),
    "sensor": (
        {"state_topic"},
        ENTITY_COMMON
        | {
            "device_class",
            "state_class",
            "unit_of_measurement",
            "value_template",
            "expire_after",
            "force_update",
            "last_reset_value_template",
            "suggested_display_precision",
            "options",
        },
    ),  # fmt: skip
    "binary_sensor": (
        {"state_topic"},
        ENTITY_COMMON
        | {
            "device_class",
            "payload_on",
            "payload_off",
            "value_template",
            "expire_after",
            "force_update",
            "off_delay",
        },
    ),  # fmt: skip
    # the desk's controls (plugins/mqtt/control.py): MQTT button and MQTT select
    "button": (
        {"command_topic"},
        ENTITY_COMMON | {"command_template", "device_class", "payload_press", "retain"},
    ),
    "select": (
        {"command_topic", "options"},
        ENTITY_COMMON
        | {"command_template", "optimistic", "retain", "state_topic", "value_template"},
    ),
    "device_automation": (
        {"automation_type", "topic", "type", "subtype", "device"},
        {"payload", "qos", "value_template", "origin", "platform"},
    ),
}
DEVICE_KEYS = {
    "identifiers", "connections", "name", "manufacturer", "model", "model_id", "sw_version",
    "hw_version", "serial_number", "suggested_area", "via_device", "configuration_url",
}  # fmt: skip
ORIGIN_KEYS = ({"name"}, {"name", "sw_version", "support_url"})
STATE_CLASSES = {"measurement", "total", "total_increasing"}
EVENT_DEVICE_CLASSES = {"button", "doorbell", "motion"}
BINARY_DEVICE_CLASSES = {"connectivity", "occupancy", "motion", "presence", "problem", "running"}


def check_config(topic: str, config: dict[str, Any]) -> str:
    """Assert one discovery config matches Home Assistant's documented schema; its component."""
    parts = topic.split("/")
    assert len(parts) == 5 and parts[-1] == "config", topic
    component = parts[1]
    required, allowed = SCHEMA[component]
    assert required <= config.keys(), (topic, required - config.keys())
    assert config.keys() <= required | allowed, (topic, config.keys() - required - allowed)
    origin = config.get("origin")
    assert origin is not None, f"{topic} has no origin"
    assert ORIGIN_KEYS[0] <= origin.keys() <= ORIGIN_KEYS[1]
    assert config["device"]["identifiers"] and config["device"].keys() <= DEVICE_KEYS
    if component == "device_automation":
        assert config["automation_type"] == "trigger"
        assert "availability_topic" not in config  # not in the trigger schema
    else:
        assert config["unique_id"].startswith("hapticdesk_")
    if component == "event":
        assert config["event_types"] and all(isinstance(t, str) for t in config["event_types"])
        assert config.get("device_class", "button") in EVENT_DEVICE_CLASSES
    if "state_class" in config:
        assert config["state_class"] in STATE_CLASSES
    if component == "binary_sensor" and "device_class" in config:
        assert config["device_class"] in BINARY_DEVICE_CLASSES
    if "entity_category" in config:
        assert config["entity_category"] in {"config", "diagnostic"}
    return component


def render(template: str, payload: str) -> str:
    """A value template as Home Assistant renders it (``value`` and ``value_json``)."""
    env = jinja2.Environment()
    return env.from_string(template).render(value=payload, value_json=json.loads(payload))


def retained(broker, topic: str) -> dict[str, str]:
    """What the broker retains under ``topic`` now (a fresh subscriber's view)."""
    sub = shutil.which("mosquitto_sub") or "mosquitto_sub"
    out = subprocess.run(
        [sub, "-p", str(broker.port), "-t", topic, "--retained-only", "-W", "1", "-F", "%t %p"],
        capture_output=True,
        text=True,
    ).stdout
    return dict(line.split(" ", 1) for line in out.splitlines() if " " in line)


def binding(gesture: str, region: str | None = "lamp", **options: Any) -> SimpleNamespace:
    return SimpleNamespace(gesture=gesture, region=region, options=options)


# --- payloads, without a broker ---------------------------------------------------------------

LAYOUT = [
    binding("tap"),
    binding("long_press", hold_s=0.8),
    binding("long_press", hold_s=1.5),
    binding("long_press", hold_s=0.8, release=True),
    binding("press", levels={"light": 2.0, "firm": 8.0}),
    binding("slide", region="dimmer"),
    binding("swipe", region=None, direction=["up", "down"]),
]


def configs_of(bindings) -> dict[str, dict[str, Any]]:
    out = discovery_configs(
        bindings, desk="study", model="m", topics=DeskTopics("hapticdesk/study")
    )
    return {c.topic: c.config for c in out}


def test_every_config_matches_the_documented_schema_and_carries_origin():
    configs = configs_of(LAYOUT)
    components = [check_config(topic, config) for topic, config in configs.items()]
    assert {"device_automation", "event", "sensor", "binary_sensor"} == set(components)
    # Home Assistant: type and subtype are unique per device
    triggers = [c for c in configs.values() if c.get("automation_type") == "trigger"]
    pairs = [(c["type"], c["subtype"]) for c in triggers]
    assert len(pairs) == len(set(pairs))


def test_long_press_tiers_and_press_levels_are_distinct_triggers():
    configs = configs_of(LAYOUT)
    node = "homeassistant/device_automation/study"
    short = configs[f"{node}/lamp_long_press_0_8s/config"]
    long = configs[f"{node}/lamp_long_press_1_5s/config"]
    assert (short["type"], long["type"]) == ("button_long_press", "button_long_press_1.5s")
    # both tiers share the action string; the event's hold_s tells them apart
    for config, hold in ((short, 0.8), (long, 1.5)):
        event = json.dumps({"action": "lamp_long_press", "hold_s": hold, "gesture": "long_press"})
        assert config["topic"] == "hapticdesk/study/event"
        assert render(config["value_template"], event) == config["payload"]
    other = json.dumps({"action": "lamp_long_press", "hold_s": 1.5})
    assert render(short["value_template"], other) != short["payload"]
    assert configs[f"{node}/lamp_long_press_end_0_8s/config"]["type"] == "button_long_release"
    assert configs[f"{node}/lamp_press_light/config"]["payload"] == "lamp_press_light"
    assert configs[f"{node}/lamp_press_firm/config"]["type"] == "press_firm"


def test_a_slide_triggers_at_begin_and_end_only_and_its_updates_are_events():
    configs = configs_of(LAYOUT)
    slide = sorted(t for t in configs if "/dimmer_slide" in t)
    assert slide == [
        "homeassistant/device_automation/study/dimmer_slide_begin/config",
        "homeassistant/device_automation/study/dimmer_slide_end/config",
    ]
    event = configs["homeassistant/event/study/gesture/config"]
    assert "dimmer_slide" in event["event_types"]  # updates reach the event entity
    update = json.dumps({"action": "dimmer_slide", "gesture": "slide", "value": 0.42})
    rendered = json.loads(render(event["value_template"], update))
    assert rendered["event_type"] == "dimmer_slide" and rendered["value"] == 0.42
    assert set(event_types(LAYOUT)) >= {"lamp_tap", "lamp_press_firm", "desk_swipe_up"}


def test_event_types_are_only_what_the_desk_can_send():
    """Issue 31 item 6: a gesture carries a region only where it is bound there; a binding
    without a region gives `desk_…` only (`lamp_swipe_up`, `pad_stroke_circle` were listed:
    32 types for a layout that can send 12)."""
    from hapticdesk.plugins.mqtt import discovery_for
    from hapticdesk.plugins.mqtt.settings import MqttSettings

    bindings = [
        binding("tap"),
        binding("swipe", region=None, direction=["up"]),
        binding("stroke", region="pad", shape=["circle"]),
    ]
    layout = SimpleNamespace(bindings=bindings, regions={"lamp": 0, "pad": 0}, named_layouts={})
    context = SimpleNamespace(desk_name="study", profile=None, layout=layout)
    configs = {c.topic: c.config for c in discovery_for(context, MqttSettings())}
    assert set(configs["homeassistant/event/study/gesture/config"]["event_types"]) == {
        "lamp_tap", "desk_swipe", "desk_swipe_up", "pad_stroke", "pad_stroke_circle",
    }  # fmt: skip


def test_the_event_entity_renders_nothing_for_an_action_it_does_not_list():
    """Issue 31 item 1: a swipe is also a stroke of shape `line`; Home Assistant logged
    "Invalid event type desk_stroke_line" for each. Unlisted actions now render empty (which
    Home Assistant ignores) and listed ones render with `event_type`."""
    configs = configs_of([binding("swipe", region=None, direction=["up"])])
    event = configs["homeassistant/event/study/gesture/config"]
    line = json.dumps({"action": "desk_stroke_line", "gesture": "stroke", "shape": "line"})
    assert render(event["value_template"], line).strip() == ""
    up = json.dumps({"action": "desk_swipe_up", "gesture": "swipe", "x": 0.1, "y": 0.2, "seq": 3})
    rendered = json.loads(render(event["value_template"], up))
    assert rendered["event_type"] == "desk_swipe_up" and rendered["seq"] == 3


def test_no_trigger_template_reads_a_key_an_event_lacks():
    """Issue 31 item 2: Home Assistant renders every trigger's template on every event (70
    "has no attribute 'hold_s'" warnings for a tap, a long press and a slide). Rendered with
    undefined keys as errors, every template takes every kind of event."""
    env = jinja2.Environment(undefined=jinja2.StrictUndefined)
    templates = {
        c["value_template"]
        for c in configs_of(LAYOUT).values()
        if c.get("automation_type") == "trigger"
    }
    assert len(templates) == 2  # the action's, and the tier's
    events = [
        {"action": "lamp_tap", "gesture": "tap"},
        {"action": "dimmer_slide", "gesture": "slide", "value": 0.4},
        {"action": "lamp_long_press", "gesture": "long_press", "hold_s": 1.5},
    ]
    for template in templates:
        for event in events:
            env.from_string(template).render(value=json.dumps(event), value_json=event)


# --- with mosquitto -----------------------------------------------------------------------------


def hold_file(folder: Path, profile) -> Path:
    """A tap, then a press held 3.5 s (both long-press tiers and the release)."""
    path = folder / "hold.npz"
    taps = [Tap(1.5, 0.0, 0.0), Tap(2.5, 0.0, 0.0, duration_s=3.5)]
    write_recording(path, tap_recording(profile, taps, 7.0))
    return path


BINDINGS_A = [
    {"gesture": "tap", "region": "lamp", "do": {"log": {}}},
    {"gesture": "double_tap", "region": "lamp", "do": {"log": {}}},
    {"gesture": "long_press", "region": "lamp", "hold_s": 0.8, "do": {"log": {}}},
    {"gesture": "long_press", "region": "lamp", "hold_s": 1.5, "do": {"log": {}}},
]


def test_discovery_over_mosquitto_event_sensors_connectivity(
    broker, subscribe, tmp_path, paper_desk
):
    live = subscribe("hapticdesk/study/#")
    layout = write_layout(tmp_path, BINDINGS_A, {"discovery": True}, desk_name="study")
    report, events = run_layout(layout, hold_file(tmp_path, paper_desk), broker.url)
    assert report.error is None
    assert [e.get("hold_s") for e in events if e["gesture"] == "long_press"][:2] == [0.8, 1.5]
    configs = {t: json.loads(p) for t, p in retained(broker, "homeassistant/#").items()}
    for topic, config in configs.items():
        check_config(topic, config)
    event = configs["homeassistant/event/study/gesture/config"]
    assert event["state_topic"] == "hapticdesk/study/event"
    assert event["availability_topic"] == "hapticdesk/study/availability"
    connectivity = configs["homeassistant/binary_sensor/study/connectivity/config"]
    assert connectivity["state_topic"] == "hapticdesk/study/availability"
    assert (connectivity["payload_on"], connectivity["payload_off"]) == ("online", "offline")
    assert connectivity["device_class"] == "connectivity"
    force = configs["homeassistant/sensor/study/force/config"]
    assert (force["unit_of_measurement"], force["state_class"]) == ("N", "measurement")
    assert "homeassistant/binary_sensor/study/occupancy/config" in configs
    # the event entity turns every published event into one of its event types (waited for:
    # the run has ended, but the subscriber may not have printed them all yet)
    every = live.wait_until(
        lambda m: (
            sum(t == "hapticdesk/study/event" for _, t, _ in m) >= len(events)
            and [p for _, t, p in m if t == "hapticdesk/study/availability"][-1:] == ["offline"]
        )
    )
    published = [p for _, t, p in every if t == "hapticdesk/study/event"]
    assert len(published) == len(events)
    for payload in published:
        assert json.loads(render(event["value_template"], payload))["event_type"] in set(
            event["event_types"]
        )
    # the tier triggers fire once each, on the press that reached them
    node = "homeassistant/device_automation/study"
    for tier in ("0_8s", "1_5s"):
        trigger = configs[f"{node}/lamp_long_press_{tier}/config"]
        fired = [p for p in published if render(trigger["value_template"], p) == trigger["payload"]]
        assert len(fired) == 1
    # the sensors read the state JSON on hapticdesk/study: numbers, throttled to 2 Hz
    states = [p for _, t, p in every if t == "hapticdesk/study"]
    sensors = {
        name: configs[f"homeassistant/{component}/study/{name}/config"]
        for component, name in [("sensor", "force"), ("sensor", "x"), ("sensor", "y"),
                                ("sensor", "resting_load"), ("binary_sensor", "occupancy")]
    }  # fmt: skip
    forces = [float(render(sensors["force"]["value_template"], p)) for p in states]
    assert all(f >= 0 for f in forces) and max(forces) > 5.0  # the 10 N press was seen
    for name in ("x", "y", "resting_load"):
        values = [render(sensors[name]["value_template"], p) for p in states]
        assert all(v == "None" or abs(float(v)) < 1.0 for v in values)  # "None": unknown
    occupancy = [render(sensors["occupancy"]["value_template"], p) for p in states]
    assert occupancy[0] == "OFF" and "ON" in occupancy
    sensor_only = [p for p in states if "action" not in json.loads(p)]
    assert len(sensor_only) <= 7.0 * 2 + 3  # 7 s of samples at 2 Hz, and occupancy changes
    # the desk went offline at the end: the connectivity sensor reads it from the retained topic
    assert retained(broker, "hapticdesk/study/availability") == {
        "hapticdesk/study/availability": "offline"
    }


def test_a_removed_binding_has_its_config_cleared(broker, tmp_path, paper_desk):
    recording = hold_file(tmp_path, paper_desk)
    layout = write_layout(tmp_path, BINDINGS_A, {"discovery": True}, desk_name="study")
    run_layout(layout, recording, broker.url)
    node = "homeassistant/device_automation/study"
    before = retained(broker, "homeassistant/#")
    assert f"{node}/lamp_double_tap/config" in before
    assert f"{node}/lamp_long_press_1_5s/config" in before
    # another desk's configs are none of this desk's business
    other = "homeassistant/device_automation/other/lamp_tap/config"
    pub = shutil.which("mosquitto_pub") or "mosquitto_pub"
    subprocess.run([pub, "-p", str(broker.port), "-t", other, "-m", "{}", "-r"], check=True)

    # layout B: the double tap and the second tier are gone
    layout = write_layout(tmp_path, BINDINGS_A[:1], {"discovery": True}, desk_name="study")
    report, _ = run_layout(layout, recording, broker.url)
    assert report.error is None
    after = retained(broker, "homeassistant/#")
    assert f"{node}/lamp_double_tap/config" not in after
    assert f"{node}/lamp_long_press_1_5s/config" not in after
    assert f"{node}/lamp_long_press_0_8s/config" not in after
    assert f"{node}/lamp_tap/config" in after
    assert "homeassistant/event/study/gesture/config" in after
    assert other in after


def test_without_a_broker_the_announcement_gives_up_quietly(caplog):
    from hapticdesk.plugins.mqtt.announce import publish_steps
    from hapticdesk.plugins.mqtt.settings import MqttSettings

    from .conftest import free_port

    settings = MqttSettings(host="127.0.0.1", port=free_port(), client_id="t")
    assert publish_steps(settings, "homeassistant", "study", lambda found: []) is None
    assert "Home Assistant discovery not announced" in caplog.text


@pytest.mark.parametrize(
    ("section", "message"),
    [
        ("{action_style: z2m}", "`action_style` of `mqtt` must be one of hapticdesk, zigbee2mqtt"),
        ("{zigbee2mqtt_slide: fast}", "`zigbee2mqtt_slide` of `mqtt` must be one of step, move"),
    ],
)
def test_a_bad_style_names_its_place(tmp_path, section, message):
    from hapticdesk.errors import ConfigError
    from hapticdesk.plugin_loading import load_registry
    from hapticdesk.runtime.assembly import load_scene_layout

    path = tmp_path / "layout.yaml"
    path.write_text(
        "desk: kitamura2017\nunits: cm\nregions: {lamp: {rect: [-10, -10, 10, 10]}}\n"
        f"bindings: [{{gesture: tap, region: lamp, do: {{log: {{}}}}}}]\nmqtt: {section}\n"
    )
    with pytest.raises(ConfigError, match=rf"layout.yaml:5:\d+: {message}"):
        load_scene_layout(path, load_registry(entry_points=False), None)


def test_two_desks_of_one_name_on_two_floors_are_two_devices():
    """Issue 14 item 4: with a topic prefix per floor, desks called `study` on two floors get
    their own discovery topics and device identifiers; the default topics keep the old ones."""
    from hapticdesk.plugins.mqtt import discovery_for
    from hapticdesk.plugins.mqtt.settings import MqttSettings

    binding = SimpleNamespace(
        gesture="tap", region="lamp", index=0, options={}, actions=[], filters={}
    )
    layout = SimpleNamespace(bindings=[binding], regions={"lamp": None}, named_layouts={})
    context = SimpleNamespace(desk_name="study", profile=SimpleNamespace(name="kitamura2017"))
    context.layout = layout

    def devices(settings: MqttSettings) -> tuple[set[str], set[str]]:
        configs = discovery_for(context, settings)
        nodes = {c.topic.split("/")[2] for c in configs}
        ids = {i for c in configs for i in json.loads(c.payload)["device"]["identifiers"]}
        return nodes, ids

    floor2 = devices(MqttSettings(prefix="hapticdesk/site1/floor2/study"))
    floor3 = devices(MqttSettings(prefix="hapticdesk/site1/floor3/study"))
    default = devices(MqttSettings())
    assert len(floor2[0]) == len(floor2[1]) == 1  # one device per desk, one node
    assert floor2[0].isdisjoint(floor3[0]) and floor2[1].isdisjoint(floor3[1])
    assert default == ({"study"}, {"hapticdesk_study"})  # unchanged for the default topics
    # the same floors given as `base_topic` (the desk's name appended): two devices too, and
    # the same ones as with the whole prefix (they had both been `study`)
    by_base2 = devices(MqttSettings(base_topic="hapticdesk/site1/floor2"))
    by_base3 = devices(MqttSettings(base_topic="hapticdesk/site1/floor3"))
    assert by_base2 == floor2 and by_base3 == floor3
    assert devices(MqttSettings(base_topic="hapticdesk")) == default
