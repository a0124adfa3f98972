"""Stroke shapes: templates, the recognizer, stroke files, `hapticdesk strokes`."""

from __future__ import annotations

import json
import math
import zlib
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

from hapticdesk.cli import main
from hapticdesk.errors import ConfigError
from hapticdesk.files.strokefile import read_stroke, read_template_dir, write_stroke
from hapticdesk.gestures.options import GESTURE_OPTIONS
from hapticdesk.gestures.strokes.shapes import SHAPES, hand_drawn, template_document
from hapticdesk.gestures.strokes.unistroke import TemplateSet, builtin_templates, template_set

MIN_SCORE = GESTURE_OPTIONS["stroke"]["min_score"].default

SET_OF_ONE_DOLLAR = [
    "triangle", "x", "rectangle", "circle", "check", "caret", "question_mark", "arrow",
    "left_bracket", "right_bracket", "v", "delete", "left_brace", "right_brace", "star",
    "pigtail",
]  # fmt: skip


def test_the_shipped_templates_are_the_geometric_definitions():
    root = resources.files("hapticdesk.gestures.strokes").joinpath("templates")
    shipped = {Path(p.name).stem: json.loads(p.read_text()) for p in root.iterdir()}
    assert set(shipped) == set(SET_OF_ONE_DOLLAR) | {"zigzag", "line"} == set(SHAPES)
    for name, shape in SHAPES.items():
        assert shipped[name] == json.loads(json.dumps(template_document(shape))), name


def test_v_goes_down_then_up_and_caret_up_then_down_in_desk_coordinates():
    v = np.array(
        json.loads(
            resources.files("hapticdesk.gestures.strokes").joinpath("templates/v.json").read_text()
        )["strokes"][0]
    )
    low = int(np.argmin(v[:, 1]))
    assert 0 < low < len(v) - 1 and v[0, 1] > v[low, 1] < v[-1, 1]
    assert v[0, 0] < v[-1, 0]  # left to right
    templates = builtin_templates()
    assert templates.classify(v, MIN_SCORE).shape == "v"
    assert templates.classify(v * [1, -1], MIN_SCORE).shape == "caret"  # mirrored: ^


@pytest.mark.parametrize("name", list(SHAPES))
def test_every_shape_is_recognised_when_drawn_differently(name):
    rng = np.random.default_rng(zlib.crc32(name.encode()))
    templates = builtin_templates()
    verdicts = [templates.classify(hand_drawn(name, rng), MIN_SCORE).shape for _ in range(12)]
    # all but the odd one, and never a wrong shape more than once; a rectangle with rounded
    # corners turns like a circle (real people's: 7 of 150 $1 rectangles went to circle)
    assert verdicts.count(name) >= 10, verdicts
    assert sum(v not in (None, name) for v in verdicts) <= (2 if name == "rectangle" else 1), (
        verdicts
    )


def test_scale_position_and_rotation_within_the_limit_do_not_matter():
    templates = builtin_templates()
    rng = np.random.default_rng(0)
    check = hand_drawn("check", rng, wobble=0.0, slant_deg=0.0)
    for scale, shift, turn in [
        (0.2, (0, 0), 0),
        (5.0, (1, -2), 0),
        (1, (0, 0), 20),
        (1, (0, 0), -25),
    ]:
        a = math.radians(turn)
        rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
        match = templates.classify(check @ rot.T * scale + shift, MIN_SCORE)
        assert match.shape == "check", (scale, shift, turn, match)
    # turned a quarter: beyond max_rotation_deg, it is no longer a check
    quarter = check @ np.array([[0, -1], [1, 0]]).T
    assert templates.classify(quarter, MIN_SCORE, max_rotation_deg=30).shape != "check"
    assert templates.classify(quarter, MIN_SCORE, max_rotation_deg=180).shape == "check"


def test_closed_shapes_match_from_any_start_and_either_direction():
    templates = builtin_templates()
    a = np.linspace(0, 2 * np.pi, 100)
    for start in (0.0, 1.0, 2.5, 4.0):
        ring = np.column_stack([np.cos(a + start), np.sin(a + start)])
        assert templates.classify(ring, 0.9).shape == "circle"
        assert templates.classify(ring[::-1], 0.9).shape == "circle"


