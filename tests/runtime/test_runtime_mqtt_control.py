"""The desk told things over MQTT, and many desks on one broker, against a real mosquitto.

`hapticdesk run` runs as a process, as it would as a service; mosquitto_pub and mosquitto_sub
are the independent clients."""

from __future__ import annotations

import json
import re
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from hapticdesk.files.recording import write_recording

from .conftest import Mosquitto, Subscriber, _program
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


def wait_until(sub: Subscriber, done: Callable[[Messages], bool], timeout: float = 15) -> Messages:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        messages = sub.messages()
        if done(messages):
            return messages
        time.sleep(0.05)
    raise AssertionError(f"timed out; the broker carried: {sub.messages()}")


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
        [*RUN, "--layout", str(layout), "--source", f"replay:{taps(tmp_path, paper_desk, 16)}"],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        wait_until(sub, lambda m: len(regions(m)) >= 2)
        publish(broker, "hapticdesk/study/set", '{"layout": "evening"}')
        wait_until(sub, lambda m: "fan" in regions(m))
        publish(broker, "hapticdesk/study/set", '{"command": "pause"}')
        paused = wait_until(sub, lambda m: len(results(m)) == 2)
        time.sleep(1.6)  # three taps happen meanwhile
        during = sub.messages()
        publish(broker, "hapticdesk/study/set", "resume")
        wait_until(sub, lambda m: len(regions(m)) > len(regions(during)))
        publish(broker, "hapticdesk/study/set", '{"layout": "attic"}')
        publish(broker, "hapticdesk/study/set", '{"tare": true}')
        retared = wait_until(sub, lambda m: len(results(m)) == 5)
        time.sleep(1.6)
        after_tare = sub.messages()
        publish(broker, "hapticdesk/study/set", "explode")
        wait_until(sub, lambda m: len(results(m)) == 6)
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
        wait_until(availability, lambda m: any(p == "online" for _, _, p in m))
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
    assert [p for _, _, p in availability.messages()] == ["online", "offline"]


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
    from hapticdesk.files.yamlfile import ConfigError
    from hapticdesk.registry import load_registry
    from hapticdesk.runtime.service import load_scene_layout

    layout = write_layout(tmp_path / "l.yaml", "lamp", broker, mqtt=mqtt)
    with pytest.raises(ConfigError, match=re.escape(message)) as err:
        load_scene_layout(layout, load_registry(entry_points=False))
    assert str(err.value).startswith(f"{layout}:11:")
    assert main(["check", str(layout)]) == 2
