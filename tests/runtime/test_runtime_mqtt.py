"""MQTT against a real mosquitto, with mosquitto_sub as the independent client."""

from __future__ import annotations

import json
import logging
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from types import SimpleNamespace

import pytest

from hapticdesk.errors import ConfigError
from hapticdesk.files.recording_io import write_recording
from hapticdesk.files.yamlfile import load_marked_yaml
from hapticdesk.hookspecs import hookimpl
from hapticdesk.plugin_loading import load_registry
from hapticdesk.plugins.mqtt.link import MqttLink
from hapticdesk.plugins.mqtt.message import Message
from hapticdesk.plugins.mqtt.settings import MqttSettings, settings_from_layout
from hapticdesk.runtime.assembly import build_scene
from hapticdesk.runtime.service import Runtime

from .conftest import Mosquitto, Subscriber, make_tls, wait_subscribed
from .taps import Tap, tap_recording

LAMP = {"rect": [-10, -10, 10, 10]}


def write_layout(folder: Path, bindings: list[dict], mqtt: dict | None = None, **top) -> Path:
    doc = {
        "desk": "kitamura2017",
        "units": "cm",
        "regions": {"lamp": LAMP},
        "bindings": bindings,
        **top,
    }
    if mqtt is not None:
        doc["mqtt"] = mqtt
    path = folder / "layout.yaml"
    path.write_text(json.dumps(doc))  # JSON is YAML
    return path


def taps_file(folder: Path, profile, count: int, *, gap_s: float = 0.6) -> Path:
    taps = [Tap(1.5 + i * gap_s, 0.0, 0.0) for i in range(count)]
    path = folder / "taps.npz"
    write_recording(path, tap_recording(profile, taps, 1.5 + count * gap_s + 0.5))
    return path


TOGGLE = {
    "gesture": "tap",
    "region": "lamp",
    "do": {"mqtt": {"topic": "lamp/set", "payload": {"state": "TOGGLE", "t": "{{ t }}"}}},
}


def run_layout(layout: Path, recording: Path, url: str, *, plugins=(), **kw):
    registry = load_registry(entry_points=False, plugins=plugins)
    scene = build_scene(
        layout, f"replay:{recording}", registry, speed=0, overrides={"mqtt": {"broker": url}}, **kw
    )
    events = layout.parent / "events.jsonl"
    report = Runtime(scene, events_path=events).run(handle_signals=False)
    return report, [json.loads(line) for line in events.read_text().splitlines()]


def test_every_command_arrives_once_in_order(broker, subscribe, tmp_path, paper_desk):
    sub = subscribe("lamp/#")
    layout = write_layout(tmp_path, [TOGGLE])
    report, events = run_layout(layout, taps_file(tmp_path, paper_desk, 12), broker.url)
    assert len(events) == 12
    messages = sub.wait_for(12)
    assert [m[1] for m in messages] == ["lamp/set"] * 12
    payloads = [json.loads(m[2]) for m in messages]
    assert [p["state"] for p in payloads] == ["TOGGLE"] * 12
    assert [p["t"] for p in payloads] == pytest.approx([e["t"] for e in events], abs=1e-6)
    # 12 commands, and each gesture three times on the desk's own topics (action, state, event)
    assert report.notes == [f"MQTT {broker.url}: 48 of 48 messages delivered"]


