"""Faults while running (issue 11, "Hardening"): a broker that is down or refuses the login,
the ``--mqtt`` flag against a TLS layout, and announcements that must not pile up."""

from __future__ import annotations

import logging
import subprocess
import sys
import threading
import time
from types import SimpleNamespace

import pytest

from hapticdesk.errors import ConfigError
from hapticdesk.files.recording_io import write_recording
from hapticdesk.files.yamlfile import load_marked_yaml
from hapticdesk.plugin_loading import load_registry
from hapticdesk.plugins.mqtt import link_for
from hapticdesk.plugins.mqtt.link import MqttLink
from hapticdesk.plugins.mqtt.message import Message
from hapticdesk.plugins.mqtt.settings import MqttSettings, settings_from_layout
from hapticdesk.runtime.assembly import build_scene
from hapticdesk.runtime.service import Runtime

from .conftest import Mosquitto, Subscriber, wait_subscribed
from .taps import tap_recording
from .test_runtime_mqtt import TOGGLE, link_to_nowhere, taps_file, write_layout

RUN = [sys.executable, "-m", "hapticdesk", "run"]


def test_a_broker_back_after_an_outage_is_used_within_a_second(
    mosquitto_available, tmp_path, paper_desk
):
    """The broker is down when the run starts and comes back after ~1.5 s (issue item 8)."""
    broker = Mosquitto(tmp_path)  # not started: the run begins during the outage
    layout = write_layout(tmp_path, [TOGGLE])
    # 5 s of a quiet desk at real speed: the commands below are all sent during the outage,
    # as in the run, so nothing published later can wake the back-off
    recording = tmp_path / "quiet.npz"
    write_recording(recording, tap_recording(paper_desk, [], 5.0))
    scene = build_scene(
        layout,
        f"replay:{recording}",
        load_registry(entry_points=False),
        speed=1.0,
        overrides={"mqtt": {"broker": broker.url}},
    )
    runtime = Runtime(scene)
    done: list[object] = []
    runner = threading.Thread(target=lambda: done.append(runtime.run(handle_signals=False)))
    runner.start()
    link = link_for(scene.context)  # the run's one connection, which the actions use
    try:
        assert isinstance(link, MqttLink)
        started = time.monotonic()
        for i in range(360):  # commands during the outage (the run had 360)
            link.publish("lamp/early", str(i))
            time.sleep(0.004)
        time.sleep(max(0.0, 1.5 - (time.monotonic() - started)))
        broker.start()  # returns once the broker accepts connections
        back = time.monotonic()
        while not link.connected and time.monotonic() - back < 10:
            time.sleep(0.005)
        reconnect_s = time.monotonic() - back
        print(f"connected {reconnect_s:.3f} s after the broker accepted connections")
        assert link.connected
        assert reconnect_s < 1.0
        runner.join(30)
        [report] = done
        assert report.notes == [f"MQTT {broker.url}: 360 of 360 messages delivered"]
        assert scene.context.failures == []
    finally:
        runtime.stop()
        runner.join(10)
        broker.stop()


def test_a_refused_login_is_a_clear_error_and_the_run_exits_non_zero(
    mosquitto_available, tmp_path, paper_desk, monkeypatch
):
    broker = Mosquitto(tmp_path, users={"desk": "right"})
    broker.start()
    try:
        monkeypatch.setenv("DESK_PW", "wrong")
        layout = write_layout(
            tmp_path, [TOGGLE], mqtt={"username": "desk", "password_env": "DESK_PW"}
        )
        recording = taps_file(tmp_path, paper_desk, 2)
        started = time.monotonic()
        done = subprocess.run(
            [*RUN, "--layout", str(layout), "--source", f"replay:{recording}", "--speed", "0",
             "--mqtt", broker.url, "--drain", "3"],
            capture_output=True, text=True, timeout=60,
        )  # fmt: skip
        took = time.monotonic() - started
    finally:
        broker.stop()
    assert done.returncode == 3, done.stderr
    err = done.stderr
    assert "refused the login" in err and "broker away" not in err
    assert "check `username` and the password" in err
    assert "error: not everything was delivered" in err.splitlines()[-1]
    assert "wrong" not in err  # the password itself is never shown
    assert "Traceback" not in err
    assert took < 20  # it did not wait out the drain retrying the same password


