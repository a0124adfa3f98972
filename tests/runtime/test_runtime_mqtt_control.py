"""The desk told things over MQTT, and many desks on one broker, against a real mosquitto.

`hapticdesk run` runs as a process, as it would as a service; mosquitto_pub and mosquitto_sub
are the independent clients."""

from __future__ import annotations

import contextlib
import json
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest

from hapticdesk.files.recording_io import write_recording

from .conftest import Mosquitto, Subscriber, _program, wait_subscribed
from .taps import Tap, tap_recording

LAYOUT = """\
desk: kitamura2017
desk_name: study
units: cm
%s
regions:
  %s: {rect: [-10, -10, 10, 10]}
bindings:
  - gesture: tap
    region: %s
    do: {log: {}}
mqtt: {broker: "%s"%s}
"""
RUN = [sys.executable, "-m", "hapticdesk", "run", "--speed", "1"]
Messages = list[tuple[bool, str, str]]


def write_layout(path: Path, region: str, broker: Mosquitto, extra="", mqtt="") -> Path:
    path.write_text(LAYOUT % (extra, region, region, broker.url, mqtt))
    return path


def taps(folder: Path, profile, until_s: float, gap_s: float = 0.5) -> Path:
    count = int((until_s - 1.5) / gap_s)
    path = folder / "taps.npz"
    recording = tap_recording(
        profile, [Tap(1.5 + k * gap_s, 0.0, 0.0) for k in range(count)], until_s + 0.5
    )
    write_recording(path, recording)
    return path


def publish(broker: Mosquitto, topic: str, payload: str) -> None:
    subprocess.run(
        [_program("mosquitto_pub") or "mosquitto_pub", "-h", "127.0.0.1", "-p",
         str(broker.port), "-t", topic, "-m", payload, "-q", "1"],
        check=True, timeout=10,
    )  # fmt: skip


def regions(messages: Messages) -> list[str]:
    return [json.loads(p)["region"] for _, t, p in messages if t == "hapticdesk/study/event"]


def results(messages: Messages) -> list[dict]:
    return [json.loads(p) for _, t, p in messages if t == "hapticdesk/study/set/result"]


