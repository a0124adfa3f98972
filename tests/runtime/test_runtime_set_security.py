"""What a client of the broker can do to a desk through `<prefix>/set` (issue 30, items 1 and
10): a pause is bounded and visible on the desk's state topic, and a reload may not add what
reads the environment. Against a real mosquitto where one is installed."""

from __future__ import annotations

import json
import subprocess
import time
from pathlib import Path

import pytest

from hapticdesk.runtime.control import MAX_PAUSE_S, ControlError, parse_command
from hapticdesk.runtime.service import Runtime

from .scripted import answer_into, scripted_run
from .taps import Tap, tap_recording
from .test_runtime_control import write_layout
from .test_runtime_mqtt_control import RUN, publish, results, taps
from .test_runtime_mqtt_control import write_layout as write_mqtt_layout


def _start_desk(layout: Path, tmp_path: Path, paper_desk) -> subprocess.Popen[str]:
    """`hapticdesk run` on ``layout``, a tap every 0.5 s for 20 s, as a service would."""
    recording = taps(tmp_path, paper_desk, 20)
    return subprocess.Popen(
        [*RUN, "--layout", str(layout), "--source", f"replay:{recording}"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )


def test_pause_takes_a_length_within_bounds() -> None:
    """Guards item 10: `pause` takes `for_s` (1 s to MAX_PAUSE_S); other values are refused
    saying what is expected."""
    assert parse_command('{"command": "pause", "for_s": 600}').argument == "600"
    assert parse_command('{"pause": 90}').argument == "90"
    assert parse_command('{"pause": true}').argument is None
    assert parse_command("pause").argument is None
    for bad in ('{"pause": 0}', f'{{"pause": {MAX_PAUSE_S + 1}}}', '{"pause": "soon"}'):
        with pytest.raises(ControlError, match="`pause` takes `for_s`, seconds from 1 to 3600"):
            parse_command(bad)


def test_a_pause_ends_by_itself_after_its_length(tmp_path: Path, paper_desk) -> None:
    """Guards item 10 ("any broker client can pause the desk for ever"): a pause lasts its
    `for_s`, at most MAX_PAUSE_S, then gestures are sent again and the log says so
    (b5a43bd: paused until a `resume`)."""
    path = write_layout(tmp_path / "a.yaml", "lamp")
    recording = tap_recording(paper_desk, [Tap(1.5, 0.0, 0.0), Tap(3.5, 0.0, 0.0)], 4.5)
    answers: list[str] = []

    def pause(runtime: Runtime) -> None:
        runtime.request("pause", "1").add_done_callback(answer_into(answers))

    script = {1.0: pause, 2.5: lambda runtime: time.sleep(1.2)}  # (the pause is wall time)
    runtime, events = scripted_run(path, recording, script, tmp_path / "events.jsonl")
    times = [round(e["t"]) for e in events]
    assert times == [4]  # the tap during the pause is not sent, the one after it is
    assert answers == [
        "paused for 1 s: gestures are recognised but not sent (sensing and the zero go on); "
        "`resume` ends it sooner"
    ]
    assert not runtime.paused


def test_a_paused_desk_says_so_on_its_state_topic(broker, subscribe, tmp_path, paper_desk):
    """Guards item 10 ("a desk paused by `/set` says so on its availability/state"): the
    state JSON on `<prefix>` carries `paused`, published at once when the desk is paused and
    resumed, also without Home Assistant discovery (b5a43bd: nothing said it)."""
    layout = write_mqtt_layout(tmp_path / "day.yaml", "lamp", broker)
    sub = subscribe("hapticdesk/study/#")
    process = _start_desk(layout, tmp_path, paper_desk)

    def states(messages):
        return [json.loads(p) for _, t, p in messages if t == "hapticdesk/study"]

    try:
        sub.wait_until(lambda m: any(t == "hapticdesk/study/event" for _, t, _ in m))
        publish(broker, "hapticdesk/study/set", '{"command": "pause", "for_s": 600}')
        sub.wait_until(lambda m: any(s.get("paused") is True for s in states(m)))
        publish(broker, "hapticdesk/study/set", "resume")
        sub.wait_until(
            lambda m: any(s.get("paused") is False and "action" not in s for s in states(m))
        )
        process.terminate()
        _, err = process.communicate(timeout=20)
    finally:
        if process.poll() is None:
            process.kill()
    flags = [s["paused"] for s in states(sub.messages()) if "action" not in s]
    assert flags == [True, False]
    assert [a["ok"] for a in results(sub.messages())] == [True, True]
    assert "Traceback" not in err


def test_a_reload_over_mqtt_may_not_add_what_reads_the_environment(
    broker, subscribe, tmp_path, paper_desk
):
    """Guards item 1 for MQTT `reload`: the answer on `set/result` says why it was refused,
    the desk goes on with its layout (b5a43bd: reloaded; taps then sent the variable)."""
    layout = write_mqtt_layout(tmp_path / "day.yaml", "lamp", broker)
    sub = subscribe("hapticdesk/study/#")
    process = _start_desk(layout, tmp_path, paper_desk)
    try:
        sub.wait_until(lambda m: any(t == "hapticdesk/study/event" for _, t, _ in m))
        text = (
            write_mqtt_layout(layout, "fan", broker)
            .read_text()
            .replace(
                "    do: {log: {}}\n",
                "    do: [{log: {}}, {http: {url: 'http://127.0.0.1:9/x', headers: "
                "{Authorization: {env: HOME}}}}]\n",
            )
        )
        layout.write_text(text)
        publish(broker, "hapticdesk/study/set", "reload")
        answer = sub.wait_until(lambda m: len(results(m)) == 1)
        time.sleep(1.2)
        process.terminate()
        _, err = process.communicate(timeout=20)
    finally:
        if process.poll() is None:
            process.kill()
    [said] = results(answer)
    assert said["ok"] is False and said["command"] == "reload"
    assert "`http` reads the environment variable HOME: a reload" in said["message"]
    regions = {
        json.loads(p)["region"] for _, t, p in sub.messages() if t == "hapticdesk/study/event"
    }
    assert regions == {"lamp"}
    assert "Traceback" not in err
