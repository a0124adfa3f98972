"""Runtime.reload_layout: a saved layout is used from the next block, without a new tare."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from hapticdesk.files.recording import write_recording
from hapticdesk.files.yamlfile import ConfigError
from hapticdesk.plugins.replay import RecordingSource
from hapticdesk.registry import load_registry
from hapticdesk.runtime.dispatcher import Lane
from hapticdesk.runtime.service import Runtime, build_scene

from .taps import Tap, tap_recording

BEFORE = """desk: kitamura2017
units: cm
regions:
  left: {rect: [-15, -5, -5, 5]}
bindings:
  - {gesture: tap, region: left, do: {log: {}}}
"""
AFTER = (
    BEFORE.replace("regions:\n", "regions:\n  right: {rect: [5, -5, 15, 5]}\n")
    + "  - {gesture: tap, region: right, do: {log: {}}}\n"
)


class ReloadingSource(RecordingSource):
    """Hands out the recording and asks the runtime to reload once sample time passes 2.5 s."""

    runtime: Runtime | None = None
    layout_path = None

    def blocks(self) -> Iterator:
        reloaded = False
        for block in super().blocks():
            if not reloaded and block.t[0] >= 2.5 and self.runtime is not None:
                self.layout_path.write_text(AFTER)
                self.runtime.reload_layout()
                reloaded = True
            yield block


@pytest.mark.parametrize("with_reload", [False, True])
def test_reload_uses_the_new_layout_without_a_new_tare(tmp_path, paper_desk, with_reload):
    # a tap on the right (0.1, 0) before the reload and after it; one on the left after it
    taps = [Tap(1.8, 0.1, 0.0), Tap(3.0, 0.1, 0.0), Tap(3.6, -0.1, 0.0)]
    recording = tap_recording(paper_desk, taps, 4.2)
    source = ReloadingSource(recording, paper_desk.sample_rate_hz)
    layout_path = tmp_path / "layout.yaml"
    layout_path.write_text(BEFORE)
    recording_path = tmp_path / "taps.csv"
    write_recording(recording_path, recording)
    registry = load_registry(entry_points=False)
    scene = build_scene(layout_path, f"replay:{recording_path}", registry, speed=0)
    scene.source.close()
    scene.source = source  # the same recording, with the reload in the middle
    runtime = Runtime(scene)
    if with_reload:
        source.runtime, source.layout_path = runtime, layout_path
    events: list = []
    scene.dispatcher.add_sink(Lane("spy", events.append))
    estimator = scene.estimator
    report = runtime.run(handle_signals=False)
    assert report.error is None
    taps_seen = [e.region for e in events if e.gesture == "tap"]
    if with_reload:  # the tap on the right before the reload found no region; the one after did
        assert taps_seen == ["right", "left"], taps_seen
    else:  # the first layout knows only `left`
        assert taps_seen == ["left"], taps_seen
    tares = [n for n in estimator.notices if n.kind == "tare"]
    assert len(tares) == 1  # the estimator was kept: no new tare
    assert scene.estimator is estimator


def test_a_broken_layout_is_refused_and_the_old_one_kept(tmp_path, paper_desk):
    recording = tap_recording(paper_desk, [], 1.0)
    path = tmp_path / "taps.csv"
    write_recording(path, recording)
    layout_path = tmp_path / "layout.yaml"
    layout_path.write_text(BEFORE)
    scene = build_scene(layout_path, f"replay:{path}", load_registry(entry_points=False), speed=0)
    runtime = Runtime(scene)
    layout_path.write_text(BEFORE.replace("[-15, -5, -5, 5]", "[-15, -5, -5]"))
    with pytest.raises(ConfigError, match=r"layout.yaml:4:\d+"):
        runtime.reload_layout()
    assert runtime._pending_layout is None
    assert list(scene.layout.regions) == ["left"]
    scene.close()