def test_set_commands_switch_layouts_pause_and_retare_a_running_desk(
    broker, subscribe, tmp_path, paper_desk
):
    write_layout(tmp_path / "evening.yaml", "fan", broker)
    layout = write_layout(
        tmp_path / "day.yaml", "lamp", broker, extra="layouts: {evening: evening.yaml}"
    )
    sub = subscribe("hapticdesk/study/#")
    process = subprocess.Popen(
        [*RUN, "--layout", str(layout), "--source", f"replay:{taps(tmp_path, paper_desk, 40)}"],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        sub.wait_until(lambda m: len(regions(m)) >= 2)
        publish(broker, "hapticdesk/study/set", '{"layout": "evening"}')
        sub.wait_until(lambda m: "fan" in regions(m))
        publish(broker, "hapticdesk/study/set", '{"command": "pause"}')
        paused = sub.wait_until(lambda m: len(results(m)) == 2)
        time.sleep(1.6)  # three taps happen meanwhile
        during = sub.messages()
        publish(broker, "hapticdesk/study/set", "resume")
        sub.wait_until(lambda m: len(regions(m)) > len(regions(during)))
        publish(broker, "hapticdesk/study/set", '{"layout": "attic"}')
        publish(broker, "hapticdesk/study/set", '{"tare": true}')
        retared = sub.wait_until(lambda m: len(results(m)) == 5)
        time.sleep(1.6)
        after_tare = sub.messages()
        publish(broker, "hapticdesk/study/set", "explode")
        sub.wait_until(lambda m: len(results(m)) == 6)
        process.terminate()
        _, err = process.communicate(timeout=20)
    finally:
        if process.poll() is None:
            process.kill()
    answers = results(sub.messages())
    assert [(a["command"], a["ok"]) for a in answers] == [
        ("layout evening", True),
        ("pause", True),
        ("resume", True),
        ("layout attic", False),
        ("tare", True),
        (None, False),
    ]
    assert "no layout named 'attic'; known: default, evening" in answers[3]["message"]
    assert "unknown command 'explode'" in answers[5]["message"]
    seen = regions(sub.messages())
    switch = seen.index("fan")
    assert switch >= 2 and set(seen[:switch]) == {"lamp"} and set(seen[switch:]) == {"fan"}
    # paused: no gesture went out while taps went on; after resume they did again
    assert regions(during) == regions(paused)
    # a re-tare needs a still second; taps every 0.5 s keep it from finishing: no gestures
    assert regions(after_tare) == regions(retared)
    assert "control: re-taring" in err and "Traceback" not in err


def test_a_second_desk_with_the_same_name_is_refused(broker, subscribe, tmp_path, paper_desk):
    layout = write_layout(tmp_path / "day.yaml", "lamp", broker)
    recording = taps(tmp_path, paper_desk, 10)
    availability = subscribe("hapticdesk/study/availability")
    first = subprocess.Popen(
        [*RUN, "--layout", str(layout), "--source", f"replay:{recording}"],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        availability.wait_until(lambda m: any(p == "online" for _, _, p in m))
        second = subprocess.run(
            [*RUN, "--layout", str(layout), "--source", f"replay:{recording}"],
            capture_output=True, text=True, timeout=30,
        )  # fmt: skip
        assert first.poll() is None  # the first desk was not pushed off the broker
        first.terminate()
        _, first_err = first.communicate(timeout=20)
    finally:
        if first.poll() is None:
            first.kill()
    assert second.returncode == 2
    assert "another desk named `study` is online at mqtt://127.0.0.1:" in second.stderr
    assert "give this desk its own name (`desk_name:`" in second.stderr
    assert (
        f"mosquitto_pub -h 127.0.0.1 -p {broker.port} -r -n -t hapticdesk/study/availability"
        in (second.stderr)
    )
    assert "Traceback" not in second.stderr
    # the first desk kept its session: connected once, never lost
    assert "lost the connection" not in first_err
    # (the first desk's "offline" may reach the subscriber a moment after it exits)
    got = availability.wait_until(lambda m: [p for _, _, p in m][-1:] == ["offline"])
    assert [p for _, _, p in got] == ["online", "offline"]


def test_desks_on_one_broker_under_site_and_floor_prefixes(broker, subscribe, tmp_path, paper_desk):
    recording = taps(tmp_path, paper_desk, 3, gap_s=0.6)
    sub = subscribe("hapticdesk/+/+/+/event")
    runs = []
    for floor in ("floor1", "floor2"):
        folder = tmp_path / floor
        folder.mkdir()
        layout = write_layout(
            folder / "l.yaml", "lamp", broker, mqtt=f", prefix: hapticdesk/site1/{floor}/study"
        )
        runs.append(
            subprocess.Popen(
                [*RUN, "--layout", str(layout), "--source", f"replay:{recording}"],
                stderr=subprocess.PIPE,
                stdout=subprocess.DEVNULL,
                text=True,
            )  # fmt: skip
        )
    errors = [run.communicate(timeout=30)[1] for run in runs]
    assert [run.returncode for run in runs] == [0, 0], errors
    # each desk has its own client id, so neither pushed the other off the broker
    log = broker.log_text()
    assert "as hapticdesk-site1-floor1-study" in log and "as hapticdesk-site1-floor2-study" in log
    assert not any("lost the connection" in e for e in errors)
    topics = sorted(t for _, t, _ in sub.wait_for(4))
    assert (
        topics
        == ["hapticdesk/site1/floor1/study/event"] * 2 + ["hapticdesk/site1/floor2/study/event"] * 2
    )


@pytest.mark.parametrize(
    ("mqtt", "message"),
    [
        (", prefix: a/#", "`prefix` must be a topic without + or #"),
        (", prefix: a/b, base_topic: c", "give `prefix`"),
    ],
)
def test_bad_prefixes_are_refused_where_they_stand(broker, tmp_path, mqtt, message):
    from hapticdesk.cli import main
    from hapticdesk.errors import ConfigError
    from hapticdesk.plugin_loading import load_registry
    from hapticdesk.runtime.assembly import load_scene_layout

    layout = write_layout(tmp_path / "l.yaml", "lamp", broker, mqtt=mqtt)
    with pytest.raises(ConfigError, match=re.escape(message)) as err:
        load_scene_layout(layout, load_registry(entry_points=False))
    assert str(err.value).startswith(f"{layout}:11:")
    assert main(["check", str(layout)]) == 2


# --- MQTT 5 -----------------------------------------------------------------------------------


def link_settings(broker: Mosquitto, client_id: str, **options):
    from hapticdesk.files.yamlfile import load_marked_yaml
    from hapticdesk.plugins.mqtt.settings import settings_from_layout

    section = {"broker": broker.url, "client_id": client_id, **options}
    return settings_from_layout(load_marked_yaml("l.yaml", json.dumps(section)), desk="d")


def test_a_command_the_broker_holds_too_long_expires(broker, tmp_path):
    """MQTT 5 message expiry: a TOGGLE kept for a subscriber that is away is dropped after
    ``expiry_s``; with ``expiry_s: 0`` it waits as long as the subscriber's session."""
    import paho.mqtt.client as mqtt

    from hapticdesk.plugins.mqtt.link import MqttLink

    def lamp(*extra: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            [_program("mosquitto_sub") or "mosquitto_sub", "-h", "127.0.0.1", "-p",
             str(broker.port), "-t", "lamp/set", "-q", "1", "-V", "mqttv5", "-i", "lamp",
             "-c", "-x", "3600", *extra],
            capture_output=True, text=True, timeout=20,
        )  # fmt: skip

    lamp("-E")  # subscribe, then go away: the broker keeps the session and queues for it
    sent = []
    for expiry_s, payload in ((1, "stale"), (0, "kept")):
        link = MqttLink(link_settings(broker, f"desk{expiry_s}", expiry_s=expiry_s)).start()
        assert link.wait_connected(10)
        assert link.protocol == mqtt.MQTTv5
        link.publish("lamp/set", payload, qos=1)
        assert link.flush(10)
        link.close()
        sent.append(payload)
    time.sleep(2.0)  # the lamp comes back after the first command's expiry
    back = lamp("-W", "2")
    assert back.stdout.split() == ["kept"]


def test_a_broker_that_does_not_speak_mqtt5_gets_311(broker, subscribe, caplog):
    import logging
    import socket
    import threading

    import paho.mqtt.client as mqtt

    from hapticdesk.plugins.mqtt.link import MqttLink

    server = socket.create_server(("127.0.0.1", 0))
    port = server.getsockname()[1]
    protocols: list[int] = []

    def pipe(a: socket.socket, b: socket.socket) -> None:
        with contextlib.suppress(OSError):
            while data := a.recv(65536):
                b.sendall(data)
        with contextlib.suppress(OSError):
            b.shutdown(socket.SHUT_WR)

    def serve() -> None:  # a 3.1.1-only broker: CONNACK 1 to MQTT 5, mosquitto behind it
        while True:
            try:
                client, _ = server.accept()
            except OSError:
                return
            first = client.recv(65536)
            protocols.append(first[8])  # the CONNECT's protocol level (short packet)
            if first[8] == 5:
                client.sendall(b"\x20\x02\x00\x01")
                client.close()
                continue
            upstream = socket.create_connection(("127.0.0.1", broker.port))
            upstream.sendall(first)
            threading.Thread(target=pipe, args=(client, upstream), daemon=True).start()
            threading.Thread(target=pipe, args=(upstream, client), daemon=True).start()

    accepting = threading.Thread(target=serve, daemon=True)
    accepting.start()
    sub = subscribe("lamp/#")
    settings = link_settings(broker, "old-broker")
    settings = type(settings)(**{**settings.__dict__, "port": port})
    try:
        with caplog.at_level(logging.WARNING):
            link = MqttLink(settings).start()
            assert link.wait_connected(10)
            link.publish("lamp/set", "ON")
            assert link.flush(10)
            link.close()
    finally:
        with contextlib.suppress(OSError):  # (wakes the accept: a close alone does not)
            server.shutdown(socket.SHUT_RDWR)
        server.close()
    accepting.join(5.0)
    assert not accepting.is_alive()
    assert link.protocol == mqtt.MQTTv311
    assert protocols[:2] == [5, 4]  # asked in MQTT 5, then in 3.1.1
    assert "does not speak MQTT 5" in caplog.text
    assert sub.wait_for(1)[0][1:] == ("lamp/set", "ON")


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"protocol": "4"}, 'must be auto, 5 or "3.1.1"'),
        ({"expiry_s": -1}, "expiry_s"),
    ],
)
def test_bad_protocol_options_are_refused(broker, options, message):
    from hapticdesk.errors import ConfigError

    with pytest.raises(ConfigError, match=re.escape(message)):
        link_settings(broker, "x", **options)


