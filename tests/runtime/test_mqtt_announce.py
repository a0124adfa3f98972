"""Issue 31: the desk announced to Home Assistant in an order it accepts, at the start and after
every layout switch, in either discovery shape, and moved between the shapes without losing an
entity; all against a real mosquitto, watched by mosquitto_sub. (scripts/ha_check.py runs a
real Home Assistant over the same paths.)"""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import jinja2

from hapticdesk.plugin_loading import load_registry
from hapticdesk.runtime.assembly import build_scene
from hapticdesk.runtime.service import Runtime

from .test_mqtt_homeassistant import BINDINGS_A, hold_file, retained
from .test_runtime_mqtt import run_layout, write_layout

NODE = "homeassistant/device_automation/study"
ONE_TIER = [
    {"gesture": "tap", "region": "lamp", "do": {"log": {}}},
    {"gesture": "long_press", "region": "lamp", "hold_s": 0.8, "do": {"log": {}}},
]


def order_of(messages: list[tuple[bool, str, str]], topic: str, empty: bool) -> int:
    """Where the first message on ``topic`` (empty, or with a payload) came."""
    for i, (_, t, payload) in enumerate(messages):
        if t == topic and (payload in ("", "(null)")) == empty:
            return i
    raise AssertionError(f"no {'empty ' if empty else ''}message on {topic}: {messages}")


def test_old_triggers_are_cleared_before_their_successors_arrive(
    broker, subscribe, tmp_path, paper_desk
):
    """Item 3: one long-press tier, then two: the new 0.8 s trigger has the old one's type and
    subtype (button_long_press, lamp); Home Assistant refuses it while the old one stands, so
    the old config must be cleared first (it went out 70 ms after the new one)."""
    recording = hold_file(tmp_path, paper_desk)
    run_layout(write_layout(tmp_path, ONE_TIER, {"discovery": True}, desk_name="study"),
               recording, broker.url)  # fmt: skip
    assert f"{NODE}/lamp_long_press/config" in retained(broker, "homeassistant/#")
    live = subscribe("homeassistant/#")
    run_layout(write_layout(tmp_path, BINDINGS_A, {"discovery": True}, desk_name="study"),
               recording, broker.url)  # fmt: skip
    seen = live.wait_until(
        lambda m: any(t == f"{NODE}/lamp_long_press_0_8s/config" and p for _, t, p in m)
    )
    cleared = order_of(seen, f"{NODE}/lamp_long_press/config", empty=True)
    assert cleared < order_of(seen, f"{NODE}/lamp_long_press_0_8s/config", empty=False)
    assert f"{NODE}/lamp_long_press/config" not in retained(broker, "homeassistant/#")


def layouts_default_and_b(folder: Path) -> Path:
    """A layout with discovery and ``layouts: {b: b.yaml}``; b has one tap on the knob."""
    (folder / "b.yaml").write_text(
        json.dumps(
            {
                "desk": "kitamura2017",
                "units": "cm",
                "desk_name": "study",
                "regions": {"knob": {"rect": [-5, -5, 5, 5]}},
                "bindings": [{"gesture": "tap", "region": "knob", "do": {"log": {}}}],
                "mqtt": {"discovery": True},
            }
        )
    )
    return write_layout(
        folder, BINDINGS_A, {"discovery": True}, desk_name="study", layouts={"b": "b.yaml"}
    )


def run_switching(layout: Path, recording: Path, url: str, to: str):
    """A run that is told to switch its layout (as the select does) before its first block."""
    scene = build_scene(
        layout, f"replay:{recording}", load_registry(entry_points=False), speed=0,
        overrides={"mqtt": {"broker": url}},
    )  # fmt: skip
    runtime = Runtime(scene)
    switched = runtime.request("layout", to)
    report = runtime.run(handle_signals=False)
    return report, switched.result(1)


def test_a_layout_switch_announces_the_new_layout_and_the_select_shows_it(
    broker, subscribe, tmp_path, paper_desk
):
    """Items 4 and 5: after a switch Home Assistant gets the new layout's triggers (the old
    ones cleared) and event types, and the select reads the running layout from the desk's
    state (it had no state_topic and never learnt a switch made elsewhere)."""
    layout = layouts_default_and_b(tmp_path)
    live = subscribe("hapticdesk/study")
    report, line = run_switching(layout, hold_file(tmp_path, paper_desk), broker.url, "b")
    assert report.error is None and "layout `b`" in line
    configs = {t: json.loads(p) for t, p in retained(broker, "homeassistant/#").items()}
    triggers = {t for t in configs if "/device_automation/" in t}
    assert triggers == {f"{NODE}/knob_tap/config"}
    assert configs["homeassistant/event/study/gesture/config"]["event_types"] == ["knob_tap"]
    select = configs["homeassistant/select/study/layout/config"]
    assert select["options"] == ["default", "b"]  # the run's names, kept after the switch
    assert select["state_topic"] == "hapticdesk/study"
    states = [json.loads(p) for _, _, p in live.wait_until(
        lambda m: any('"layout": "b"' in p for _, _, p in m))]  # fmt: skip
    env = jinja2.Environment()
    shown = {env.from_string(select["value_template"]).render(value_json=s) for s in states}
    assert "b" in shown and shown <= {"default", "b"}


