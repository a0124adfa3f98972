"""A third-party plugin can do all a built-in does: block the built-in, register the same
names through the same hooks, and the run uses the replacement (STYLE.md 16)."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from hapticdesk.estimator.contacts import ContactEvent
from hapticdesk.files.recording_io import write_recording
from hapticdesk.gestures.event import GestureEvent
from hapticdesk.gestures.recognizer import Recognizer
from hapticdesk.gestures.touch import Touch
from hapticdesk.hookspecs import hookimpl
from hapticdesk.plugin_loading import load_registry
from hapticdesk.registered import PluginError
from hapticdesk.registry import BLOCK_ENV
from hapticdesk.runtime.assembly import build_scene
from hapticdesk.runtime.service import Runtime

from .taps import Tap, tap_recording

LAYOUT = """\
desk: kitamura2017
regions: {left: {rect: [-0.3, -0.2, 0, 0.2]}, right: {rect: [0, -0.2, 0.3, 0.2]}}
bindings:
  - {gesture: tap, region: left, do: {log: {}}}
"""


class EveryTouchIsATap(Recognizer):
    """The replacement `tap`: any touch, however long, released in a region."""

    gestures = ("tap",)

    def on_contact(self, event: ContactEvent, touch: Touch) -> list[GestureEvent]:
        if event.kind != "up":
            return []
        region = self.layout.regions["left"]
        inside = bool(region.contains(np.array([event.x]), np.array([event.y]))[0])
        return [GestureEvent(event.t, "tap", "left" if inside else None, event.x, event.y)]


def replacement(seen: list[GestureEvent]) -> SimpleNamespace:
    def register_recognizers(register):
        register("tap", EveryTouchIsATap, "every touch")

    def register_actions(register):
        register("log", lambda options, context: seen.append, "collect instead of print")

    return SimpleNamespace(
        register_recognizers=hookimpl(register_recognizers),
        register_actions=hookimpl(register_actions),
    )


def test_a_third_party_plugin_replaces_the_built_in_tap_and_log(tmp_path, paper_desk):
    seen: list[GestureEvent] = []
    registry = load_registry(
        entry_points=False,
        blocked=["hapticdesk.plugins.recognizers", "hapticdesk.plugins.log"],
        plugins=[("my-taps", replacement(seen))],
    )
    assert registry.recognizers["tap"].plugin == registry.actions["log"].plugin == "my-taps"
    assert "double_tap" not in registry.recognizers  # the whole built-in plugin is out
    # a built-in tap would reject this 1.2 s touch (a long press); the replacement takes it
    recording = tmp_path / "taps.csv"
    write_recording(recording, tap_recording(paper_desk, [Tap(1.0, -0.1, 0.0, 1.2)], 3.5))
    layout = tmp_path / "layout.yaml"
    layout.write_text(LAYOUT)
    scene = build_scene(layout, f"replay:{recording}", registry, speed=0)
    assert type(scene.engine.recognizers["tap"]) is EveryTouchIsATap
    report = Runtime(scene).run(handle_signals=False)
    assert report.gestures == {"tap": 1}
    assert [(e.gesture, e.region) for e in seen] == [("tap", "left")]


def test_without_blocking_the_built_in_the_same_name_is_refused_naming_both():
    with pytest.raises(PluginError, match="hapticdesk.plugins.recognizers.*my-taps"):
        load_registry(
            entry_points=False,
            blocked=["hapticdesk.plugins.log"],
            plugins=[("my-taps", replacement([]))],
        )


def test_the_environment_blocks_a_built_in_for_every_command(monkeypatch):
    monkeypatch.setenv(BLOCK_ENV, "hapticdesk.plugins.log, hapticdesk.plugins.recognizers")
    registry = load_registry(entry_points=False, plugins=[("my-taps", replacement([]))])
    assert "hapticdesk.plugins.log" not in registry.plugins
    assert registry.actions["log"].plugin == "my-taps"
    assert list(registry.recognizers) == ["tap"]


@pytest.mark.parametrize("command", ["check", "run"])
def test_a_gesture_whose_recognizer_is_blocked_is_refused_at_its_binding(
    command, monkeypatch, tmp_path, capsys
):
    """`check` refuses what `run` would: with the built-in recognizers blocked and nothing in
    their place, a `tap` binding is an error at its place (exit 2), not a valid layout that
    `run` then fails on with an unexpected error."""
    from hapticdesk.cli import main

    monkeypatch.setenv(BLOCK_ENV, "hapticdesk.plugins.recognizers")
    monkeypatch.setenv("HAPTICDESK_DISABLE_PLUGIN_AUTOLOAD", "1")
    layout = tmp_path / "layout.yaml"
    layout.write_text(LAYOUT)
    scene = f"sim:{Path(__file__).resolve().parents[2] / 'examples/scenes/buttons.yaml'}"
    argv = ["check", str(layout)] if command == "check" else ["run", "--layout", str(layout)]
    argv += [] if command == "check" else ["--source", scene]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert f"{layout}:4:15: no recognizer for gesture `tap` is installed" in err
    assert "HAPTICDESK_BLOCK_PLUGINS" in err and "unexpected" not in err
