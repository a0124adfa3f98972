"""Layouts: what loads, what each mistake says and where, settings at three levels, regions."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hapticdesk.errors import ConfigError
from hapticdesk.files.profile_reader import load_profile
from hapticdesk.gestures.event import GestureEvent
from hapticdesk.gestures.layout_reader import load_layout
from hapticdesk.gestures.regions import regions_overlap
from hapticdesk.plugin_loading import load_registry
from hapticdesk.runtime.assembly import load_scene_layout

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "layouts"
ACTIONS = {"mqtt", "log", "exec", "http"}


@pytest.mark.parametrize("name", ["buttons.yaml", "living-room.yaml", "demo.yaml"])
def test_shipped_examples_load(name):
    # as `check` and `run` load them: the plugins' actions and sections (living-room's `mqtt:`)
    layout, _ = load_scene_layout(EXAMPLES / name, load_registry(entry_points=False))
    assert layout.bindings and layout.warnings == []
    assert layout.desk.name == "kitamura2017"


def test_buttons_example_is_a_3x3_grid_of_5cm_buttons_8cm_apart():
    layout = load_layout(EXAMPLES / "buttons.yaml", action_names=ACTIONS)
    centres = sorted(
        (round((r.bounds[0] + r.bounds[2]) / 2, 6), round((r.bounds[1] + r.bounds[3]) / 2, 6))
        for r in layout.regions.values()
    )
    assert centres == sorted((x, y) for x in (-0.08, 0, 0.08) for y in (-0.08, 0, 0.08))
    sizes = {
        (round(r.bounds[2] - r.bounds[0], 6), round(r.bounds[3] - r.bounds[1], 6))
        for r in layout.regions.values()
    }
    assert sizes == {(0.05, 0.05)}
    assert [(b.gesture, b.actions[0].name) for b in layout.bindings] == [("tap", "log")] * 9


def error_of(make_layout, text, **kwargs) -> str:
    with pytest.raises(ConfigError) as info:
        make_layout(text, **kwargs)
    return str(info.value)


def at(message: str, line: int, column: int) -> None:
    assert f"layout.yaml:{line}:{column}: " in message, message


GOOD_REGION = "regions:\n  lamp: {rect: [-0.3, -0.2, -0.1, 0]}\n"


@pytest.mark.parametrize(
    ("text", "line", "column", "words"),
    [
        ("colour: red\nbindings: []\n", 2, 1, ["unknown key `colour`", "allowed:", "regions"]),
        ("regions:\n  lamp: {rect: [0, 0, 1]}\nbindings: []\n", 3, 16, ["4 numbers", "found 3"]),
        ("regions:\n  lamp: {rect: [0.1, 0, 0, 0.1]}\nbindings: []\n", 3, 16, ["x0 < x1"]),
        (
            "regions:\n  lamp: {square: [0, 0, 1, 1]}\nbindings: []\n",
            3,
            10,
            ["unknown key `square`", "circle"],
        ),
        (
            "regions:\n  lamp: {rect: [0, 0, 0.1, 0.1], surface: shelf}\nbindings: []\n",
            3,
            43,
            ["surface", "top"],
        ),
        (
            "regions:\n  lamp: {circle: {center: [0, 0], radius: -1}}\nbindings: []\n",
            3,
            43,
            ["> 0"],
        ),
        (
            "regions:\n  lamp: {rect: [0, 0, 0.1, 0.1], axis: z}\nbindings: []\n",
            3,
            40,
            ["x, y or two points"],
        ),
        (
            "regions:\n  2lamp: {rect: [0, 0, 0.1, 0.1]}\nbindings: []\n",
            3,
            3,
            ["start with a letter"],
        ),
        (
            GOOD_REGION + "bindings:\n  - {gesture: tapp, region: lamp, do: log}\n",
            5,
            15,
            ["double_tap", "tap, found"],
        ),
        (
            GOOD_REGION + "bindings:\n  - {gesture: tap, region: lap, do: log}\n",
            5,
            28,
            ["unknown region 'lap'", "lamp"],
        ),
        (
            GOOD_REGION + "bindings:\n  - {gesture: tap, do: log}\n",
            5,
            5,
            ["needs `region`", "lamp"],
        ),
        (
            GOOD_REGION + "bindings:\n  - {gesture: tap, region: lamp, do: mqt}\n",
            5,
            38,
            ["unknown action `mqt`", "mqtt"],
        ),
        (
            GOOD_REGION + "bindings:\n  - {gesture: tap, region: lamp, do: []}\n",
            5,
            38,
            ["names no action"],
        ),
        (GOOD_REGION + "bindings:\n  - {gesture: tap, region: lamp}\n", 5, 5, ["missing `do`"]),
        (
            GOOD_REGION + "bindings:\n  - {gesture: tap, region: lamp, shape: v, do: log}\n",
            5,
            34,
            ["unknown key `shape`", "max_duration_s"],
        ),
        (
            GOOD_REGION
            + "bindings:\n  - {gesture: tap, region: lamp, max_duration_s: 0, do: log}\n",
            5,
            50,
            ["> 0"],
        ),
        (
            GOOD_REGION
            + "bindings:\n  - {gesture: tap, region: lamp, max_duration_s: fast, do: log}\n",
            5,
            50,
            ["must be a number"],
        ),
        (
            GOOD_REGION + "bindings:\n  - {gesture: slide, region: lamp, do: log}\n",
            5,
            30,
            ["no `axis`"],
        ),
        (
            GOOD_REGION + "bindings:\n  - {gesture: stroke, shape: hexagon, do: log}\n",
            5,
            30,
            ["unknown shape 'hexagon'", "circle", "zigzag"],
        ),
        (
            GOOD_REGION + "bindings:\n  - {gesture: swipe, direction: up_left, do: log}\n",
            5,
            33,
            ["directions: 4", "right, up, left, down"],
        ),
        (
            GOOD_REGION + "bindings:\n  - {gesture: press, region: lamp, level: medium, do: log}\n",
            5,
            43,
            ["unknown level 'medium'", "light, firm, hard"],
        ),
        (
            GOOD_REGION
            + "bindings:\n  - {gesture: force, region: lamp, min_n: 10, max_n: 5, do: log}\n",
            5,
            5,
            ["`min_n`", "below `max_n`"],
        ),
        (
            GOOD_REGION + "bindings:\n  - {gesture: force, region: lamp, phase: middle, do: log}\n",
            5,
            43,
            ["begin, update, end"],
        ),
        (
            GOOD_REGION + "settings:\n  tap: {max_move: 0.01, shape: v}\nbindings: []\n",
            5,
            25,
            ["unknown key `shape`"],
        ),
        (
            GOOD_REGION + "settings:\n  stroke: {shape: v}\nbindings: []\n",
            5,
            12,
            ["put it on a `stroke` binding"],
        ),
        (GOOD_REGION + "settings:\n  flick: {}\nbindings: []\n", 5, 3, ["unknown gesture `flick`"]),
        (
            GOOD_REGION
            + "bindings:\n  - {gesture: tap, region: lamp, max_move: 0.01, do: log}\n"
            + "  - {gesture: tap, region: lamp, max_move: 0.02, do: log}\n",
            6,
            44,
            ["binding 1", "must agree"],
        ),
        (GOOD_REGION + "true: 1\nbindings: []\n", 4, 1, ["boolean", "quotes"]),
        (GOOD_REGION + "on: true\nbindings: []\n", 4, 1, ["unknown key `on`", "allowed"]),
        (GOOD_REGION + "bindings: {}\n", 4, 11, ["a list of bindings", "`[]` for none yet"]),
        (
            GOOD_REGION
            + "bindings:\n  - {gesture: tap, region: lamp, do: log}\n"
            + "templates: {z: [missing.csv]}\n",
            6,
            17,
            ["no stroke file or folder `missing.csv`"],
        ),
        (
            GOOD_REGION
            + "bindings:\n  - {gesture: tap, region: lamp, do: log}\ntemplates: {z: [[0, 0]]}\n",
            6,
            16,
            ["at least 2 distinct points"],
        ),
        (
            GOOD_REGION
            + "bindings:\n  - {gesture: press, region: lamp, levels: {soft: 3}, "
            + "hysteresis_n: 4, do: log}\n",
            5,
            69,
            ["below the lowest level"],
        ),
    ],
)
def test_each_mistake_is_reported_where_it_is_with_what_is_allowed(
    make_layout, text, line, column, words
):
    message = error_of(make_layout, text)
    at(message, line, column)
    for word in words:
        assert word in message, message


def test_region_entirely_off_the_desk_suggests_the_unit(make_layout):
    message = error_of(make_layout, "regions:\n  lamp: {rect: [-30, -20, -10, 0]}\nbindings: []\n")
    at(message, 3, 16)
    assert "entirely outside surface `top`" in message and "units: cm" in message
    assert "x -0.375..0.375" in message


def test_region_partly_off_the_desk_is_a_warning(make_layout):
    layout = make_layout(
        "regions:\n  edge: {rect: [0.3, 0, 0.45, 0.1]}\n"
        "bindings:\n  - {gesture: tap, region: edge, do: log}\n"
    )
    assert len(layout.warnings) == 1 and "reaches beyond surface `top`" in layout.warnings[0]


def test_overlapping_regions_binding_the_same_gesture_are_an_error(make_layout):
    text = """
    units: cm
    regions:
      a: {rect: [0, 0, 10, 10]}
      b: {circle: {center: [14, 5], radius: 3}}
      c: {polygon: [[9, 9], [15, 9], [15, 15]]}
    bindings:
      - {gesture: tap, region: a, do: log}
      - {gesture: tap, region: b, do: log}
      - {gesture: long_press, region: a, do: log}
      - {gesture: long_press, region: c, do: log}
    """
    message = error_of(make_layout, text)
    at(message, 11, 35)
    assert "regions `a` and `c` overlap and both bind `long_press`" in message
    # the same regions binding different gestures are fine; so are edges that only touch
    layout = make_layout(text.replace("long_press, region: c", "press, region: c"))
    assert len(layout.bindings) == 4
    layout = make_layout(
        "units: cm\nregions:\n  a: {rect: [0, 0, 10, 10]}\n  b: {rect: [10, 0, 20, 10]}\n"
        "bindings:\n  - {gesture: tap, region: a, do: log}\n"
        "  - {gesture: tap, region: b, do: log}\n"
    )
    assert len(layout.bindings) == 2


def test_overlap_geometry(paper_desk):
    from hapticdesk.gestures.regions import Region, circle_outline

    def rect(x0, y0, x1, y1):
        return Region("r", "rect", "top", 0, np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]]))

    def circle(cx, cy, r):
        return Region(
            "c", "circle", "top", 0, circle_outline(np.array([cx, cy]), r), np.array([cx, cy]), r
        )

    def tri(*pts):
        return Region("p", "polygon", "top", 0, np.array(pts, dtype=float))

    assert regions_overlap(rect(0, 0, 1, 1), rect(0.5, 0.5, 2, 2))
    assert not regions_overlap(rect(0, 0, 1, 1), rect(1, 0, 2, 1))
    assert regions_overlap(circle(0, 0, 1), circle(1.9, 0, 1))
    assert not regions_overlap(circle(0, 0, 1), circle(2.0, 0, 1))
    # the circle's bounding box overlaps the rectangle's corner, the circle does not
    assert not regions_overlap(circle(0, 0, 1), rect(0.75, 0.75, 2, 2))
    assert regions_overlap(circle(0, 0, 1), rect(0.6, 0.6, 2, 2))
    # two triangles that share the diagonal of a square
    assert not regions_overlap(tri((0, 0), (1, 0), (1, 1)), tri((0, 0), (1, 1), (0, 1)))
    assert regions_overlap(tri((0, 0), (1, 0), (1, 1)), tri((0, 0), (1, 0.9), (0, 1)))


def test_units_settings_and_bindings_resolve_at_three_levels(make_layout):
    layout = make_layout(
        """
        units: mm
        regions:
          lamp: {rect: [-300, -200, -100, 0]}
          fan: {circle: {center: [200, 100], radius: 50}}
          dimmer: {rect: [-300, 100, 300, 200], axis: x}
        settings:
          tap: {max_move: 10}
          swipe: {directions: 8}
        bindings:
          - {gesture: tap, region: lamp, max_duration_s: 0.3, do: log}
          - {gesture: tap, region: lamp, do: {mqtt: {topic: a}}}
          - {gesture: tap, region: fan, do: log}
          - {gesture: swipe, min_distance: 80, direction: up_left, do: log}
          - {gesture: slide, region: dimmer, do: log}
        """
    )
    lamp = layout.regions["lamp"]
    assert lamp.bounds == pytest.approx((-0.3, -0.2, -0.1, 0.0))
    assert layout.regions["fan"].radius == pytest.approx(0.05)
    b = layout.bindings
    # binding level, for every binding of the same region; layout level; built-in
    assert b[0].options == {"max_duration_s": 0.3, "max_move": 0.01, "snap": 0.012}
    assert b[1].options == b[0].options
    assert b[2].options == {"max_duration_s": 0.5, "max_move": 0.01, "snap": 0.012}
    assert b[3].options["min_distance"] == pytest.approx(0.08)
    assert b[3].options["directions"] == 8 and b[3].options["direction"] == ("up_left",)
    assert b[3].options["max_duration_s"] == 0.8
    assert b[4].options["phase"] is None
    assert layout.options_for("tap", "lamp")["max_duration_s"] == 0.3
    assert layout.options_for("tap", None)["max_duration_s"] == 0.5
    assert b[1].actions[0].name == "mqtt" and b[1].actions[0].options == {"topic": "a"}
    assert set(layout.settings) == {"tap", "swipe", "slide"}


def test_do_accepts_a_mapping_a_list_or_a_name_and_validates_each_action(make_layout):
    seen = []

    def validate(name, options, position):
        seen.append((name, options, position.line, position.column))
        if name == "exec" and not options.get("argv"):
            raise ConfigError(position, "exec needs `argv`")

    layout = make_layout(
        GOOD_REGION
        + "bindings:\n"
        + "  - gesture: tap\n    region: lamp\n    do:\n      - log\n"
        + "      - {mqtt: {topic: t}, http: {url: 'http://127.0.0.1:1/'}}\n",
        validate_action=validate,
    )
    assert [a.name for a in layout.bindings[0].actions] == ["log", "mqtt", "http"]
    assert seen == [
        ("log", None, 8, 9),
        ("mqtt", {"topic": "t"}, 9, 16),
        ("http", {"url": "http://127.0.0.1:1/"}, 9, 34),
    ]
    message = error_of(
        make_layout,
        GOOD_REGION + "bindings:\n  - {gesture: tap, region: lamp, do: {exec: {}}}\n",
        validate_action=validate,
    )
    at(message, 5, 45)
    assert "exec needs `argv`" in message


def test_a_section_a_plugin_claims_is_kept_raw_and_handed_to_its_validator(make_layout):
    text = (
        GOOD_REGION
        + "desk_name: study\nmqtt: {url: 'mqtt://127.0.0.1:1883', anything: [1, 2]}\n"
        + "bindings:\n  - {gesture: tap, region: lamp, do: log}\n"
    )
    seen = []
    layout = make_layout(
        text,
        section_names=["mqtt"],
        validate_section=lambda *args: seen.append(args),
    )
    assert layout.desk_name == "study"
    assert layout.raw["mqtt"] == {"url": "mqtt://127.0.0.1:1883", "anything": [1, 2]}
    [(name, value, position, path)] = seen
    assert (name, value, position.line, path) == ("mqtt", layout.raw["mqtt"], 5, layout.path)
    with pytest.raises(ConfigError, match=r":5:1: unknown key `mqtt` in the layout"):
        make_layout(text)  # no plugin claimed it


def test_the_desk_name_defaults_to_the_profile_name_and_is_checked(make_layout):
    layout = make_layout(GOOD_REGION + "bindings:\n  - {gesture: tap, region: lamp, do: log}\n")
    assert layout.desk_name == layout.desk.name == "kitamura2017"
    with pytest.raises(ConfigError, match=r":\d+:\d+: `desk_name` must be letters"):
        make_layout(
            GOOD_REGION + "desk_name: a/b\nbindings: [{gesture: tap, region: lamp, do: log}]\n"
        )


def test_desk_from_the_layout_relative_path_or_override(write_layout, tmp_path, paper_desk):
    shelf_text = (Path(load_profile("kitamura2017-shelf").path)).read_text()
    (tmp_path / "desks").mkdir()
    (tmp_path / "desks" / "mine.yaml").write_text(shelf_text.replace("kitamura2017-shelf", "mine"))
    path = write_layout(
        "desk: desks/mine.yaml\nregions:\n  s: {rect: [-0.1, 0.3, 0.1, 0.35], surface: shelf}\n"
        "bindings:\n  - {gesture: tap, region: s, do: log}\n"
    )
    layout = load_layout(path)
    assert layout.desk.name == "mine" and layout.regions["s"].surface_index == 1
    # --desk replaces the layout's desk: the paper's desk has no shelf
    with pytest.raises(ConfigError, match="shelf"):
        load_layout(path, profile=paper_desk)
    missing = write_layout("desk: nowhere\nbindings:\n  - {gesture: swipe, do: log}\n", "m.yaml")
    with pytest.raises(ConfigError, match=r"m\.yaml:1:7: desk `nowhere`: no such desk profile"):
        load_layout(missing)
    with pytest.raises(ConfigError, match="missing `desk`"):
        load_layout(write_layout("bindings:\n  - {gesture: swipe, do: log}\n", "n.yaml"))


def test_user_templates_from_files_folders_and_inline_points(write_layout, tmp_path):
    folder = tmp_path / "strokes" / "zed"
    folder.mkdir(parents=True)
    (folder / "1.csv").write_text("x,y,t\n0,1,0\n1,1,0.1\n0,0,0.2\n1,0,0.3\n")
    (folder / "2.json").write_text('{"points": [[0, 1], [1, 1], [0, 0], [1, 0.1]]}')
    (tmp_path / "hook.csv").write_text("x,y\n0,0\n0,1\n1,1\n")
    path = write_layout(
        """
        desk: kitamura2017
        units: cm
        templates:
          zed: [strokes/zed]
          hook: hook.csv
          ell: [[0, 10], [0, 0], [5, 0]]
          mixed: [hook.csv, [[0, 0], [3, 0]]]
        bindings:
          - {gesture: stroke, shape: [zed, ell, circle], do: log}
        """
    )
    layout = load_layout(path)
    assert {k: len(v) for k, v in layout.templates.items()} == {
        "zed": 2,
        "hook": 1,
        "ell": 1,
        "mixed": 2,
    }
    assert layout.templates["ell"][0] == pytest.approx(np.array([[0, 0.1], [0, 0], [0.05, 0]]))
    assert layout.template_dir == (tmp_path / "strokes").resolve()
    # a folder of shapes, as `strokes record` fills it
    path2 = write_layout(
        "desk: kitamura2017\ntemplates: strokes\n"
        "bindings:\n  - {gesture: stroke, shape: zed, do: log}\n",
        "folder.yaml",
    )
    assert list(load_layout(path2).templates) == ["zed"]
    (tmp_path / "bad.csv").write_text("x,y\n0,0\n1,oops\n")
    bad = write_layout(
        "desk: kitamura2017\ntemplates: {b: bad.csv}\nbindings:\n  - {gesture: stroke, do: log}\n",
        "bad.yaml",
    )
    with pytest.raises(ConfigError, match=r"bad\.yaml:2:16: template .*bad\.csv:3: not a number"):
        load_layout(bad)


def test_region_contains_and_slider_value(make_layout):
    layout = make_layout(
        """
        units: cm
        regions:
          tri: {polygon: [[0, 0], [10, 0], [0, 10]]}
          dial: {circle: {center: [-10, -10], radius: 5}}
          diag: {rect: [-30, 0, -20, 10], axis: [[-30, 10], [-20, 0]]}
          vert: {rect: [20, -20, 30, 20], axis: y}
        bindings:
          - {gesture: slide, region: diag, do: log}
          - {gesture: slide, region: vert, do: log}
        """
    )
    r = layout.regions
    x = np.array([0.01, 0.06, 0.0, 0.1, -0.1, -0.14, -0.16])
    y = np.array([0.01, 0.06, 0.1, 0.0, -0.1, -0.1, -0.1])
    assert r["tri"].contains(x, y).tolist() == [True, False, True, True, False, False, False]
    assert r["dial"].contains(x, y).tolist() == [False, False, False, False, True, True, False]
    assert r["diag"].value_along(
        np.array([-0.3, -0.25, -0.2, -0.5]), np.array([0.1, 0.05, 0.0, 0.5])
    ) == pytest.approx([0, 0.5, 1, 0])
    assert r["vert"].value_along(0.25, np.array([-0.2, 0.0, 0.2, 0.3])) == pytest.approx(
        [0, 0.5, 1, 1]
    )


def test_binding_matches_by_gesture_region_and_filters(make_layout):
    layout = make_layout(
        GOOD_REGION
        + """
        bindings:
          - {gesture: stroke, shape: circle, do: log}
          - {gesture: stroke, region: lamp, do: log}
          - {gesture: tap, region: lamp, do: log}
          - {gesture: slide, region: dimmer, phase: end, do: log}
        """.replace("        ", "")
        .replace("regions:", "")
        .replace("bindings:", "  dimmer: {rect: [-0.3, 0.1, 0.3, 0.2], axis: x}\nbindings:")
    )
    b = layout.bindings
    circle_anywhere = GestureEvent(1.0, "stroke", None, 0, 0, shape="circle", score=0.9)
    v_in_lamp = GestureEvent(1.0, "stroke", "lamp", 0, 0, shape="v", score=0.9)
    rejected = GestureEvent(1.0, "stroke", "lamp", 0, 0, shape=None, score=0.5)
    assert [x.matches(circle_anywhere) for x in b] == [True, False, False, False]
    assert [x.matches(v_in_lamp) for x in b] == [False, True, False, False]
    assert [x.matches(rejected) for x in b] == [False, False, False, False]
    assert b[2].matches(GestureEvent(1.0, "tap", "lamp", 0, 0))
    assert not b[2].matches(GestureEvent(1.0, "tap", "fan", 0, 0))
    assert b[3].matches(GestureEvent(1.0, "slide", "dimmer", 0, 0, value=1.0, phase="end"))
    assert not b[3].matches(GestureEvent(1.0, "slide", "dimmer", 0, 0, value=1.0, phase="update"))


def test_builtin_templates_can_be_switched_off(write_layout):
    def layout(text: str) -> Path:
        return write_layout("desk: kitamura2017\n" + text)

    own = "templates: {ell: [[[0, 1], [0, 0], [1, 0]]]}\n"
    off = load_layout(
        layout(
            own
            + "builtin_templates: false\nbindings:\n  - {gesture: stroke, shape: ell, do: log}\n"
        )
    )
    assert off.builtin_templates is False
    from hapticdesk.gestures.recognizers.stroke import StrokeRecognizer

    recognizer = StrokeRecognizer(off, off.bindings)
    assert recognizer.templates.shapes == ["ell"]
    bind = "bindings:\n  - {gesture: stroke, do: log}\n"
    assert load_layout(layout(own + bind)).builtin_templates is True
    cases = {
        own
        + "builtin_templates: false\nbindings:\n  - {gesture: stroke, shape: circle, do: log}\n": (
            r"circle"
        ),
        "builtin_templates: false\nbindings:\n  - {gesture: stroke, do: log}\n": (
            r":2:20: `builtin_templates: false` needs shapes under `templates:`"
        ),
        own
        + "builtin_templates: nope\n"
        + bind: r":3:20: `builtin_templates` is true or false, found 'nope'",
    }
    for text, message in cases.items():
        with pytest.raises(ConfigError, match=message):
            load_layout(layout(text))