def test_a_broker_restart_mid_stream_loses_nothing_and_doubles_nothing(
    mosquitto_available, tmp_path
):
    # mosquitto restores at most max_inflight_messages (default 20) open QoS 2 exchanges per
    # client and sends the rest again as new messages: a subscriber that fell behind on a loaded
    # machine then got one twice (test_runtime_broker_restart_qos2.py shows it). Exactly once
    # across a restart needs a broker that restores them all; this one does.
    broker = Mosquitto(tmp_path, extra=["max_inflight_messages 1000"])
    broker.start()
    try:
        sub = Subscriber(broker, "cmd/#", client_id="restart-sub")  # a persistent session
        wait_subscribed(broker, "cmd/#")
        link = MqttLink(
            MqttSettings(host="127.0.0.1", port=broker.port, client_id="restart-desk")
        ).start()
        assert link.wait_connected(10)
        n = 600
        for i in range(n):
            link.publish("cmd/toggle", {"i": i})
            if i == 200:
                broker.stop()
            if i == 400:
                broker.start()
            if i % 25 == 0:
                time.sleep(0.01)
        assert link.flush(30)
        got = [json.loads(m[2])["i"] for m in sub.wait_for(n, 20)]
        report = link.close()
        sub.stop()
    finally:
        broker.stop()
    assert got == list(range(n))  # every one, once, in order
    assert f"{n} of {n} messages delivered" in report


def test_while_the_broker_is_away_the_oldest_commands_are_dropped_from_a_full_queue(
    mosquitto_available, tmp_path, caplog
):
    broker = Mosquitto(tmp_path)  # not started yet
    settings = MqttSettings(host="127.0.0.1", port=broker.port, client_id="q", queue_size=5)
    with caplog.at_level(logging.WARNING):
        link = MqttLink(settings).start()
        for i in range(8):
            link.publish("cmd/x", str(i))
    assert link.stats.dropped == 3
    assert "the oldest is dropped" in caplog.text
    broker.start()
    try:
        sub = Subscriber(broker, "cmd/#")
        wait_subscribed(broker, "cmd/#")
        assert link.flush(15)
        assert [m[2] for m in sub.wait_for(5)] == ["3", "4", "5", "6", "7"]
        sub.stop()
    finally:
        link.close()
        broker.stop()


def test_commands_not_delivered_are_reported_at_the_end(mosquitto_available, tmp_path):
    broker = Mosquitto(tmp_path)  # never started
    link = MqttLink(MqttSettings(host="127.0.0.1", port=broker.port, client_id="gone")).start()
    link.publish("lamp/set", '{"state": "TOGGLE"}')
    report = link.close(timeout=0.3)
    assert "0 of 1 messages delivered" in report
    assert 'NOT delivered (broker away): lamp/set {"state": "TOGGLE"}' in report


def test_username_and_password_from_a_file_or_the_environment(
    mosquitto_available, tmp_path, monkeypatch, caplog
):
    secret = "correct horse battery"
    broker = Mosquitto(tmp_path, users={"desk": secret})
    broker.start()
    (tmp_path / "mqtt.pw").write_text(secret + "\n")
    monkeypatch.setenv("DESK_PW", secret)
    monkeypatch.setenv("WRONG_PW", "guess")
    try:
        for source in ({"password_file": "mqtt.pw"}, {"password_env": "DESK_PW"}):
            section = load_marked_yaml("l.yaml", json.dumps({"username": "desk", **source}))
            settings = settings_from_layout(
                section, desk="d", url_override=broker.url, relative_to=tmp_path
            )
            assert secret not in repr(settings)
            with caplog.at_level(logging.DEBUG):
                link = MqttLink(settings).start()
                assert link.wait_connected(10)
                link.publish("lamp/set", "ON")
                assert link.flush(10)
                link.close()
            assert secret not in caplog.text
        wrong = settings_from_layout(
            load_marked_yaml("l.yaml", "{username: desk, password_env: WRONG_PW}"),
            desk="d",
            url_override=broker.url,
        )
        with caplog.at_level(logging.WARNING):
            link = MqttLink(wrong).start()
            assert not link.wait_connected(1.0)
            report = link.close(timeout=0.2)
        assert "refused" in caplog.text and "not authori" in caplog.text.lower()
        assert "guess" not in caplog.text
        assert "0 of 0" in report
    finally:
        broker.stop()