def test_a_run_whose_commands_were_all_delivered_exits_zero(broker, tmp_path, paper_desk):
    layout = write_layout(tmp_path, [TOGGLE])
    recording = taps_file(tmp_path, paper_desk, 2)
    done = subprocess.run(
        [*RUN, "--layout", str(layout), "--source", f"replay:{recording}", "--speed", "0",
         "--mqtt", broker.url],
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert "not everything was delivered" not in done.stderr


@pytest.mark.parametrize(
    "section",
    [
        "{broker: 'mqtts://home:8883', username: desk}",
        "{broker: 'mqtt://home:1883', tls: {ca: ca.crt}}",
    ],
)
def test_the_mqtt_flag_never_downgrades_a_tls_layout_to_plain_mqtt(tmp_path, section):
    (tmp_path / "ca.crt").write_text("x")
    m = load_marked_yaml(str(tmp_path / "layout.yaml"), section)
    with pytest.raises(ConfigError, match=r"plain MQTT but the layout.*uses TLS; give an mqtts"):
        settings_from_layout(
            m, desk="d", url_override="mqtt://127.0.0.1:1883", relative_to=tmp_path
        )


def test_the_mqtt_flag_with_mqtts_keeps_the_layout_tls_files(tmp_path):
    (tmp_path / "ca.crt").write_text("x")
    m = load_marked_yaml(str(tmp_path / "l.yaml"), "{broker: 'mqtt://home', tls: {ca: ca.crt}}")
    s = settings_from_layout(
        m, desk="d", url_override="mqtts://127.0.0.1:8884", relative_to=tmp_path
    )
    assert (s.tls, s.host, s.port, s.ca) == (True, "127.0.0.1", 8884, tmp_path / "ca.crt")


def test_the_mqtt_flag_downgrade_is_refused_on_the_command_line(tmp_path, paper_desk):
    (tmp_path / "ca.crt").write_text("x")
    layout = write_layout(tmp_path, [TOGGLE], mqtt={"tls": {"ca": "ca.crt"}})
    recording = taps_file(tmp_path, paper_desk, 1)
    done = subprocess.run(
        [*RUN, "--layout", str(layout), "--source", f"replay:{recording}", "--speed", "0",
         "--mqtt", "mqtt://127.0.0.1:1"],
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert done.returncode == 2
    assert "uses TLS; give an mqtts:// URL" in done.stderr
    assert "Traceback" not in done.stderr


def test_home_assistant_coming_online_again_and_again_does_not_pile_up_announcements():
    birth = [Message(f"ha/t{i}/config", b"{}", 1, True, command=False) for i in range(3)]
    link = MqttLink(
        MqttSettings(host="127.0.0.1", port=1),
        birth=birth,
        birth_again_on=("homeassistant/status", b"online"),
    )  # not started: nothing takes the announcements off the queue
    online = SimpleNamespace(topic="homeassistant/status", payload=b"online")
    for _ in range(1000):
        link._on_message(None, None, online)
    assert list(link._control) == birth  # coalesced: each announcement once, the newest


def test_announcements_again_are_sent_once_each_on_a_live_broker(broker):
    sub = Subscriber(broker, "ha/#")
    wait_subscribed(broker, "ha/#")
    birth = [Message(f"ha/t{i}/config", b"{}", 1, True, command=False) for i in range(3)]
    link = MqttLink(
        MqttSettings(host="127.0.0.1", port=broker.port, client_id="ha-again"),
        birth=birth,
        birth_again_on=("homeassistant/status", b"online"),
    ).start()
    try:
        assert link.wait_connected(10)
        assert len(sub.wait_for(3)) == 3
        online = SimpleNamespace(topic="homeassistant/status", payload=b"online")
        with link._cond:  # a burst arrives before the sender gets a turn
            for _ in range(500):
                link._on_message(None, None, online)
        assert link.flush(10)
        sub.wait_until(lambda m: len(m) >= 6)
        time.sleep(0.3)  # (and no more come)
        assert len(sub.messages()) == 6  # the three again, once each
    finally:
        link.close()
        sub.stop()


def test_closing_a_link_is_bounded_by_its_timeout(mosquitto_available, tmp_path, caplog):
    link = link_to_nowhere(tmp_path, "gone")
    started = time.monotonic()
    with caplog.at_level(logging.WARNING):
        line = link.close(timeout=0.3)
    assert time.monotonic() - started < 0.8
    assert "NOT delivered" in line
    assert link.failure == f"1 MQTT command(s) not delivered to {link.settings.url}"


@pytest.mark.parametrize("speed", [float("nan"), 1e-300, float("inf")])
def test_a_replay_speed_no_one_asks_for_is_refused(speed):
    """The fuzzing pass: --speed 1e-300 overflowed the pacer's wait in the sensing thread
    (a traceback), NaN acted as 0 (as fast as possible)."""
    from hapticdesk.runtime.pacing import Pacer

    with pytest.raises(ConfigError, match="--speed: must be 0"):
        Pacer(speed, threading.Event())
