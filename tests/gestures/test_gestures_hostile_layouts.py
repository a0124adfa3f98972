"""Hostile and broken files: `hapticdesk check` ends at once with file:line:column, never a
traceback, however the file was made (issue 11: alias bombs, huge numbers, wrong encodings,
deep nesting, unhashable values, huge files, self-crossing polygons, costly templates)."""

from __future__ import annotations

import re
import time
from pathlib import Path

import pytest

from hapticdesk.cli import main
from hapticdesk.errors import ConfigError
from hapticdesk.files.profile_reader import load_profile
from hapticdesk.files.yamlfile import load_marked_yaml
from hapticdesk.hookspecs import hookimpl
from hapticdesk.sim.scene import load_scene

PROFILES = Path(__file__).resolve().parents[2] / "profiles"

TAP = "bindings:\n  - {gesture: tap, region: a, do: log}\n"
REGION_A = "regions: {a: {rect: [0, 0, 0.1, 0.1]}}\n"


def billion_laughs(levels: int = 9) -> str:
    """Ten aliases per level: 10**levels values once expanded, a few hundred bytes written."""
    lines = ["lol0: &lol0 [lol]"]
    for i in range(1, levels + 1):
        lines.append(f"lol{i}: &lol{i} [{', '.join([f'*lol{i - 1}'] * 10)}]")
    return "\n".join(lines) + "\n"


# name -> (file content, (line, column) of the error, words the message must hold)
HOSTILE: dict[str, tuple[bytes, tuple[int, int], str]] = {
    "alias bomb": (
        ("desk: kitamura2017\n" + billion_laughs() + TAP).encode(),
        (7, 21),
        "more than 50000 values with its aliases expanded",
    ),
    "recursive alias": (
        b"desk: kitamura2017\nbindings: &b [*b]\n",
        (2, 15),
        "alias *b refers to the value that holds it",
    ),
    "400-digit integer": (
        (
            "desk: kitamura2017\nregions: {a: {rect: [0, 0, 0.1, " + "9" * 400 + "]}}\n" + TAP
        ).encode(),
        (2, 33),
        "a number of 400 characters; numbers here have at most 32",
    ),
    "Latin-1": (
        "desk: kitamura2017\n# the café light\n".encode("latin-1") + TAP.encode(),
        (2, 10),
        "not UTF-8 text: byte 0xe9",
    ),
    "UTF-16": (("desk: kitamura2017\n" + TAP).encode("utf-16"), (1, 1), "UTF-16"),
    "binary": (bytes(range(256)) * 4, (1, 1), "a NUL byte: this is a binary file"),
    "control character": (b"desk: kitamura2017\nbindings: \x07\n", (2, 11), "not allowed"),
    "20 000 open brackets": (
        b"desk: kitamura2017\nbindings: " + b"[" * 20_000 + b"\n",
        # at the 65th bracket, or at libyaml's 1000th (from PyYAML 6.0.4 it scans a line ahead)
        (2, (74, 1010)),
        "nest more than 64 deep",
    ),
    "a region given as a list": (
        ("desk: kitamura2017\n" + REGION_A + TAP.replace("region: a", "region: [a]")).encode(),
        (4, 28),
        "`region` of binding 1 (`tap`) is one region's name (one of: a), found ['a']",
    ),
    "a list as a key": (b"desk: kitamura2017\n? [a]\n: 1\n", (2, 3), "keys must be text"),
    "a set": (b"desk: kitamura2017\nbindings: !!set {a}\n", (2, 11), "!!set is not read"),
    "a self-crossing polygon": (
        b"desk: kitamura2017\nregions:\n"
        b"  bow: {polygon: [[0, 0], [0.1, 0.1], [0.1, 0], [0, 0.1]]}\n"
        + TAP.replace("region: a", "region: bow").encode(),
        (3, 19),
        "`polygon` of region `bow` crosses itself: the edge from point 1 crosses the edge "
        "from point 3",
    ),
    "a circle of radius 1e200 (its outline overflowed into a crash)": (
        (
            "desk: kitamura2017\nunits: cm\nregions:\n"
            "  a: {circle: {center: [0, 0], radius: 1e200}}\n" + TAP
        ).encode(),
        (4, 15),
        "region `a` reaches 1e+200 cm from the desk's origin; a region lies within 10000 cm",
    ),
    "a rect to 1e308 (an overflow warning, then `OK`)": (
        ("desk: kitamura2017\nregions: {a: {rect: [0, 0, 1e308, 0.1]}}\n" + TAP).encode(),
        (2, 21),
        "region `a` reaches 1e+308 m from the desk's origin",
    ),
    "a polygon at 1e200 (overflow warnings before its error)": (
        (
            "desk: kitamura2017\nregions:\n  a: {polygon: [[0, 0], [1e200, 0], [0, 1e200]]}\n" + TAP
        ).encode(),
        (3, 16),
        "region `a` reaches 1e+200 m from the desk's origin",
    ),
    "a slider axis to 1e300": (
        b"desk: kitamura2017\nregions:\n"
        b"  a: {rect: [0, 0, 0.1, 0.1], axis: [[0, 0], [1e300, 0]]}\n"
        b"bindings:\n  - {gesture: slide, region: a, do: log}\n",
        (3, 37),
        "the `axis` of region `a` reaches 1e+300 m",
    ),
    "a long press repeating every 1e-300 s (an event every sample)": (
        (
            "desk: kitamura2017\n" + REGION_A + "bindings:\n  - {gesture: long_press, region: a, "
            "repeat: true, interval_s: 1e-300, do: log}\n"
        ).encode(),
        (4, 64),
        "`interval_s` in binding 1 (`long_press`) must be >= 0.02, found 1e-300",
    ),
    # the fuzzing pass: forces and lengths had no upper bound (a slider's full scale at 1e300 N)
    "a press level of 1e300 N": (
        (
            "desk: kitamura2017\n" + REGION_A + "bindings:\n  - {gesture: press, region: a, "
            "levels: {light: 1e300}, do: log}\n"
        ).encode(),
        (4, 49),
        "`light` in `levels` of binding 1 (`press`) must be <= 10000, found 1e+300",
    ),
    "a force slider's full scale at 1e300 N": (
        (
            "desk: kitamura2017\n" + REGION_A + "bindings:\n  - {gesture: force, region: a, "
            "max_n: 1e300, do: log}\n"
        ).encode(),
        (4, 40),
        "must be <= 10000, found 1e+300; expected >= 0 and <= 10000",
    ),
    "a tap that may move 1e300 mm": (
        (
            b"desk: kitamura2017\nunits: mm\nregions: {a: {rect: [0, 0, 100, 100]}}\n"
            b"bindings:\n  - {gesture: tap, region: a, max_move: 1e300, do: log}\n"
        ),
        (5, 41),
        "must be <= 100000, found 1e+300; expected > 0 and <= 100000",
    ),
    "a payload template that fails on every event": (
        (
            "desk: kitamura2017\n" + REGION_A + "bindings:\n  - {gesture: tap, region: a, do: "
            "{mqtt: {topic: t, payload: {v: '{{ \"a\" * 10**10 }}'}}}}\n"
        ).encode(),
        (4, 66),
        "too costly to render for an event: repeating would make 10000000000 characters",
    ),
    "a file of 50 MB": (
        b"k: 1\n" * 10_000_000,
        (1, 1),
        "larger than 1 MB",
    ),
    "a file of many small keys under the size limit": (
        ("desk: kitamura2017\n" + "".join(f"k{i}: {i}\n" for i in range(120_000)))[
            : 1_000_000
            - 10  # just under the 1 MB limit
        ].encode(),
        (25_000, 9),
        "more than 50000 values by here",
    ),
}