@pytest.mark.parametrize(
    ("text", "at", "expected"),
    [
        ("{broker: 'mqtt://u:pw@host'}", "'mqtt", "do not put a password in the broker URL"),
        ("{password_env: NOPE_XYZ}", "NOPE", "the environment variable NOPE_XYZ is not set"),
        ("{password_file: missing.txt}", "missing", "`password_file`: no such file"),
        ("{qos: 5}", "5", "`qos` of `mqtt` must be 0, 1 or 2"),
        ("{brokr: x}", "brokr", "unknown key `brokr`"),
        ("{broker: 'http://host'}", "'http", "mqtt://host[:port] or mqtts://host[:port]"),
        ("{tls: {cert: l.yaml}}", "{cert", "needs both `cert` and `key`"),
        ("{discovery: 'yes'}", "'yes'", "`discovery` of `mqtt` must be false, true"),
        # the fuzzing pass: port 0 connected to 1883, a 1e18 queue was taken, a binary
        # password file was "a plugin crashed ... UnicodeDecodeError"
        ("{broker: 'mqtt://localhost:0'}", "'mqtt", "has port 0; expected 1 to 65535"),
        ("{queue_size: 1.0e+18}", "1.0e", "`queue_size` in `mqtt` must be <= 1e+06"),
        ("{password_file: binary.pw}", "binary", "binary.pw is not text (UTF-8)"),
        # urllib's ValueError had been "an action could not be set up"
        ("{broker: 'mqtt://[::1'}", "'mqtt", "cannot be read: Invalid IPv6 URL"),
    ],
)
def test_mqtt_section_errors_point_at_the_layout(tmp_path, text, at, expected):
    (tmp_path / "binary.pw").write_bytes(b"\xff\xfe\x00secret")
    (tmp_path / "l.yaml").write_text(text)
    with pytest.raises(ConfigError) as err:
        settings_from_layout(load_marked_yaml("l.yaml", text), desk="d", relative_to=tmp_path)
    assert str(err.value).startswith(f"l.yaml:1:{text.index(at) + 1}: "), str(err.value)
    assert expected in str(err.value)


def test_a_bad_mqtt_option_is_named_as_the_option(tmp_path, capsys):
    """`run --mqtt 'mqtt://[::1'` was blamed on the layout's first MQTT action."""
    from hapticdesk.cli import main

    examples = Path(__file__).resolve().parents[2] / "examples"
    argv = ["run", "--layout", str(examples / "layouts" / "demo.yaml"), "--speed", "0"]
    argv += ["--source", f"sim:{examples / 'scenes' / 'demo.yaml'}", "--mqtt", "mqtt://[::1"]
    assert main(argv) == 2
    assert capsys.readouterr().err == (
        "hapticdesk run: error: --mqtt: broker URL 'mqtt://[::1' cannot be read: Invalid IPv6 URL\n"
    )


def test_tls_with_a_ca_and_a_client_certificate(mosquitto_available, tmp_path, caplog):
    tls = make_tls(tmp_path)
    broker = Mosquitto(tmp_path, tls=tls, require_client_cert=True)
    broker.start()
    try:
        client_args = [
            "--cafile",
            str(tls.ca),
            "--cert",
            str(tls.client_cert),
            "--key",
            str(tls.client_key),
        ]
        sub = Subscriber(broker, "lamp/#", extra=client_args)
        wait_subscribed(broker, "lamp/#")
        section = load_marked_yaml(
            "l.yaml",
            json.dumps(
                {
                    "broker": broker.url,
                    "tls": {"ca": "ca.crt", "cert": "client.crt", "key": "client.key"},
                }
            ),
        )
        settings = settings_from_layout(section, desk="d", relative_to=tmp_path)
        assert settings.tls and settings.port == broker.port
        link = MqttLink(settings).start()
        assert link.wait_connected(10)
        link.publish("lamp/set", '{"state": "ON"}')
        assert link.flush(10)
        link.close()
        assert sub.wait_for(1)[0][1:] == ("lamp/set", '{"state": "ON"}')
        sub.stop()
        # without the client certificate the broker refuses the connection
        no_cert = settings_from_layout(
            load_marked_yaml("l.yaml", json.dumps({"broker": broker.url, "tls": {"ca": "ca.crt"}})),
            desk="d",
            relative_to=tmp_path,
        )
        with caplog.at_level(logging.WARNING):
            link = MqttLink(no_cert).start()
            assert not link.wait_connected(1.0)
            link.close(timeout=0.1)
        assert f"cannot connect to {broker.url}" in caplog.text
    finally:
        broker.stop()


