"""Scenes: the shipped examples, YAML validation with positions, Python-built scenes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hapticdesk.errors import ConfigError
from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.profile_reader import load_profile
from hapticdesk.sim import (
    GLYPHS,
    Idle,
    LiftObject,
    LongPress,
    Press,
    PutObject,
    Scene,
    Stroke,
    Tap,
    load_scene,
    text_paths,
)
from hapticdesk.sim.timeline import Timeline

SCENES = Path(__file__).resolve().parents[2] / "examples" / "scenes"
EXAMPLES = sorted(SCENES.glob("*.yaml"))


def scene_text(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "scene.yaml"
    path.write_text(text, encoding="utf-8")
    return path


def test_every_example_is_shipped() -> None:
    names = {p.stem for p in EXAMPLES}
    assert {"paper-experiment", "kita", "buttons", "slider", "swipes", "shapes", "demo"} <= names


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.stem)
def test_examples_load_and_start_quietly(path: Path, paper_desk: DeskProfile) -> None:
    scene = load_scene(path)
    assert scene.quiet_s >= 1.5
    desk = load_profile(scene.desk) if scene.desk else paper_desk  # (panel.yaml: its panel)
    timeline = Timeline(desk, scene, seed=0)
    first = min(s.start_s for s in timeline.spans)
    assert first >= 1.5
    assert timeline.duration_s > max(s.end_s for s in timeline.spans)


def test_paper_experiment_presses_nine_points_three_times() -> None:
    scene = load_scene(SCENES / "paper-experiment.yaml")
    assert len(scene.actions) == 27 and all(type(a) is Press for a in scene.actions)
    points = [a.point for a in scene.actions]  # type: ignore[attr-defined]
    unique = sorted(set(points))
    assert len(unique) == 9 and all(points.count(p) == 3 for p in unique)
    xs, ys = sorted({p[0] for p in unique}), sorted({p[1] for p in unique})
    assert xs == pytest.approx([-0.3, 0.0, 0.3]) and ys == pytest.approx([-0.2, 0.0, 0.2])


def test_kita_traces_the_five_strokes_of_the_glyph() -> None:
    scene = load_scene(SCENES / "kita.yaml")
    strokes = [a for a in scene.actions if isinstance(a, Stroke)]
    assert len(strokes) == 5
    glyph = text_paths("北", size=0.30)
    for stroke, expected in zip(strokes, glyph, strict=True):
        np.testing.assert_allclose(np.array(stroke.path), expected, atol=1e-9)


def test_buttons_grid_and_demo_layout() -> None:
    buttons = load_scene(SCENES / "buttons.yaml")
    taps = [a for a in buttons.actions if type(a) is Tap][:9]
    centres = np.array([t.point for t in taps])
    assert sorted(set(np.round(centres[:, 0], 6))) == pytest.approx([-0.08, 0.0, 0.08])
    assert sorted(set(np.round(centres[:, 1], 6))) == pytest.approx([-0.08, 0.0, 0.08])
    assert any(isinstance(a, LongPress) for a in buttons.actions)
    demo = load_scene(SCENES / "demo.yaml")
    kinds = [type(a).__name__ for a in demo.actions]
    assert kinds == ["Tap", "Drag", "Stroke", "Tap"]


def test_demo_is_short(paper_desk: DeskProfile) -> None:
    timeline = Timeline(paper_desk, load_scene(SCENES / "demo.yaml"), seed=0)
    assert timeline.duration_s <= 20.0


def test_units_scale_positions_and_speeds(tmp_path: Path) -> None:
    path = scene_text(
        tmp_path,
        "units: mm\ntimeline:\n  - drag: {from: [-100, 20], to: [100, 20], speed: 50}\n",
    )
    drag = load_scene(path).actions[0]
    assert drag.path == ((-0.1, 0.02), (0.1, 0.02))  # type: ignore[attr-defined]
    assert drag.speed == pytest.approx(0.05)  # type: ignore[attr-defined]


def test_repeat_text_and_idle_shorthand(tmp_path: Path) -> None:
    path = scene_text(
        tmp_path,
        "timeline:\n"
        "  - tap: {point: [0, 0], repeat: 4, wait_s: 0.2, start_s: 3}\n"
        "  - idle: 2\n"
        "  - stroke: {text: 北, size: 0.2, pen_up_s: 0.3}\n",
    )
    scene = load_scene(path)
    taps = scene.actions[:4]
    assert [t.start_s for t in taps] == [3.0, None, None, None]
    assert all(t.wait_s == 0.2 for t in taps)
    assert isinstance(scene.actions[4], Idle) and scene.actions[4].duration_s == 2.0
    strokes = scene.actions[5:]
    assert len(strokes) == len(GLYPHS["北"])
    assert [s.wait_s for s in strokes[1:]] == [0.3] * 4


def test_stroke_from_a_file_fitted_to_a_size(tmp_path: Path) -> None:
    (tmp_path / "z.csv").write_text("x,y\n0,0\n1,0\n0,-1\n1,-1\n", encoding="utf-8")
    path = scene_text(
        tmp_path, "timeline:\n  - stroke: {file: z.csv, center: [0.1, 0.05], size: 0.1}\n"
    )
    stroke = load_scene(path).actions[0]
    pts = np.array(stroke.path)  # type: ignore[attr-defined]
    np.testing.assert_allclose(pts.min(axis=0), [0.05, 0.0])
    np.testing.assert_allclose(pts.max(axis=0), [0.15, 0.1])


# --- errors, each with file:line:column -------------------------------------------------------

BAD = [
    ("timeline:\n  - pres: {point: [0, 0]}\n", "2:5", "unknown action `pres`"),
    ("timeline:\n  - press: {point: [0, 0], peek_n: 20}\n", "2:28", "unknown key `peek_n`"),
    ("timeline:\n  - press: {point: [0]}\n", "2:20", "must have 2 numbers"),
    ("timeline:\n  - press: {}\n", "2:12", "missing `point`"),
    ("timeline:\n  - press: {point: [0, 0]}\n    tap: {point: [0, 0]}\n", "2:5", "single key"),
    ("timeline:\n  - press: {point: [0, 0], peak_n: -3}\n", "2:36", "must be > 0"),
    ("timeline:\n  - tap: {point: [0, 0], repeat: 1.5}\n", "2:34", "whole number"),
    ("quiet_s: 0.5\ntimeline:\n  - tap: {point: [0, 0]}\n", "1:10", "estimator tares"),
    ("units: inch\ntimeline:\n  - tap: {point: [0, 0]}\n", "1:8", "m, cm, mm"),
    ("timeline:\n  - stroke: {shape: hexagon}\n", "2:21", "unknown shape 'hexagon'"),
    ("timeline:\n  - stroke: {shape: line, path: [[0, 0], [1, 1]]}\n", "2:27", "exactly one"),
    ("timeline:\n  - stroke: {text: 猫}\n", "2:20", "built-in characters"),
    ("timeline:\n  - stroke: {shape: [circle]}\n", "2:21", "unknown shape ['circle']"),
    ("timeline:\n  - stroke: {text: 十, clockwise: true}\n", "2:23", "applies to `shape` only"),
    ("timeline:\n  - stroke: {path: [[0, 0]]}\n", "2:20", "two or more"),
    ("timeline:\n  - stroke: {file: nowhere.csv}\n", "2:20", "cannot read"),
    ("timeline:\n  - swipe: {from: [0, 0], to: [0, 0]}\n", "2:31", "must differ"),
    ("timeline:\n  - stroke: {shape: circle, clockwise: 1}\n", "2:40", "true or false"),
    ("human: {peak_n: [30, 10]}\ntimeline:\n  - tap: {point: [0, 0]}\n", "1:17", "low <= high"),
    ("human: {speed: 3}\ntimeline:\n  - tap: {point: [0, 0]}\n", "1:9", "unknown key `speed`"),
    ("timeline: []\n", "1:11", "at least one action"),
    ("timeline:\n  - tap: [0, 0]\n", "2:10", "must be a mapping"),
    ("timeline:\n  - tap: {point: [0, 0]\n", "3:1", "not valid YAML"),
    ("objects:\n  - {name: cup, mass_kg: 0}\ntimeline:\n  - idle: 1\n", "2:5", "missing `point`"),
    (
        "timeline:\n  - idle: {duration_s: 1}\n  - {on: {point: [0, 0]}}\n",
        "3:6",
        "unknown action `on`",
    ),
]


@pytest.mark.parametrize(("text", "where", "message"), BAD, ids=[b[2] for b in BAD])
def test_bad_scene_files_say_where_and_what(
    tmp_path: Path, text: str, where: str, message: str
) -> None:
    path = scene_text(tmp_path, text)
    with pytest.raises(ConfigError) as err:
        load_scene(path)
    assert str(err.value).startswith(f"{path}:{where}: "), str(err.value)
    assert message in str(err.value)


BAD_ON_DESK = [
    ("timeline:\n  - tap: {point: [0.5, 0]}\n", "2:10", "outside surface `top`"),
    ("timeline:\n  - tap: {point: [0, 0], surface: shelf}\n", "2:10", "no surface `shelf`"),
    ("timeline:\n  - lift: {object: cup}\n", "2:11", "cannot lift `cup`"),
    (
        "timeline:\n  - put: {object: cup, mass_kg: 0.3, point: [0, 0]}\n"
        "  - put: {object: cup, mass_kg: 0.3, point: [0, 0]}\n",
        "3:10",
        "already on the desk",
    ),
    ("timeline:\n  - tap: {point: [0, 0], start_s: 1.0}\n", "2:10", "quiet start"),
    ("duration_s: 3\ntimeline:\n  - press: {point: [0, 0], hold_s: 5}\n", "1:1", "beyond"),
]


@pytest.mark.parametrize(("text", "where", "message"), BAD_ON_DESK, ids=[b[2] for b in BAD_ON_DESK])
def test_scene_errors_found_on_a_desk_keep_their_position(
    tmp_path: Path, paper_desk: DeskProfile, text: str, where: str, message: str
) -> None:
    path = scene_text(tmp_path, text)
    scene = load_scene(path)
    with pytest.raises(ConfigError) as err:
        Timeline(paper_desk, scene, seed=0)
    assert str(err.value).startswith(f"{path}:{where}: "), str(err.value)
    assert message in str(err.value)


# --- Python-built scenes ----------------------------------------------------------------------


def test_python_scene_with_objects_and_timing(paper_desk: DeskProfile) -> None:
    scene = Scene(
        [
            PutObject(name="cup", mass_kg=0.3, point=(0.2, 0.1)),
            Tap((0.0, 0.0), wait_s=0.5),
            Tap((0.1, 0.0), start_s=6.0),
            LiftObject(name="cup"),
        ],
        quiet_s=2.0,
    )
    timeline = Timeline(paper_desk, scene, seed=0)
    spans = timeline.spans
    assert spans[0].start_s == 2.0
    assert spans[1].start_s == pytest.approx(spans[0].end_s + 0.5)
    assert spans[2].start_s == 6.0
    assert spans[3].start_s > spans[2].end_s
    assert [s.kind for s in spans] == ["put", "tap", "tap", "lift"]


def test_python_scene_errors_without_positions(paper_desk: DeskProfile) -> None:
    with pytest.raises(ValueError, match="two finite numbers"):
        Tap((0.0, float("nan")))
    with pytest.raises(ValueError, match="Press.peak_n must be > 0"):
        Press((0.0, 0.0), peak_n=-5.0)
    with pytest.raises(ValueError, match="Stroke.speed must be > 0"):
        Stroke([(0.0, 0.0), (0.1, 0.0)], speed=0.0)
    with pytest.raises(ValueError, match="wait_s must be >= 0"):
        Tap((0.0, 0.0), wait_s=-1.0)
    with pytest.raises(ConfigError, match="outside surface"):
        Timeline(paper_desk, Scene([Press((2.0, 0.0))]), seed=0)
