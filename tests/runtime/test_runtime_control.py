"""Telling a running desk things: tare, pause/resume, reload and layout switches, SIGHUP.

The commands are requested from inside the source, on the sensing thread, at chosen sample
times, so what each one does to the gesture stream is exact and needs no sleeping."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from hapticdesk.errors import ConfigError
from hapticdesk.files.recording import Recording
from hapticdesk.files.recording_io import write_recording
from hapticdesk.hookspecs import hookimpl
from hapticdesk.plugin_loading import load_registry
from hapticdesk.runtime.assembly import build_scene
from hapticdesk.runtime.control import ControlError, command, parse_command
from hapticdesk.runtime.service import Runtime
from hapticdesk.runtime.source import Source, WrenchBlock

from .taps import Tap, tap_recording

LAYOUT = """\
desk: kitamura2017
units: cm
%s
regions:
  %s: {rect: [-35, -22, 35, 22]}
bindings:
  - gesture: tap
    region: %s
    do: {log: {}}
"""
BLOCK = 60  # samples: 50 ms at 1200 Hz


def write_layout(path: Path, region: str, extra: str = "") -> Path:
    path.write_text(LAYOUT % (extra, region, region))
    return path


class ScriptedSource(Source):
    """A recording in blocks; ``script`` maps a sample time to a call made (on the sensing
    thread) just before the first block at or after it."""

    def __init__(self, recording: Recording, script: dict[float, Callable[[], None]]):
        super().__init__(recording.sensor_names, 1200.0)
        self.recording = recording
        self.script = dict(sorted(script.items()))
        self.start = 0

    def read_block(self) -> WrenchBlock | None:
        rec, start = self.recording, self.start
        if start >= len(rec):
            return None
        t0 = float(rec.t[start])
        for when in [w for w in self.script if w <= t0]:
            self.script.pop(when)()
        self.start += BLOCK
        return WrenchBlock(rec.t[start : start + BLOCK], rec.wrench[start : start + BLOCK])


@pytest.fixture
def run_scripted(tmp_path, paper_desk):
    """``run_scripted(taps, duration_s, script, layout)`` -> (runtime, events) after the run;
    ``script`` maps a sample time to ``f(runtime)``."""

    def run(
        taps: list[Tap], duration_s: float, script: dict[float, Callable[[Runtime], None]], layout
    ):
        recording = tap_recording(paper_desk, taps, duration_s)
        holder: dict[str, Runtime] = {}
        source = ScriptedSource(
            recording, {t: (lambda f=f: f(holder["rt"])) for t, f in script.items()}
        )

        def register_sources(register):
            register("scripted", lambda argument, profile, **o: source)

        plugin = SimpleNamespace(register_sources=hookimpl(register_sources))
        registry = load_registry(entry_points=False, plugins=[("scripted", plugin)])
        scene = build_scene(layout, "scripted:", registry, speed=0)
        events_path = tmp_path / "events.jsonl"
        runtime = holder["rt"] = Runtime(scene, events_path=events_path)
        report = runtime.run(handle_signals=False)
        assert report.error is None
        events = [json.loads(line) for line in events_path.read_text().splitlines()]
        return runtime, events

    return run


TAPS = [Tap(1.5, 0.0, 0.0), Tap(2.5, 0.1, 0.0), Tap(3.5, -0.1, 0.05), Tap(4.5, 0.05, -0.05)]


def test_without_commands_every_tap_is_sent(tmp_path, run_scripted):
    _, events = run_scripted(TAPS, 5.0, {}, write_layout(tmp_path / "a.yaml", "lamp"))
    assert [round(e["t"]) for e in events] == [2, 3, 4, 5]


def test_pause_holds_gestures_back_and_resume_sends_them_again(tmp_path, run_scripted):
    results = []

    def ask(name):
        return lambda rt: rt.request(name).add_done_callback(lambda f: results.append(f.result()))

    runtime, events = run_scripted(
        TAPS,
        5.0,
        {2.2: ask("pause"), 4.0: ask("resume")},
        write_layout(tmp_path / "a.yaml", "lamp"),
    )
    assert [round(e["x"], 2) for e in events] == [0.0, 0.05]  # taps 2 and 3 not sent
    assert runtime.report.gestures == {"tap": 2}
    assert results[0].startswith("paused") and results[1].startswith("resumed")
    assert runtime.scene.estimator.tared  # sensing went on


def test_tare_takes_the_zero_again_and_taps_during_it_are_not_reported(tmp_path, run_scripted):
    zero_t = {}

    def tare(rt):
        zero_t["before"] = rt.scene.estimator.zeroing.state.zero_t
        rt.request("tare")

    taps = [Tap(1.5, 0.0, 0.0), Tap(2.5, 0.1, 0.0), Tap(4.5, -0.1, 0.05), Tap(5.0, 0.05, -0.05)]
    layout = write_layout(tmp_path / "a.yaml", "lamp")
    runtime, events = run_scripted(taps, 5.5, {2.2: tare}, layout)
    # the tap at 2.5 s falls in the first second of the new tare, which is refused (not
    # still) and taken in the next quiet second, 3.2 to 4.2 s; taps after it are seen
    assert [round(e["x"], 2) for e in events] == [0.0, -0.1, 0.05]
    assert zero_t["before"] < 1.5
    assert runtime.scene.estimator.zeroing.state.zero_t == pytest.approx(4.2, abs=0.01)
    assert runtime.scene.estimator.tared


def test_reload_keeps_the_zero_and_uses_the_new_layout_at_once(tmp_path, run_scripted):
    path = write_layout(tmp_path / "a.yaml", "lamp")
    seen = {}

    def reload(rt):
        seen["estimator"] = rt.scene.estimator
        seen["zero"] = rt.scene.estimator.zero
        write_layout(path, "fan")  # as the browser UI saves it
        future = rt.request("reload")
        # runs on the sensing thread right after the swap, before another block
        future.add_done_callback(
            lambda f: seen.update(after=rt.scene.estimator.zero, line=f.result())
        )

    runtime, events = run_scripted(TAPS, 5.0, {2.3: reload}, path)
    assert [e["region"] for e in events] == ["lamp", "fan", "fan", "fan"]
    # the tap 0.2 s after the reload is found: no new tare (it would take 1 s)
    assert events[1]["t"] == pytest.approx(2.6, abs=0.1)
    assert seen["zero"] is not None and np.array_equal(seen["zero"], seen["after"])
    assert runtime.scene.estimator is seen["estimator"]
    assert "reloaded" in seen["line"] and "1 bindings" in seen["line"]


def test_a_reload_turns_the_second_finger_stage_on_and_off_with_the_layout(tmp_path, run_scripted):
    """A layout that binds two_finger_tap needs the estimator's second-finger stage; a reload
    to it turns the stage on in the running estimator, a reload away turns it off."""
    path = write_layout(tmp_path / "a.yaml", "lamp")
    two = LAYOUT % ("", "lamp", "lamp") + "  - {gesture: two_finger_tap, region: lamp, do: log}\n"
    stages: list[object] = []

    def reload_to(text):
        def reload(rt):
            stages.append(rt.scene.estimator.second_finger)
            path.write_text(text)
            rt.request("reload").add_done_callback(
                lambda f: stages.append(rt.scene.estimator.second_finger)
            )

        return reload

    plain = LAYOUT % ("", "lamp", "lamp")
    run_scripted(TAPS, 5.0, {2.3: reload_to(two), 3.3: reload_to(plain)}, path)
    before, on, still_on, off = stages
    assert before is None and on is not None and still_on is on and off is None


def test_a_reload_that_does_not_load_keeps_the_running_layout(tmp_path, run_scripted):
    path = write_layout(tmp_path / "a.yaml", "lamp")
    errors = []

    def reload(rt):
        path.write_text(path.read_text().replace("gesture: tap", "gesture: tapp"))
        rt.request("reload").add_done_callback(lambda f: errors.append(f.exception()))

    _, events = run_scripted(TAPS, 5.0, {2.3: reload}, path)
    assert [e["region"] for e in events] == ["lamp"] * 4
    assert isinstance(errors[0], ConfigError)
    assert f"{path}:7:14:" in str(errors[0]) and "tapp" in str(errors[0])


def test_layout_switches_among_named_layouts_and_back(tmp_path, run_scripted):
    write_layout(tmp_path / "evening.yaml", "fan")
    path = write_layout(tmp_path / "a.yaml", "lamp", "layouts: {evening: evening.yaml}")
    answers = []

    def switch(name):
        return lambda rt: rt.request("layout", name).add_done_callback(answers.append)

    _, events = run_scripted(
        TAPS, 5.0, {2.2: switch("evening"), 3.2: switch("nope"), 4.2: switch("default")}, path
    )
    assert [e["region"] for e in events] == ["lamp", "fan", "fan", "lamp"]
    assert "layout `evening`" in answers[0].result()
    with pytest.raises(ControlError, match="no layout named 'nope'; known: default, evening"):
        answers[1].result()


def test_a_named_layout_that_is_missing_is_refused_where_it_is_named(tmp_path):
    from hapticdesk.runtime.assembly import load_scene_layout

    path = write_layout(tmp_path / "a.yaml", "lamp", "layouts: {evening: gone.yaml}")
    with pytest.raises(ConfigError, match=r"a\.yaml:3:20: `layouts.evening`: no such file"):
        load_scene_layout(path, load_registry(entry_points=False))


def test_reload_refuses_a_layout_for_another_desk(tmp_path, run_scripted):
    path = write_layout(tmp_path / "a.yaml", "lamp")
    errors = []

    def reload(rt):
        path.write_text(path.read_text() + "desk_name: other\n")
        rt.request("reload").add_done_callback(lambda f: errors.append(f.exception()))

    _, events = run_scripted(TAPS, 5.0, {2.3: reload}, path)
    assert len(events) == 4
    assert "names the desk `other` but this run is `kitamura2017`" in str(errors[0])


@pytest.mark.parametrize(
    ("payload", "expected"),
    [
        (b'{"command": "tare"}', "tare"),
        (b"pause", "pause"),
        (b'"resume"', "resume"),
        (b'{"reload": true}', "reload"),
        (b'{"layout": "evening"}', "layout evening"),
        (b'{"command": "layout", "layout": "evening"}', "layout evening"),
    ],
)
def test_commands_read_from_json(payload, expected):
    assert str(parse_command(payload)) == expected


@pytest.mark.parametrize(
    ("payload", "message"),
    [
        (b'{"command": "explode"}', "unknown command 'explode'; known: tare, pause"),
        (b"x" * 4000, f"unknown command '{'x' * 60}…'; known: tare"),  # not echoed whole
        (b'{"layout": 3}', "`layout` needs the name of a layout"),
        (b"{nope", "expected JSON such as"),
        (b"[1, 2]", "expected a JSON object or a command name"),
        (b'{"tare": 1, "pause": 1}', "expected one command of"),
        (b"\xff\xfe", "must be UTF-8"),
        (b"x" * 5000, "at most 4096 bytes"),
        (b"[" * 4000, "expected JSON such as"),
    ],
)
def test_what_is_not_a_command_is_refused_saying_why(payload, message):
    with pytest.raises(ControlError, match=message.replace("[", r"\[")):
        parse_command(payload)


def test_python_api_waits_for_the_result_and_times_out_when_not_sensing(tmp_path):
    from hapticdesk.runtime.control import ControlQueue

    queue = ControlQueue()
    future = queue.request(command("reload"))
    assert not future.done()
    assert [str(c) for c, _ in queue.take()] == ["reload"]
    full = [queue.request("tare") for _ in range(65)]
    with pytest.raises(ControlError, match="64 commands are already waiting"):
        full[-1].result(0)


def test_sighup_reloads_the_layout_of_a_running_desk(tmp_path, paper_desk):
    taps = [Tap(1.5 + 0.5 * k, 0.0, 0.0) for k in range(14)]
    recording = tmp_path / "taps.csv"
    write_recording(recording, tap_recording(paper_desk, taps, 8.5))
    path = write_layout(tmp_path / "a.yaml", "lamp")
    events = tmp_path / "events.jsonl"
    process = subprocess.Popen(
        [sys.executable, "-m", "hapticdesk", "run", "--layout", str(path), "--source",
         f"replay:{recording}", "--speed", "1", "--events", str(events)],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline and not (
            events.exists() and events.read_text().count("\n") >= 2
        ):
            time.sleep(0.05)
        write_layout(path, "fan")
        os.kill(process.pid, signal.SIGHUP)
        _, err = process.communicate(timeout=30)
    finally:
        process.kill()
    assert process.returncode == 0, err
    regions = [json.loads(line)["region"] for line in events.read_text().splitlines()]
    assert len(regions) == 14  # nothing lost, no new tare
    switch = regions.index("fan")
    assert switch >= 2 and set(regions[:switch]) == {"lamp"} and set(regions[switch:]) == {"fan"}
    assert "SIGHUP: reloading the layout" in err and "control: reloaded" in err


def test_reload_says_when_a_plugin_section_changed_that_needs_a_restart(tmp_path, paper_desk):
    path = write_layout(tmp_path / "a.yaml", "lamp", "spy_section: {host: a}")
    recording = tap_recording(paper_desk, TAPS[:2], 3.0)
    answers = []

    def reload(rt):
        write_layout(path, "lamp", "spy_section: {host: b}")
        rt.request("reload").add_done_callback(lambda f: answers.append(f.result()))

    holder: dict[str, Runtime] = {}
    source = ScriptedSource(recording, {2.0: lambda: reload(holder["rt"])})
    plugin = SimpleNamespace(
        register_sources=hookimpl(
            lambda register: register("scripted", lambda argument, profile, **o: source)
        ),
        register_layout_sections=hookimpl(
            lambda register: register("spy_section", lambda value, position, path: None)
        ),
    )
    registry = load_registry(entry_points=False, plugins=[("spy", plugin)])
    runtime = holder["rt"] = Runtime(build_scene(path, "scripted:", registry, speed=0))
    runtime.run(handle_signals=False)
    assert (
        "(`spy_section:` changed: its connection settings take effect at the next start)"
        in (answers[0])
    )


def test_a_flood_on_the_set_topic_is_dropped_beyond_its_rate_and_said_once(caplog):
    """10,000 messages on /set were each read, logged and answered (QoS 1 answers that filled
    the link's window and stopped every gesture's message): now at most SET_BURST at once and
    SET_RATE a second are taken; the rest are dropped unanswered, said in one line."""
    from hapticdesk.plugins.mqtt.control import SET_BURST, SetTopic
    from hapticdesk.runtime.control import ControlQueue

    queue, answers = ControlQueue(), []
    topic = SetTopic(queue, lambda t, payload: answers.append(payload), "hapticdesk/d/set")
    with caplog.at_level("WARNING"):
        for _ in range(10_000):
            topic(b"garbage")
    assert SET_BURST <= len(answers) <= SET_BURST + 5  # (a few more for the time it took)
    assert all(a["ok"] is False for a in answers)
    flood = [r for r in caplog.records if "commands a second" in r.getMessage()]
    assert len(flood) == 1 and "dropped so far, unanswered" in flood[0].getMessage()
    assert queue.take() == []  # garbage is never queued


def test_commands_on_the_set_topic_before_the_run_begins_wait_for_it():
    """`set` is subscribed before the desk says it is online, the run's queue comes later:
    what arrives in between is held and queued, in its order, when the queue is attached."""
    from hapticdesk.plugins.mqtt.control import SetTopic
    from hapticdesk.runtime.control import ControlQueue

    answers: list[dict] = []
    topic = SetTopic(None, lambda t, payload: answers.append(payload), "hapticdesk/d/set")
    topic(b'{"command": "layout", "layout": "b"}')
    topic(b"tare")
    topic(b"explode")  # refused at once, not held
    assert [(a["command"], a["ok"]) for a in answers] == [(None, False)]
    queue = ControlQueue()
    topic.attach(queue)
    topic(b"pause")
    assert [str(cmd) for cmd, _ in queue.take()] == ["layout b", "tare", "pause"]