def test_a_program_that_knows_its_broker_sets_the_protocol_over_the_layout(tmp_path):
    """The demo starts a broker that speaks MQTT 3.1.1 only: its desk asks in 3.1.1 from the
    start, whatever the layout says (no MQTT 5 refused, no warning to hide)."""
    from hapticdesk.files.yamlfile import load_marked_yaml
    from hapticdesk.plugins.mqtt.settings import settings_from_layout

    layout = tmp_path / "layout.yaml"
    layout.write_text('mqtt:\n  broker: mqtt://127.0.0.1:1883\n  protocol: "5"\n')
    section = load_marked_yaml(layout)["mqtt"]
    assert settings_from_layout(section, desk="d").protocol == "5"
    told = settings_from_layout(section, desk="d", protocol_override="3.1.1")
    assert told.protocol == "3.1.1"
    with pytest.raises(ValueError, match="protocol override"):
        settings_from_layout(section, desk="d", protocol_override="4")


# --- the fleet examples -----------------------------------------------------------------------

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def test_shared_consumers_split_the_fleet(broker, tmp_path):
    """examples/fleet: two consumers in one `$share` group get every event once between them."""
    consumers = [
        subprocess.Popen(
            [
                sys.executable,
                str(EXAMPLES / "fleet" / "fleet_consumer.py"),
                "--broker",
                broker.url,
                "--group",
                "fleet",
                "--client-id",
                f"consumer{k}",
            ],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )  # fmt: skip
        for k in range(2)
    ]
    try:
        for k, consumer in enumerate(consumers):
            assert consumer.stderr is not None
            assert consumer.stderr.readline().startswith("subscribed to $share/fleet/"), k
        for n in range(20):
            floor = n % 2 + 1
            publish(broker, f"hapticdesk/site1/floor{floor}/study/event", json.dumps({"n": n}))
        time.sleep(1.0)
    finally:
        for consumer in consumers:
            consumer.terminate()
    outputs = [consumer.communicate(timeout=10)[0].splitlines() for consumer in consumers]
    got = [[json.loads(line) for line in lines] for lines in outputs]
    numbers = sorted(row["event"]["n"] for rows in got for row in rows)
    assert numbers == list(range(20))  # every event once, none twice
    assert all(rows for rows in got)  # both took a share
    desks = {row["desk"] for rows in got for row in rows}
    assert desks == {"hapticdesk/site1/floor1/study", "hapticdesk/site1/floor2/study"}