def test_two_identical_taps_are_two_different_messages(broker, subscribe, tmp_path, paper_desk):
    """Home Assistant drops a state equal to the last one: every message carries ``seq``."""
    from hapticdesk.files.recording_io import write_recording

    from .taps import Tap, tap_recording

    path = tmp_path / "taps.npz"
    write_recording(path, tap_recording(paper_desk, [Tap(1.5, 0, 0), Tap(2.5, 0, 0)], 4.0))
    live = subscribe("hapticdesk/study/event")
    layout = write_layout(tmp_path, ONE_TIER[:1], {"discovery": True}, desk_name="study")
    run_layout(layout, path, broker.url)
    events = [json.loads(p) for _, _, p in live.wait_until(lambda m: len(m) >= 2)]
    assert [e["action"] for e in events] == ["lamp_tap", "lamp_tap"]
    assert [e["seq"] for e in events] == [1, 2]


def test_device_discovery_is_one_config_and_the_move_keeps_every_entity(
    broker, subscribe, tmp_path, paper_desk
):
    """``discovery: device``: one retained config for the desk. Coming from one config each,
    every old config is first told to migrate (Home Assistant unloads the entity and keeps it
    in its registries), then cleared, then the device config brings the entities back under
    the same ids (component id = the old object id, same unique_id)."""
    recording = hold_file(tmp_path, paper_desk)
    run_layout(write_layout(tmp_path, BINDINGS_A, {"discovery": True}, desk_name="study"),
               recording, broker.url)  # fmt: skip
    before = {t: json.loads(p) for t, p in retained(broker, "homeassistant/#").items()}
    live = subscribe("homeassistant/#")
    run_layout(write_layout(tmp_path, BINDINGS_A, {"discovery": "device"}, desk_name="study"),
               recording, broker.url)  # fmt: skip
    device = "homeassistant/device/study/config"
    seen = live.wait_until(lambda m: any(t == device and p for _, t, p in m))
    for topic in before:
        migrate = next(i for i, (_, t, p) in enumerate(seen) if t == topic and "migrate" in p)
        assert migrate < order_of(seen, topic, empty=True) < order_of(seen, device, empty=False)
    after = {t: json.loads(p) for t, p in retained(broker, "homeassistant/#").items()}
    assert set(after) == {device}
    config = after[device]
    assert config["device"]["identifiers"] == ["hapticdesk_study"] and config["origin"]["name"]
    for topic, old in before.items():
        component, object_id = topic.split("/")[1], topic.split("/")[3]
        new = config["components"][object_id]
        assert new["platform"] == component
        assert new.get("unique_id") == old.get("unique_id")
        assert {k: v for k, v in new.items() if k != "platform"} == {
            k: v for k, v in old.items() if k not in ("device", "origin")
        }


def test_a_component_left_out_of_the_device_config_is_removed_first(
    broker, subscribe, tmp_path, paper_desk
):
    """Home Assistant removes a device config's component when it comes as its platform
    alone; only then is it left out."""
    recording = hold_file(tmp_path, paper_desk)
    mqtt = {"discovery": "device"}
    run_layout(write_layout(tmp_path, BINDINGS_A, mqtt, desk_name="study"), recording, broker.url)
    live = subscribe("homeassistant/device/study/config")
    run_layout(write_layout(tmp_path, BINDINGS_A[:1], mqtt, desk_name="study"), recording,
               broker.url)  # fmt: skip
    payloads = [json.loads(p) for _, _, p in live.wait_until(lambda m: len(m) >= 3)]
    # the retained one from before, the one emptying what goes, the new one
    emptied, final = payloads[1]["components"], payloads[2]["components"]
    assert emptied["lamp_double_tap"] == {"platform": "device_automation"}
    assert "lamp_double_tap" not in final and "lamp_tap" in final


def test_a_command_sent_on_seeing_the_desk_online_is_taken(broker, subscribe, tmp_path, paper_desk):
    """Home Assistant offers the select the moment the desk is ``online`` and sends at once.
    The desk said ``online`` (and announced itself) when its connection opened, while the
    scene was still being built, and subscribed to ``set`` only when the run began, a second
    later under load: Home Assistant's ``{"command": "layout", "layout": "b"}`` (QoS 0, not
    retained: scripts/ha_check.py saw it on the broker) reached no one. Now ``set`` is granted
    before anything is announced, and a command that comes before sensing waits for it."""
    layout = layouts_default_and_b(tmp_path)
    answers = subscribe("hapticdesk/study/set/result")
    online = subscribe("hapticdesk/study/availability")
    scene = build_scene(
        layout, f"replay:{hold_file(tmp_path, paper_desk)}", load_registry(entry_points=False),
        speed=0, overrides={"mqtt": {"broker": broker.url}},
    )  # fmt: skip
    online.wait_until(lambda m: any(p == "online" for _, _, p in m))
    subprocess.run(
        [shutil.which("mosquitto_pub") or "mosquitto_pub", "-p", str(broker.port), "-q", "0",
         "-t", "hapticdesk/study/set", "-m", '{"command": "layout", "layout": "b"}'],
        check=True, timeout=10,
    )  # fmt: skip
    report = Runtime(scene).run(handle_signals=False)
    assert report.error is None
    said = [json.loads(p) for _, _, p in answers.wait_until(lambda m: bool(m), timeout=10)]
    assert said[0]["command"] == "layout b" and said[0]["ok"] is True
    triggers = {t for t in retained(broker, "homeassistant/#") if "/device_automation/" in t}
    assert triggers == {f"{NODE}/knob_tap/config"}
    # in the broker's order: `set` subscribed before `online` and before any discovery config
    log = broker.log_text()
    subscribed = log.index("\thapticdesk/study/set (QoS")
    assert subscribed < log.index("'hapticdesk/study/availability'")
    assert subscribed < log.index("Received PUBLISH from hapticdesk-study-discovery")