@pytest.fixture(autouse=True)
def _no_installed_plugins(monkeypatch):
    monkeypatch.setenv("HAPTICDESK_DISABLE_PLUGIN_AUTOLOAD", "1")


@pytest.mark.parametrize("name", list(HOSTILE))
def test_check_ends_at_once_with_the_place_and_no_traceback(name, tmp_path, capsys):
    content, (line, column), words = HOSTILE[name]
    layout = tmp_path / "hostile.yaml"
    layout.write_bytes(content)
    main(["check", str(tmp_path / "missing.yaml")])  # import and load the plugins first
    capsys.readouterr()
    started = time.process_time()  # CPU time: other work on the machine does not count
    assert main(["check", str(layout)]) == 2
    elapsed = time.process_time() - started
    err = capsys.readouterr().err
    columns = column if isinstance(column, tuple) else (column,)
    assert any(
        err.startswith(f"hapticdesk check: error: {layout}:{line}:{at}: ") for at in columns
    ), err[:300]
    assert words in err
    assert "Traceback" not in err and err.count("\n") == 1
    assert elapsed < 1.0, f"{name}: {elapsed:.2f} s"


def test_a_bad_profile_and_a_bad_scene_are_refused_the_same_way(tmp_path):
    profile = tmp_path / "bomb.yaml"
    profile.write_text((PROFILES / "kitamura2017.yaml").read_text() + billion_laughs())
    with pytest.raises(ConfigError, match=r"bomb\.yaml:\d+:\d+: the file holds more than"):
        load_profile(profile)
    scene = tmp_path / "scene.yaml"
    scene.write_bytes(b"desk: kitamura2017\ntimeline: " + b"{a: " * 5_000 + b"\n")
    with pytest.raises(ConfigError, match=r"scene\.yaml:2:\d+: lists and mappings nest more"):
        load_scene(scene)


def test_unicode_is_read_and_positions_count_characters(tmp_path):
    """The strict decoding still reads UTF-8 (with or without a byte-order mark), and a
    column after a non-ASCII character counts characters, not bytes."""
    path = tmp_path / "u.yaml"
    path.write_bytes("\ufeffname: Café\nlamp: ☀\n".encode())
    assert load_marked_yaml(path) == {"name": "Café", "lamp": "☀"}
    path.write_bytes("a: ☀☀\nb: ok\x07\n".encode())
    with pytest.raises(ConfigError, match=r"u\.yaml:2:6: not valid YAML: character"):
        load_marked_yaml(path)