def test_nothing_like_a_shape_is_rejected_not_forced():
    templates = builtin_templates()
    u = np.linspace(0, 1, 200)
    spiral = np.column_stack([u * np.cos(4 * np.pi * u), u * np.sin(4 * np.pi * u)])
    zed = np.array([[0, 1], [1, 1], [0, 0], [1, 0]], dtype=float)
    for path in (spiral, zed):
        match = templates.classify(path, MIN_SCORE)
        assert match.shape is None and match.best_shape is not None and match.score < MIN_SCORE
    # a user template teaches it the new shape
    with_zed = template_set({"zed": [zed]})
    assert with_zed.classify(zed * 3 + 1, MIN_SCORE).shape == "zed"
    assert with_zed.classify(spiral, MIN_SCORE).shape is None


def test_the_catalogue_is_made_only_where_there_are_templates_to_rival():
    """Without the built-in templates, they are read only as the rival of a person's own
    (unistroke.template_set): a layout with none of its own does not read and expand 291
    templates it never asks; one with its own has the catalogue, and generators of strokes
    are taken as the lists they were."""
    zed = np.array([[0, 1], [1, 1], [0, 0], [1, 0]], dtype=float)
    assert template_set(None, builtin=False).catalogue is None
    assert template_set({"zed": []}, builtin=False).catalogue is None
    mine = template_set({"zed": (p for p in [zed, zed[::-1]])}, builtin=False)
    assert mine.catalogue is not None and len(mine.catalogue) == len(builtin_templates())
    assert len(mine) == 2 and mine.shapes == ["zed"]


def test_degenerate_strokes():
    templates = builtin_templates()
    assert templates.classify(np.zeros((5, 2)), 0.0).shape is None
    assert TemplateSet().classify(np.eye(2), 0.0).shape is None
    with pytest.raises(ValueError, match="no extent"):
        TemplateSet().add("dot", np.zeros((3, 2)))


def test_stroke_files_round_trip_and_errors(tmp_path):
    pts = np.array([[0.0, 0.1], [0.05, 0.0], [0.1, 0.1]])
    write_stroke(tmp_path / "a.csv", pts, np.array([0, 0.1, 0.2]))
    write_stroke(tmp_path / "b.json", pts)
    assert read_stroke(tmp_path / "a.csv") == pytest.approx(pts)
    assert read_stroke(tmp_path / "b.json") == pytest.approx(pts)
    cases = {
        "h.csv": ("x;y\n0;0\n", r"h\.csv:1: the header must be `x,y` or `x,y,t`"),
        "n.csv": ("x,y\n0,0\n1,nan\n", r"n\.csv:3: values must be finite"),
        "w.csv": ("x,y\n0,0\n1\n", r"w\.csv:3: expected 2 values, found 1"),
        "one.csv": ("x,y\n0,0\n", r"at least 2 points, found 1"),
        "same.csv": ("x,y\n1,1\n1,1\n", r"does not move"),
        "j.json": ('{"points": [[0, 0], [1]]}', r"two numbers per point"),
        "bad.json": ("{", r"bad\.json:1:2: not valid JSON"),
        "s.txt": ("x,y\n", r"must end in \.csv"),
    }
    for name, (text, message) in cases.items():
        (tmp_path / name).write_text(text)
        with pytest.raises(ConfigError, match=message):
            read_stroke(tmp_path / name)


def write_templates(root: Path) -> Path:
    zed = np.array([[0, 1], [1, 1], [0, 0], [1, 0]], dtype=float)
    (root / "zed").mkdir(parents=True)
    write_stroke(root / "zed" / "1.csv", zed * 0.1)
    (root / "empty").mkdir()
    return root


def test_classify_command_json_lines_folders_and_a_bad_file(tmp_path, capsys):
    strokes = tmp_path / "in"
    strokes.mkdir()
    rng = np.random.default_rng(1)
    write_stroke(strokes / "1-circle.csv", hand_drawn("circle", rng))
    write_stroke(strokes / "2-zed.json", np.array([[0, 1], [1, 1.1], [0, 0], [1.1, 0]]) * 0.08)
    (strokes / "3-broken.csv").write_text("x,y\n0,zero\n")
    templates = write_templates(tmp_path / "tpl")
    assert read_template_dir(templates).keys() == {"zed"}
    code = main(["strokes", "classify", str(strokes), "--json"])
    out, err = capsys.readouterr()
    rows = [json.loads(line) for line in out.splitlines()]
    assert code == 2 and "3-broken.csv:2: not a number" in err  # (an input error: cli.md)
    assert [(Path(r["file"]).name, r["shape"]) for r in rows] == [
        ("1-circle.csv", "circle"), ("2-zed.json", None)
    ]  # fmt: skip
    assert rows[0]["score"] >= MIN_SCORE and set(rows[0]) == {"file", "shape", "score"}
    code = main(
        [
            "strokes",
            "classify",
            str(strokes / "2-zed.json"),
            "--templates",
            str(templates),
            "--json",
        ]
    )
    assert code == 0 and json.loads(capsys.readouterr().out)["shape"] == "zed"
    code = main(
        [
            "strokes",
            "classify",
            str(strokes / "1-circle.csv"),
            "--templates",
            str(templates),
            "--no-builtin",
        ]
    )
    out = capsys.readouterr().out
    assert code == 0 and "1-circle.csv" in out and "nearest zed" in out