def test_home_assistant_discovery_and_availability(broker, subscribe, tmp_path, paper_desk):
    live = subscribe("hapticdesk/#")
    bindings = [
        TOGGLE,
        {"gesture": "double_tap", "region": "lamp", "do": {"log": {}}},
        {"gesture": "long_press", "region": "lamp", "hold_s": 1.0, "do": {"log": {}}},
        {"gesture": "swipe", "direction": ["up", "down"], "do": {"log": {}}},
    ]
    layout = write_layout(tmp_path, bindings, {"discovery": True}, desk_name="study")
    report, events = run_layout(layout, taps_file(tmp_path, paper_desk, 1), broker.url)
    assert report.error is None
    # a new subscriber gets what the broker retained
    # (the event entity, sensors and connectivity: tests/runtime/test_mqtt_homeassistant.py)
    retained = Subscriber(broker, "homeassistant/device_automation/#")
    configs = {m[1]: (m[0], json.loads(m[2])) for m in retained.wait_for(5)}
    retained.stop()
    node = "homeassistant/device_automation/study"
    # (the desk's control buttons are tested with the `set` topic)
    assert {topic for topic in configs if "/device_automation/" in topic} == {
        f"{node}/lamp_tap/config",
        f"{node}/lamp_double_tap/config",
        f"{node}/lamp_long_press/config",
        f"{node}/desk_swipe_up/config",
        f"{node}/desk_swipe_down/config",
    }
    assert all(was_retained for was_retained, _ in configs.values())
    tap = configs[f"{node}/lamp_tap/config"][1]
    assert tap["automation_type"] == "trigger"
    assert tap["type"] == "button_short_press"
    assert tap["subtype"] == "lamp"
    # on the event topic: the trigger's payload_json carries the gesture's data
    assert (tap["topic"], tap["value_template"]) == (
        "hapticdesk/study/event",
        "{{ value_json.action }}",
    )
    assert tap["payload"] == "lamp_tap"
    assert tap["device"]["identifiers"] == ["hapticdesk_study"]
    assert tap["device"]["name"] == "study"
    assert tap["device"]["manufacturer"] == "hapticdesk"
    assert tap["device"]["model"] == "hapticdesk on kitamura2017"
    assert tap["device"]["sw_version"]
    assert configs[f"{node}/lamp_double_tap/config"][1]["type"] == "button_double_press"
    assert configs[f"{node}/lamp_long_press/config"][1]["type"] == "button_long_press"
    assert configs[f"{node}/desk_swipe_up/config"][1]["type"] == "swipe_up"
    assert configs[f"{node}/desk_swipe_up/config"][1]["subtype"] == "desk"
    # the desk's own topics: online, the gesture as an action string and in full, offline
    offline = ("hapticdesk/study/availability", "offline")
    messages = live.wait_until(lambda m: offline in [(t, p) for _, t, p in m])
    by_topic = [(topic, payload) for _, topic, payload in messages]
    assert by_topic[0] == ("hapticdesk/study/availability", "online")
    assert ("hapticdesk/study/action", "lamp_tap") in by_topic
    event = next(json.loads(p) for t, p in by_topic if t == "hapticdesk/study/event")
    assert event == {**events[0], "action": "lamp_tap", "seq": 1}  # the run's count
    assert by_topic[-1] == offline