def test_nothing_is_announced_before_the_link_is_ready(broker, tmp_path):
    """The discovery goes out on a connection of its own: it waits until the desk's link says
    its ``set`` subscription is granted (Home Assistant would otherwise offer buttons and a
    select whose commands reach no one)."""
    import threading
    import time

    from hapticdesk.files.yamlfile import load_marked_yaml
    from hapticdesk.plugins.mqtt.announce import Announcer
    from hapticdesk.plugins.mqtt.control import control_entities
    from hapticdesk.plugins.mqtt.settings import settings_from_layout

    settings = settings_from_layout(
        load_marked_yaml("l.yaml", json.dumps({"broker": broker.url, "discovery": True})),
        desk="study",
    )
    configs = control_entities(
        desk="study", set_topic="hapticdesk/study/set", availability_topic="a", layouts=[],
        device={"identifiers": ["hapticdesk_study"]},
    )  # fmt: skip
    ready = threading.Event()
    announcer = Announcer(
        settings, node="study", mode="entity", configs=lambda: configs, keep=lambda step: None,
        ready=ready.wait,
    ).start()  # fmt: skip
    time.sleep(1.0)
    assert retained(broker, "homeassistant/#") == {}
    ready.set()
    deadline = time.monotonic() + 10
    while announcer.rounds == 0 and time.monotonic() < deadline:
        time.sleep(0.05)
    announcer.close()
    assert set(retained(broker, "homeassistant/#")) == {c.topic for c in configs}


def test_back_from_the_device_config_it_is_migrated_and_expires_unemptied(
    broker, subscribe, tmp_path, paper_desk
):
    """From ``discovery: device`` back to ``entity``: the device config gets the migration
    message, retained with an MQTT 5 expiry, and no empty payload (Home Assistant 2025.4.4
    warned "No device components to cleanup" when it was emptied before the new configs, and
    "conflicting MQTT discovery message" for every entity when after them); then the broker
    holds only the per-entity configs."""
    import time

    from hapticdesk.plugins.mqtt.announce import MIGRATE_EXPIRY_S

    recording = hold_file(tmp_path, paper_desk)
    run_layout(write_layout(tmp_path, BINDINGS_A, {"discovery": "device"}, desk_name="study"),
               recording, broker.url)  # fmt: skip
    device = "homeassistant/device/study/config"
    live = subscribe(device)
    run_layout(write_layout(tmp_path, BINDINGS_A, {"discovery": True}, desk_name="study"),
               recording, broker.url)  # fmt: skip
    gone = time.monotonic()
    seen = [(was_retained, p) for was_retained, _, p in live.wait_until(
        lambda m: any("migrate_discovery" in p for _, _, p in m))]  # fmt: skip
    assert seen[0][0] and '"components"' in seen[0][1]  # the device config, retained
    assert [p for _, p in seen[1:]] == ['{"migrate_discovery": true}']  # nothing emptied
    assert f"{NODE}/lamp_tap/config" in retained(broker, "homeassistant/#")
    time.sleep(max(0.0, gone + MIGRATE_EXPIRY_S + 1.0 - time.monotonic()))
    assert device not in retained(broker, "homeassistant/#")


def test_a_switch_seen_during_an_announcement_is_announced_before_the_close_ends_it():
    """The run ends (close) while the first announcement is under way and a layout switch
    asks for another: that one still goes out (it was dropped: the thread saw the close after
    the first and returned, and Home Assistant kept the old layout's triggers)."""
    from hapticdesk.plugins.mqtt.announce import Announcer
    from hapticdesk.plugins.mqtt.settings import MqttSettings

    announcer = Announcer(
        MqttSettings(host="127.0.0.1", port=1, client_id="n"), node="n", mode="entity",
        configs=lambda: [], keep=lambda step: None,
    )  # fmt: skip
    made: list[int] = []

    def announce() -> None:
        made.append(len(made))
        if len(made) == 1:  # the switch and the run's end, both while the first is under way
            announcer.layout_changed()
            announcer._closing = True

    announcer._announce = announce  # type: ignore[method-assign]
    announcer.start()
    announcer.close(timeout=5)
    assert made == [0, 1]