def test_record_command_captures_strokes_from_a_simulated_scene(tmp_path, capsys):
    scene = tmp_path / "scene.yaml"
    scene.write_text(
        "name: zeds\ndesk: kitamura2017\nunits: cm\nquiet_s: 1.5\ntimeline:\n"
        "  - stroke: {path: [[-5, 5], [5, 5], [-5, -5], [5, -5]], speed: 10}\n"
        "  - tap: {point: [10, 10], peak_n: 5}\n"
        "  - stroke: {path: [[-4, 4], [6, 4], [-4, -5], [6, -5]], speed: 12}\n"
    )
    layout = tmp_path / "layout.yaml"
    layout.write_text(  # with a plugin's section, as `check` and `run` take it (README)
        "desk: kitamura2017\ntemplates: strokes\nmqtt: {broker: mqtt://127.0.0.1:1883}\n"
        "bindings:\n  - {gesture: stroke, shape: circle, do: log}\n"
    )
    (tmp_path / "strokes").mkdir()
    code = main(["strokes", "record", "zed", "--layout", str(layout), "--source", f"sim:{scene}"])
    out, err = capsys.readouterr()
    rows = [json.loads(line) for line in out.splitlines()]
    files = sorted((tmp_path / "strokes" / "zed").iterdir())
    assert code == 0 and [f.name for f in files] == ["zed-001.csv", "zed-002.csv"]
    assert [r["looks_like"] for r in rows] == [None, None]  # not a built-in shape
    assert all(9 <= r["size_cm"] <= 15 for r in rows)
    assert "1 smaller touches skipped" in err and "to use them" not in err
    # the layout now knows the shape, and a zed drawn again is recognised as one
    code = main(
        [
            "strokes",
            "record",
            "zed",
            "--layout",
            str(layout),
            "--source",
            f"sim:{scene}",
            "--count",
            "1",
        ]
    )
    out, _ = capsys.readouterr()
    assert code == 0 and json.loads(out)["looks_like"] == "zed"
    assert (tmp_path / "strokes" / "zed" / "zed-003.csv").is_file()
    assert not (tmp_path / "strokes" / "zed" / "zed-004.csv").exists()
    assert (
        main(["strokes", "record", "2bad", "--layout", str(layout), "--source", f"sim:{scene}"])
        == 2
    )


def test_record_keeps_the_strokes_before_a_bad_line_and_exits_1(tmp_path, capsys):
    """A replayed recording with a bad line after a stroke: sensing stopped part way, as
    `run` and `record` say it (exit 1, the strokes before it kept and counted); it was
    exit 2, an input error, and the count of the strokes already saved was never said."""
    from hapticdesk.files.profile_reader import load_profile
    from hapticdesk.files.recording_io import write_recording
    from hapticdesk.sim import load_scene, simulate

    scene = tmp_path / "scene.yaml"
    scene.write_text(
        "name: zed\ndesk: kitamura2017\nunits: cm\nquiet_s: 1.5\ntimeline:\n"
        "  - stroke: {path: [[-5, 5], [5, 5], [-5, -5], [5, -5]], speed: 10}\n"
        "  - idle: 1.0\n"
    )
    recording = tmp_path / "zed.csv"
    write_recording(recording, simulate(load_profile("kitamura2017"), load_scene(scene)))
    lines = recording.read_text().splitlines()
    recording.write_text("\n".join([*lines[:-200], "1,2,zero", *lines[-200:]]) + "\n")
    layout = tmp_path / "layout.yaml"
    layout.write_text(
        "desk: kitamura2017\nbindings:\n  - {gesture: stroke, shape: circle, do: log}\n"
    )
    (tmp_path / "strokes").mkdir()
    argv = ["strokes", "record", "zed", "--layout", str(layout), "--source", f"replay:{recording}"]
    code = main([*argv, "--into", str(tmp_path / "strokes")])
    err = capsys.readouterr().err
    bad = len(lines) - 200 + 1
    assert code == 1, err
    assert f"hapticdesk strokes: error: sensing stopped part way: {recording}:{bad}:" in err
    assert "the strokes drawn before it are saved" in err and "recorded 1 stroke(s)" in err
    assert [f.name for f in (tmp_path / "strokes" / "zed").iterdir()] == ["zed-001.csv"]
    recording.write_text("\n".join([lines[0], "1,2,zero", *lines[1:]]) + "\n")
    assert main([*argv, "--into", str(tmp_path / "again")]) == 2  # nothing read: the input's