def test_aliases_within_the_limit_still_work(tmp_path):
    path = tmp_path / "a.yaml"
    path.write_text(billion_laughs(3) + "base: &b {x: 1}\nmerged: {<<: *b, y: 2}\n")
    doc = load_marked_yaml(path)
    assert len(doc["lol3"]) == 10 and doc["lol3"][9][9] == [["lol"]] * 10
    assert doc["merged"] == {"x": 1, "y": 2}
    assert doc["lol3"][0] is not doc["lol3"][1]  # expanded, so validators may annotate freely


def test_a_merged_key_is_overridden_by_one_written_as_yaml_says(tmp_path):
    """`{<<: *base, rect: …}` was refused: "key `rect` appears twice" (YAML's merge key: a
    key written overrides a merged one; of merged mappings the earlier wins). A key written
    twice in one mapping is still an error."""
    path = tmp_path / "m.yaml"
    path.write_text(
        "a: &a {rect: [0, 0, 1, 1], surface: top}\n"
        "b: &b {rect: [5, 5, 6, 6], axis: x}\n"
        "c: {<<: *a, rect: [2, 2, 3, 3]}\n"
        "d: {<<: [*a, *b]}\n"
    )
    doc = load_marked_yaml(path)
    assert doc["c"] == {"rect": [2, 2, 3, 3], "surface": "top"}
    assert doc["c"].where("rect").line == 3
    assert doc["d"] == {"rect": [0, 0, 1, 1], "surface": "top", "axis": "x"}
    path.write_text("a: &a {x: 1}\nc: {<<: *a, y: 2, y: 3}\n")
    with pytest.raises(ConfigError, match=r"m\.yaml:2:19: key `y` appears twice"):
        load_marked_yaml(path)


def test_a_warning_is_printed_once(tmp_path, capsys, caplog, monkeypatch):
    """A failing plugin's warning was logged by the registry and printed again by check."""
    import hapticdesk.plugin_loading as registry_module

    class Broken:
        @hookimpl
        def register_actions(self, register):
            raise RuntimeError("no actions today")

    real = registry_module.load_registry
    monkeypatch.setattr(
        registry_module,
        "load_registry",
        lambda **kw: real(**kw, plugins=[("broken", Broken())]),
    )
    layout = tmp_path / "wide.yaml"  # a region reaching beyond the desk: a layout warning
    layout.write_text(
        "desk: kitamura2017\nregions: {a: {rect: [0.3, 0.1, 0.5, 0.2]}}\n"
        "bindings:\n  - {gesture: tap, region: a, do: log}\n"
    )
    assert main(["check", str(layout)]) == 0
    captured = capsys.readouterr()
    shown = captured.out + captured.err + "\n".join(r.getMessage() for r in caplog.records)
    assert len(re.findall("no actions today", shown)) == 1
    assert len(re.findall("reaches beyond surface `top`", shown)) == 1


def test_a_region_on_a_desk_without_surfaces_is_refused_at_the_region(tmp_path, capsys):
    # a layout for a desk, checked against the bare-sensor profile (nothing to touch): an
    # IndexError before (the layout naming that desk itself was refused at its `desk:`)
    layout = tmp_path / "layout.yaml"
    layout.write_text("desk: kitamura2017\n" + REGION_A + TAP)
    assert main(["check", str(layout), "--desk", str(PROFILES / "ati-bench.yaml")]) == 2
    err = capsys.readouterr().err
    assert re.search(r"layout.yaml:2:\d+: region `a`: the desk `ati-bench` has no surfaces", err)
    assert "Traceback" not in err


@pytest.mark.parametrize(
    "bad",
    [
        "units: {long}\n" + REGION_A,  # a choice
        REGION_A + TAP.replace("region: a", "region: {long}"),  # a region's name
        REGION_A + TAP.replace("do: log", "do: {long}"),  # an action's name
        REGION_A + "bindings: {long}\n",  # a value of the wrong kind, quoted whole
    ],
    ids=["a choice", "a region's name", "an action's name", "a value of the wrong kind"],
)
def test_an_error_quoting_a_huge_value_stays_one_short_line(bad, tmp_path, capsys):
    """An error quotes what it found; a 500 kB value was printed whole, a line of 500 kB."""
    layout = tmp_path / "long.yaml"
    layout.write_text("desk: kitamura2017\n" + bad.replace("{long}", "x" * 500_000))
    assert main(["check", str(layout)]) == 2
    err = capsys.readouterr().err
    assert re.match(rf"hapticdesk check: error: {re.escape(str(layout))}:\d+:\d+: `?\w", err)
    assert err.count("\n") == 1 and len(err) < 1_200, len(err)
    assert "characters left out" in err
