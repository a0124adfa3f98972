"""Stopping a run while a finger is down (in process, and SIGTERM to a real `hapticdesk run`),
or a recording that ends mid-press, makes up no release: no tap and no tap action fire for
that touch; a held long press ends with phase cancel (issue 10, items 4 and 5)."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from hapticdesk.files.recording_io import write_recording
from hapticdesk.plugin_loading import load_registry
from hapticdesk.runtime.assembly import build_scene
from hapticdesk.runtime.service import Runtime

from .taps import Tap, tap_recording

LAYOUT = {
    "desk": "kitamura2017",
    "units": "cm",
    "regions": {"lamp": {"rect": [-5, -5, 5, 5]}},
    # a tap may last long here, so a made-up release at the stop would be a tap
    "bindings": [{"gesture": "tap", "region": "lamp", "max_duration_s": 5, "do": {"log": {}}}],
}


def run(tmp_path: Path, paper_desk, taps: list[Tap], duration_s: float, stop_at_s=None):
    """Run the layout over a recording of ``taps``; with ``stop_at_s``, stop the run (as
    SIGTERM does) at the first block after that sample time. Returns the tap events."""
    layout = tmp_path / "layout.yaml"
    layout.write_text(json.dumps(LAYOUT))
    recording = tmp_path / "taps.npz"
    write_recording(recording, tap_recording(paper_desk, taps, duration_s))
    scene = build_scene(layout, f"replay:{recording}", load_registry(entry_points=False), speed=0)
    events_path = tmp_path / "events.jsonl"
    runtime = Runtime(scene, events_path=events_path)
    if stop_at_s is not None:
        blocks = scene.source.blocks

        def stopping() -> Iterator:
            for block in blocks():
                yield block
                if block.t[-1] >= stop_at_s:
                    runtime.stop()  # what the SIGTERM handler calls

        scene.source.blocks = stopping  # type: ignore[method-assign]
    report = runtime.run(handle_signals=False)
    assert report.error is None
    events = [json.loads(line) for line in events_path.read_text().splitlines()]
    return [e for e in events if e["gesture"] == "tap"], report


def test_a_stop_while_the_finger_is_down_fires_no_tap(tmp_path, paper_desk):
    taps = [Tap(1.5, 0.0, 0.0), Tap(2.5, 0.0, 0.0, duration_s=3.0)]  # the second is held
    fired, report = run(tmp_path, paper_desk, taps, 7.0, stop_at_s=3.5)
    assert report.sample_time_s < 4.0  # it did stop mid-press
    assert len(fired) == 1 and fired[0]["t"] < 2.0
    # not stopped, the held touch is released and is a tap (so the test can fail)
    fired, _ = run(tmp_path, paper_desk, taps, 7.0)
    assert len(fired) == 2


def test_a_recording_that_ends_mid_press_fires_no_tap(tmp_path, paper_desk):
    taps = [Tap(1.5, 0.0, 0.0), Tap(2.5, 0.0, 0.0, duration_s=1.0)]
    fired, _ = run(tmp_path, paper_desk, taps, 3.0)  # ends half way through the second
    assert len(fired) == 1 and 1.5 < fired[0]["t"] < 2.0


HELD = {
    "desk": "kitamura2017",
    "units": "cm",
    "regions": {"lamp": {"rect": [-5, -5, 5, 5]}},
    "bindings": [
        # a made-up release at the stop would be a tap: any touch up to 5 s counts
        {"gesture": "tap", "region": "lamp", "max_duration_s": 5, "do": {"log": {}}},
        # tells the test the finger is down and held
        {"gesture": "long_press", "region": "lamp", "hold_s": 0.5, "do": {"log": {}}},
    ],
}


def hapticdesk_run(tmp_path: Path, paper_desk, speed: str) -> tuple[subprocess.Popen, Path]:
    """`hapticdesk run` in its own process over a tap, then a press on the lamp held from
    2.3 s to 5.7 s (sample time)."""
    layout = tmp_path / "held.yaml"
    layout.write_text(json.dumps(HELD))
    recording = tmp_path / "held.npz"
    taps = [Tap(1.0, 0.0, 0.0), Tap(2.0, 0.0, 0.0, duration_s=4.0, peak_n=40.0)]
    write_recording(recording, tap_recording(paper_desk, taps, 7.0))
    events = tmp_path / f"events-{speed}.jsonl"
    argv = [sys.executable, "-m", "hapticdesk", "run", "--layout", str(layout)]
    argv += ["--source", f"replay:{recording}", "--speed", speed, "--events", str(events)]
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    return proc, events


def read_events(path: Path) -> list[dict]:
    if not path.exists():
        return []
    return [json.loads(line) for line in path.read_text().splitlines() if line.endswith("}")]


def test_sigterm_to_hapticdesk_run_while_the_finger_is_down_fires_no_tap(tmp_path, paper_desk):
    proc, events_path = hapticdesk_run(tmp_path, paper_desk, speed="0.5")
    try:
        deadline = time.monotonic() + 60
        while not any(e["gesture"] == "long_press" for e in read_events(events_path)):
            if proc.poll() is not None or time.monotonic() > deadline:
                pytest.fail(f"the press was never held; the run said: {proc.communicate()[1]}")
            time.sleep(0.05)
        proc.send_signal(signal.SIGTERM)  # the finger is down until 5.7 s: ≥ 5 s away
        _, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, err
    assert "stopped by SIGTERM" in err and "Traceback" not in err
    events = read_events(events_path)
    assert [e["t"] < 2.0 for e in events if e["gesture"] == "tap"] == [True]  # the first only
    presses = [e.get("phase") for e in events if e["gesture"] == "long_press"]
    assert presses == [None, "cancel"]  # the hold broke off: cancel, not end
    assert events[-1]["t"] < 5.7
    # played to the end, the press is released (so the test can fail): an end, where the stop
    # gave a cancel; no second tap, as the long press holds that touch (one gesture per touch:
    # the made-up tap is the in-process tests' above)
    proc, events_path = hapticdesk_run(tmp_path, paper_desk, speed="0")
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    events = read_events(events_path)
    assert len([e for e in events if e["gesture"] == "tap"]) == 1
    assert [e.get("phase") for e in events if e["gesture"] == "long_press"] == [None, "end"]