def test_a_compensated_desks_strokes_keep_their_corners():
    """Where the estimator takes the sway out (an accelerometer, or `sway_compensation`), a
    stroke gets the calm smoothing whatever its wobble: a fast stroke's corners look like
    sway to the wobble test and the heavy σ rounded them."""
    from dataclasses import replace

    from hapticdesk.files.profile_reader import load_profile
    from hapticdesk.gestures.recognizers.stroke import (
        calm_smoothing_s,
        smoothing_s,
        stroke_path,
        sway_compensated,
    )

    shipped = load_profile("kitamura2017")  # `fused`: compensated unless the profile says not
    plain = shipped.with_estimation(sway_compensation=False)
    legs = plain.with_estimation(sway_compensation=True)
    accel = load_profile("kitamura2017-accel")
    assert not sway_compensated(plain)
    assert not sway_compensated(shipped.with_estimation(method="switched"))
    assert sway_compensated(shipped) and sway_compensated(legs) and sway_compensated(accel)
    assert not sway_compensated(replace(legs, natural_frequency_hz=None))
    assert smoothing_s(plain) > 2 * calm_smoothing_s(plain)
    for desk in (legs, accel):
        assert smoothing_s(desk) == calm_smoothing_s(desk)
    # a clean square drawn at 0.3 m/s, 7 cm a side: its corners survive the calm σ only
    side = np.linspace(0.0, 0.07, 24, endpoint=False)
    square = np.vstack(
        [np.column_stack(c) for c in ((side, 0 * side), (0 * side + 0.07, side),
                                      (0.07 - side, 0 * side + 0.07), (0 * side, 0.07 - side))]
    )  # fmt: skip
    times = np.arange(len(square)) * (0.07 / 24 / 0.3)

    def corner_gap(desk) -> float:
        _, path = stroke_path(times, square, smoothing_s(desk), calm_smoothing_s(desk))
        return float(np.min(np.hypot(path[:, 0] - 0.07, path[:, 1] - 0.0)))

    # (13 mm from the corner with the calm σ, 22 mm with the heavy one the wobble test chose)
    assert corner_gap(legs) < 0.7 * corner_gap(plain)


def test_a_desk_whose_mass_sits_on_its_sensors_keeps_the_calm_smoothing():
    """Load cells just under the top see the sway only through the centre of mass's few
    millimetres above them: the profile says so (its centre of mass, or its top, above the
    sensors), and such a desk's strokes get the calm σ without any flag; the same cells
    under a tall frame, or the paper's desk, keep the heavy σ."""
    from dataclasses import replace

    from hapticdesk.files.profile_reader import load_profile
    from hapticdesk.gestures.recognizers.stroke import (
        calm_smoothing_s,
        smoothing_s,
        sway_compensated,
        sway_reaches_path,
    )

    for name in ("kitamura2017-loadcells-1khz", "kitamura2017-loadcells-80hz", "balance-board"):
        desk = load_profile(name)
        assert not sway_compensated(desk)  # (no shear: the legs' compensation is off)
        assert not sway_reaches_path(desk)
        assert smoothing_s(desk) == calm_smoothing_s(desk)
    cells = load_profile("kitamura2017-loadcells-80hz")
    tall = replace(cells, center_of_mass_m=np.array([0.0, 0.0, 0.703 + 0.6]))
    assert sway_reaches_path(tall) and smoothing_s(tall) > 2 * calm_smoothing_s(tall)
    # without a centre of mass, the top's height above the sensors bounds the lever
    assert not sway_reaches_path(replace(cells, center_of_mass_m=None))
    plain = load_profile("kitamura2017").with_estimation(sway_compensation=False)
    assert sway_reaches_path(plain) and smoothing_s(plain) > 2 * calm_smoothing_s(plain)
