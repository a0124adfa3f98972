"""A layout that binds `two_finger_tap` turns the estimator's second-finger stage on, through
`hapticdesk run`'s own assembly; other layouts leave it out."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from hapticdesk.plugin_loading import load_registry
from hapticdesk.runtime.assembly import build_scene
from hapticdesk.runtime.service import Runtime

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def test_the_two_finger_example_runs_with_the_stage_and_buttons_without(tmp_path):
    registry = load_registry(entry_points=False)
    source = f"sim:{EXAMPLES / 'scenes' / 'two-finger.yaml'}"
    buttons = build_scene(EXAMPLES / "layouts" / "buttons.yaml", source, registry, speed=0)
    try:
        assert buttons.estimator.second_finger is None
    finally:
        buttons.close()
    scene = build_scene(EXAMPLES / "layouts" / "two-finger.yaml", source, registry, speed=0)
    assert scene.estimator.second_finger is not None
    events_path = tmp_path / "events.jsonl"
    report = Runtime(scene, events_path=events_path).run(handle_signals=False)
    assert report.error is None
    events = [json.loads(line) for line in events_path.read_text().splitlines()]
    assert [(e["gesture"], e["region"]) for e in events] == [
        ("tap", "lamp"),
        ("two_finger_tap", "lamp"),
        ("tap", "lamp"),
    ]
    two = events[1]
    assert np.hypot(two["x"] + 0.20, two["y"] + 0.10) < 0.015  # the first finger, on the lamp
    assert np.hypot(two["x2"] + 0.08, two["y2"] + 0.02) < 0.03  # the second, where it tapped