RUN = [sys.executable, "-m", "hapticdesk", "run", "--speed", "1"]


def test_the_last_will_says_offline_when_the_process_dies(broker, subscribe, tmp_path, paper_desk):
    avail = subscribe("hapticdesk/+/availability")
    layout = write_layout(tmp_path, [TOGGLE], desk_name="study")
    recording = taps_file(tmp_path, paper_desk, 30)
    proc = subprocess.Popen(
        [*RUN, "--layout", str(layout), "--source", f"replay:{recording}", "--mqtt", broker.url],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        assert avail.wait_for(1, 20)[0][1:] == ("hapticdesk/study/availability", "online")
    finally:
        proc.kill()  # no chance to say goodbye: the broker sends the will
        proc.wait()
    assert avail.wait_for(2, 10)[1][1:] == ("hapticdesk/study/availability", "offline")


def test_sigterm_stops_cleanly_and_reports_what_was_not_delivered(
    broker, subscribe, tmp_path, paper_desk
):
    sub = subscribe("lamp/#")
    layout = write_layout(tmp_path, [TOGGLE])
    recording = taps_file(tmp_path, paper_desk, 30, gap_s=0.5)
    proc = subprocess.Popen(
        [
            *RUN,
            "--layout",
            str(layout),
            "--source",
            f"replay:{recording}",
            "--mqtt",
            broker.url,
            "--drain",
            "0.5",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        if len(sub.wait_for(2, 20)) < 2:
            proc.kill()
            pytest.fail(f"no commands arrived; the run said: {proc.communicate()[1]}")
        broker.stop()  # the next commands cannot go anywhere
        time.sleep(1.2)  # two more taps happen meanwhile
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=20)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 3, err  # commands were not delivered: not a success
    assert "error: not everything was delivered" in err.splitlines()[-1]
    assert "stopped by SIGTERM" in err
    [line] = [line for line in err.splitlines() if "NOT delivered (broker away)" in line]
    assert 'lamp/set {"state": "TOGGLE"' in line
    assert "Traceback" not in err


class _Boom(Exception):
    pass


def test_a_failing_and_a_hanging_action_plugin_while_sensing_continues(
    broker, subscribe, tmp_path, paper_desk
):
    sub = subscribe("lamp/#")
    release = threading.Event()

    def explode(options, context):
        def call(event):
            raise _Boom("the coffee machine is on fire")

        return call

    def hang(options, context):
        return lambda event: release.wait(60)

    def register_actions(register):
        register("explode", explode)
        register("hang", hang)

    plugin = SimpleNamespace(register_actions=hookimpl(register_actions))
    bindings = [
        {"gesture": "tap", "region": "lamp", "do": [{"explode": {}}, {"hang": {}}, TOGGLE["do"]]},
    ]
    layout = write_layout(tmp_path, bindings)
    recording = taps_file(tmp_path, paper_desk, 8)
    try:
        report, events = run_layout(
            layout, recording, broker.url, plugins=[("troublemakers", plugin)], action_timeout_s=0.2
        )
    finally:
        release.set()
    assert report.samples == int((1.5 + 8 * 0.6 + 0.5) * paper_desk.sample_rate_hz)  # all sensed
    assert len(events) == 8
    assert len(sub.wait_for(8)) == 8  # the MQTT action did every command
    lanes = report.dispatch.lanes
    [boom] = [s for label, s in lanes.items() if label.endswith("explode")]
    [stuck] = [s for label, s in lanes.items() if label.endswith("hang")]
    assert boom.failed == 8
    assert stuck.timed_out >= 1 and stuck.ok == 0
    assert report.dispatch.totals.failed == 8


def test_a_layout_section_and_the_mqtt_flag_agree(tmp_path):
    section = load_marked_yaml("l.yaml", "{broker: 'mqtt://home:1884', username: desk, qos: 1}")
    s = settings_from_layout(section, desk="study", url_override="mqtt://127.0.0.1:1999")
    assert (s.tls, s.host, s.port, s.username, s.qos, s.client_id) == (
        False,
        "127.0.0.1",
        1999,
        "desk",
        1,
        "hapticdesk-study",
    )
    assert s.url == "mqtt://desk@127.0.0.1:1999"


def test_run_from_the_command_line_end_to_end(broker, subscribe, tmp_path, paper_desk):
    sub = subscribe("lamp/#")
    layout = write_layout(tmp_path, [TOGGLE])
    recording = taps_file(tmp_path, paper_desk, 3)
    events = tmp_path / "events.jsonl"
    done = subprocess.run(
        [sys.executable, "-m", "hapticdesk", "run", "--layout", str(layout),
         "--source", f"replay:{recording}", "--speed", "0", "--mqtt", broker.url,
         "--events", str(events), "--json"],
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    summary = json.loads(done.stdout.splitlines()[-1])
    assert summary["gestures"] == {"tap": 3}
    assert summary["actions"]["ok"] == 6  # 3 commands + 3 times the desk's own topics
    assert len(sub.wait_for(3)) == 3
    assert len(events.read_text().splitlines()) == 3


def test_discovery_is_announced_again_when_home_assistant_comes_back(broker, subscribe):
    sub = subscribe("homeassistant/device_automation/#")
    config = Message("homeassistant/device_automation/d/lamp_tap/config", b"{}", 1, True, False)
    link = MqttLink(
        MqttSettings(host="127.0.0.1", port=broker.port, client_id="ha"),
        birth=[config],
        birth_again_on=("homeassistant/status", b"online"),
    ).start()
    try:
        assert len(sub.wait_for(1)) == 1  # announced on connect
        wait_subscribed(broker, "homeassistant/status")
        subprocess.run(
            [
                _mosquitto_pub(),
                "-p",
                str(broker.port),
                "-t",
                "homeassistant/status",
                "-m",
                "online",
            ],
            check=True,
        )
        assert [m[1] for m in sub.wait_for(2)] == [config.topic] * 2  # and again
    finally:
        link.close()


def _mosquitto_pub() -> str:
    import shutil

    return shutil.which("mosquitto_pub") or "mosquitto_pub"


@pytest.mark.parametrize("name", ["my desk", "desk/1", "desk+"])
def test_a_desk_name_that_cannot_go_into_topics_is_refused(tmp_path, paper_desk, name):
    path = write_layout(tmp_path, [TOGGLE], desk_name=name)
    recording = taps_file(tmp_path, paper_desk, 1)
    with pytest.raises(ConfigError, match=r"layout.yaml:1:\d+: `desk_name` must be letters"):
        build_scene(path, f"replay:{recording}", load_registry(entry_points=False))


def test_the_goodbye_goes_last_at_the_commands_qos(broker, subscribe):
    """A QoS 2 message reaches a subscriber when it is released, a QoS 1 one at once: the
    desk's last event (QoS 2) and a QoS 1 "offline" right after it arrived the wrong way round
    once in a while. The goodbye now goes at the commands' QoS 2, after them; the last will
    (the broker's, on a lost connection) keeps its QoS 1."""
    sub = subscribe("d/#", extra=["-F", "%q %t %p"])  # QoS in place of the retained flag
    will = Message("d/availability", b"offline", 1, True, command=False)
    link = MqttLink(
        MqttSettings(host="127.0.0.1", port=broker.port, client_id="bye"), will=will
    ).start()
    assert link.wait_connected(10)
    for k in range(20):
        link.publish("d/event", {"k": k})
    link.close()
    # (retained, topic, payload) as the subscriber parses them: the first field is the QoS here
    messages = sub.wait_until(lambda got: ("d/availability", "offline") in [g[1:] for g in got])
    lines = [line.split(" ", 2) for line in sub.lines]
    assert len(messages) == 21 and lines[-1] == ["2", "d/availability", "offline"]
    assert [p for _, t, p in lines if t == "d/event"] == [json.dumps({"k": k}) for k in range(20)]


def link_to_nowhere(tmp_path: Path, client_id: str) -> MqttLink:
    """A started link, with a last will, to a broker that is never started, and one command
    queued that can never be delivered."""
    gone = Mosquitto(tmp_path)  # never started: only its free port is used
    link = MqttLink(
        MqttSettings(host="127.0.0.1", port=gone.port, client_id=client_id),
        will=Message("a/availability", b"offline", 1, True, command=False),
    ).start()
    link.publish("lamp/set", "x")
    return link


def test_nothing_is_taken_once_the_link_says_goodbye(mosquitto_available, tmp_path):
    """While close waits for the queue (a broker that is not there), a late publish (a call
    the dispatcher gave up on) is refused: it would follow the desk's "offline"."""
    link = link_to_nowhere(tmp_path, "late")
    closing = threading.Thread(target=link.close, kwargs={"timeout": 1.0})
    closing.start()
    time.sleep(0.2)
    with pytest.raises(RuntimeError, match="closed"):
        link.publish("lamp/set", "late")
    closing.join(5)
    assert link.stats.queued == 1


def test_a_lost_acknowledgement_is_recovered_by_reconnecting(broker, subscribe, monkeypatch):
    """mosquitto drops packets to a client whose queue is full, acknowledgements too (a /set
    flood did it): the message waited in flight for ever, and with the window full every
    gesture after it. Now, unacknowledged for ACK_TIMEOUT_S on a live connection, the link
    reconnects and paho sends it again on the resumed session."""
    from hapticdesk.plugins.mqtt import link as link_module

    monkeypatch.setattr(link_module, "ACK_TIMEOUT_S", 0.5)
    sub = subscribe("lamp/#")
    link = MqttLink(MqttSettings(host="127.0.0.1", port=broker.port, client_id="lost-ack"))
    paho_client, lost = link._client, []
    real_pubrec = paho_client._handle_pubrec  # (paho's own: the ack is lost before paho)

    def lose_the_first():
        if not lost:
            lost.append(True)  # as if the broker's PUBREC never came
            return 0
        return real_pubrec()

    paho_client._handle_pubrec = lose_the_first
    link.start()
    assert link.wait_connected(10)
    link.publish("lamp/set", "first")
    link.publish("lamp/set", "second")
    assert link.flush(10), "the message whose acknowledgement was lost never went again"
    link.close()
    # each once (the resumed session sends it again as a duplicate the broker knows); the
    # second came first, being released before the first's lost acknowledgement was resent
    assert lost and sorted(m[2] for m in sub.wait_for(3, timeout=2)) == ["first", "second"]
    assert link.stats.delivered == 2


def test_a_preview_sends_nothing_to_the_broker(broker, subscribe, tmp_path, paper_desk):
    """`hapticdesk ui` without --actions (build_scene(actions=False)) recognises gestures and
    sends nothing: the MQTT plugin's control channel had said the desk online, announced it
    to Home Assistant and said it offline at the end, as if it were the real desk."""
    everything = subscribe("#")
    layout = write_layout(tmp_path, [TOGGLE], {"discovery": True}, desk_name="study")
    recording = taps_file(tmp_path, paper_desk, 2)
    scene = build_scene(
        layout,
        f"replay:{recording}",
        load_registry(entry_points=False),
        speed=0,
        overrides={"mqtt": {"broker": broker.url}},
        actions=False,
    )
    report = Runtime(scene).run(handle_signals=False)
    assert report.error is None and report.gestures["tap"] == 2
    time.sleep(1.0)  # (what would have come, had anything been sent)
    assert everything.messages() == []
