"""Hostile scenes (the robustness hunt): times too long for memory end in a ConfigError at
the key's file:line:column naming the limit, never a MemoryError, TypeError or ValueError.
Limits are made small here rather than scenes long."""

from __future__ import annotations

from pathlib import Path

import pytest

from hapticdesk.errors import ConfigError
from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.profile_reader import load_profile
from hapticdesk.sim import simulator, timeline, touch_track
from hapticdesk.sim.scene import load_scene
from hapticdesk.sim.simulator import SimSource, simulate
from hapticdesk.sim.timeline import Timeline


@pytest.fixture(scope="module")
def desk() -> DeskProfile:
    return load_profile("kitamura2017")


def scene_file(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "s.yaml"
    path.write_text("desk: kitamura2017\n" + text, encoding="utf-8")
    return path


@pytest.mark.parametrize(
    ("text", "where", "message"),
    [
        ("quiet_s: 1.0e+5\ntimeline:\n  - tap: {point: [0, 0]}\n", "2:10", "`quiet_s` in the"),
        ("tail_s: 1.0e+300\ntimeline:\n  - tap: {point: [0, 0]}\n", "2:9", "`tail_s` in the"),
        ("duration_s: 1e300\ntimeline:\n  - tap: {point: [0, 0]}\n", "2:13", "`duration_s`"),
        ("timeline:\n  - tap: {point: [0, 0], wait_s: 1.0e+300}\n", "3:34", "`wait_s` in `tap`"),
        ("timeline:\n  - tap: {point: [0, 0], start_s: 1.0e+300}\n", "3:35", "`start_s`"),
        ("timeline:\n  - long_press: {point: [0, 0], hold_s: 1.0e+6}\n", "3:41", "`hold_s`"),
        ("timeline:\n  - idle: 1.0e+300\n", "3:11", "`duration_s` in `idle`"),
        (
            "timeline:\n  - ramp: {point: [0, 0], duration_s: 1e9}\n",
            "3:39",
            "`duration_s` in `ramp`",
        ),
        ("timeline:\n  - stroke: {text: 一二, pen_up_s: 1e9}\n", "3:34", "`pen_up_s`"),
    ],
)
def test_a_time_beyond_a_day_is_refused_at_its_key(
    tmp_path: Path, text: str, where: str, message: str
) -> None:
    path = scene_file(tmp_path, text)
    with pytest.raises(ConfigError) as err:
        load_scene(path)
    assert str(err.value).startswith(f"{path}:{where}: {message}"), str(err.value)
    assert "must be <= 86400" in str(err.value)


@pytest.mark.parametrize(
    ("text", "where", "message"),
    [
        # a tap of 1e300 N saturated every simulated sensor: no contact was seen
        ("  - tap: {point: [0, 0], peak_n: 1e300}\n", "3:34", "`peak_n` in `tap` (timeline item "
         "1) must be <= 1000"),
        ("  - swipe: {from: [0, 0], to: [0.1, 0], force_n: 1e300}\n", "3:50", "`force_n` in "
         "`swipe` (timeline item 1) must be <= 1000"),
        ("  - press: {point: [0, 0], rise_n_per_s: 1e300}\n", "3:42", "`rise_n_per_s` in "
         "`press` (timeline item 1) must be <= 100000"),
        # 1e-300 m/s had been refused as a swipe of a 300-digit number of samples
        ("  - swipe: {from: [0, 0], to: [0.1, 0], speed: 1e-300}\n", "3:48", "`speed` in "
         "`swipe` (timeline item 1) must be >= 0.001"),
        ("  - drag: {from: [0, 0], to: [0.1, 0], speed: 1e300}\n", "3:47", "`speed` in `drag` "
         "(timeline item 1) must be <= 10"),
        ("  - stroke: {text: 一, force_n: 1e300}\n", "3:32", "`force_n` in `stroke` (timeline "
         "item 1) must be <= 1000"),
        # a ramp to 1e300 N had been refused as a 300-digit number of samples
        ("  - ramp: {point: [0, 0], to_n: 1e300}\n", "3:33", "`to_n` in `ramp` (timeline item "
         "1) must be <= 1000"),
        # an object of 1e300 kg saturated every sensor: no contact was seen
        ("  - put: {object: mug, point: [0, 0], mass_kg: 1e300}\n", "3:48", "`mass_kg` in `put` "
         "(timeline item 1) must be <= 100"),
    ],
)  # fmt: skip
def test_a_force_or_speed_no_person_makes_is_refused_at_its_key(
    tmp_path: Path, text: str, where: str, message: str
) -> None:
    path = scene_file(tmp_path, "timeline:\n" + text)
    with pytest.raises(ConfigError) as err:
        load_scene(path)
    assert str(err.value).startswith(f"{path}:{where}: {message}"), str(err.value)


def test_repeat_and_the_expanded_timeline_are_bounded(tmp_path: Path) -> None:
    path = scene_file(tmp_path, "timeline:\n  - tap: {point: [0, 0], repeat: 1000000000}\n")
    with pytest.raises(ConfigError, match=r"s.yaml:3:34: `repeat` in .* at most 10000"):
        load_scene(path)


def test_one_touch_track_is_bounded_in_samples(
    tmp_path: Path, desk: DeskProfile, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(touch_track, "MAX_TOUCH_SAMPLES", 2_000)  # 1.67 s at 1.2 kHz
    scene = load_scene(
        scene_file(tmp_path, "timeline:\n  - long_press: {point: [0, 0], hold_s: 3}\n")
    )
    with pytest.raises(
        ConfigError, match=r"s.yaml:3:17: this long_press lasts .* at most 2000 samples"
    ):
        Timeline(desk, scene, 0)
    with pytest.raises(ConfigError, match="at most 2000 samples"):
        SimSource(desk, scene)  # `run --source sim:` refuses it as well


def test_the_touches_of_a_scene_are_bounded_together(
    tmp_path: Path, desk: DeskProfile, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(timeline, "MAX_TRACK_SAMPLES", 3_000)
    text = "timeline:\n  - long_press: {point: [0, 0], hold_s: 1, repeat: 3}\n"
    scene = load_scene(scene_file(tmp_path, text))
    with pytest.raises(ConfigError, match=r"touches last more than 3000 samples together"):
        Timeline(desk, scene, 0)


def test_simulate_refuses_a_recording_it_could_not_hold(
    tmp_path: Path, desk: DeskProfile, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(simulator, "MAX_SIMULATE_SAMPLES", 3_000)
    scene = load_scene(scene_file(tmp_path, "quiet_s: 3\ntimeline:\n  - tap: {point: [0, 0]}\n"))
    with pytest.raises(ConfigError, match=r"s.yaml:1:1: the scene lasts .* at most 3000 samples"):
        simulate(desk, scene)
    # streamed, the same scene plays
    assert sum(len(b.t) for b in SimSource(desk, scene, block_size=1024).blocks()) > 3_000