def test_the_acl_example_keeps_each_desk_to_its_own_prefix(mosquitto_available, tmp_path):
    users = {"site1-floor2-study": "s3cret", "fleet": "f1eet"}
    broker = Mosquitto(tmp_path, users=users)
    with broker.config.open("a") as config:
        config.write(f"acl_file {EXAMPLES / 'fleet' / 'mosquitto-acl.conf'}\n")
    broker.start()
    try:
        sub = Subscriber(broker, "hapticdesk/#", extra=["-u", "fleet", "-P", "f1eet"])
        wait_subscribed(broker, "hapticdesk/#")  # (a fixed sleep could miss the one message)

        def desk_publishes(topic: str) -> None:
            subprocess.run(
                [_program("mosquitto_pub") or "mosquitto_pub", "-h", "127.0.0.1", "-p",
                 str(broker.port), "-u", "site1-floor2-study", "-P", "s3cret", "-t", topic,
                 "-m", "x", "-q", "1"],
                check=True, timeout=10,
            )  # fmt: skip

        desk_publishes("hapticdesk/site1/floor1/lab/event")  # another desk's: refused
        desk_publishes("hapticdesk/site1/floor2/study/event")  # its own
        messages = sub.wait_for(1, 5)
        time.sleep(0.3)
        sub.stop()
    finally:
        broker.stop()
    assert [topic for _, topic, _ in sub.messages()] == ["hapticdesk/site1/floor2/study/event"]
    assert messages


def test_the_systemd_unit_reloads_with_sighup_and_does_not_retry_a_refusal():
    unit = (EXAMPLES / "systemd" / "hapticdesk@.service").read_text()
    assert "ExecReload=/bin/kill -HUP $MAINPID" in unit
    assert "RestartPreventExitStatus=2" in unit  # a bad layout or a desk already online
    assert "--layout /etc/hapticdesk/%i/layout.yaml" in unit


def test_answers_queued_together_all_arrive(broker, subscribe):
    """Two answers on set/result queued before the sender runs are both sent (availability
    announcements are coalesced by topic; answers must not be: each says something)."""
    from hapticdesk.plugins.mqtt.link import MqttLink

    sub = subscribe("hapticdesk/study/set/result")
    link = MqttLink(link_settings(broker, "answers"))
    link.announce("hapticdesk/study/set/result", {"command": "layout attic", "ok": False})
    link.announce("hapticdesk/study/set/result", {"command": "tare", "ok": True})
    link.start()
    assert link.wait_connected(10) and link.flush(10)
    link.close()
    answers = [json.loads(p)["command"] for _, _, p in sub.wait_for(2, 5)]
    assert answers == ["layout attic", "tare"]
