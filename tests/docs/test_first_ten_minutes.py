"""The first ten minutes of a new user (issue 32): `init` starts a layout from nothing, an empty
layout is a warning not an error, a missing extra names its install command, the `log` action
prints one line per gesture, and `strokes classify` says why a folder of a shape no template
knows is all rejected. (That the demo says nothing alarming: tests/runtime/test_runtime_run.py.)"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import pytest

from hapticdesk.cli import main
from hapticdesk.gestures.event import GestureEvent
from hapticdesk.runtime.dispatcher import ActionContext

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"


# --- init -----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "desk", ["kitamura2017", "kitamura2017-panel", "kitamura2017-shelf", "kitamura2017-accel"]
)
@pytest.mark.parametrize("blank", [False, True])
def test_init_writes_a_layout_check_takes_for_each_shipped_desk(tmp_path, capsys, desk, blank):
    layout = tmp_path / "my-desk.yaml"
    assert main(["init", str(layout), "--desk", desk, *(["--blank"] if blank else [])]) == 0
    said = capsys.readouterr().out
    assert f"wrote {layout}: a layout for desk {desk}" in said
    assert f"hapticdesk ui --layout {layout}" in said  # what to do next
    assert main(["check", str(layout)]) == 0
    checked = capsys.readouterr().out
    assert checked.startswith(f"OK: {layout} is a valid layout")
    if blank:
        assert "regions   0" in checked and "bindings  0" in checked
        assert "warning: " in checked and "no bindings yet" in checked
    else:
        assert "button" in checked and "1. tap in button → log" in checked
        assert "warning" not in checked
    text = layout.read_text(encoding="utf-8")
    assert text.startswith("# A layout for hapticdesk")  # a commented start


def test_init_never_overwrites_without_force(tmp_path, capsys):
    layout = tmp_path / "mine.yaml"
    layout.write_text("# my work\n", encoding="utf-8")
    assert main(["init", str(layout)]) == 2
    assert "already exists" in capsys.readouterr().err
    assert layout.read_text(encoding="utf-8") == "# my work\n"
    assert main(["init", str(layout), "--force"]) == 0
    assert "desk: kitamura2017" in layout.read_text(encoding="utf-8")


def test_init_names_a_desk_file_relative_to_the_layout(tmp_path, capsys, monkeypatch):
    desks = tmp_path / "desks"
    desks.mkdir()
    (desks / "three.yaml").write_text(
        (EXAMPLES / "desks" / "three-legs.yaml").read_text("utf-8"), encoding="utf-8"
    )
    monkeypatch.chdir(tmp_path)
    assert main(["init", "layout.yaml", "--desk", "desks/three.yaml", "--units", "mm"]) == 0
    text = (tmp_path / "layout.yaml").read_text(encoding="utf-8")
    assert "desk: desks/three.yaml" in text and "units: mm" in text
    capsys.readouterr()
    assert main(["check", "layout.yaml"]) == 0
    assert "three-legs" in capsys.readouterr().out


def test_init_refuses_a_desk_with_nothing_to_touch(tmp_path, capsys):
    assert main(["init", str(tmp_path / "x.yaml"), "--desk", "ati-bench"]) == 2
    assert "has no surfaces" in capsys.readouterr().err
    assert not (tmp_path / "x.yaml").exists()


def test_a_layout_with_no_bindings_runs_and_does_nothing(tmp_path, capsys):
    layout = tmp_path / "blank.yaml"
    layout.write_text("desk: kitamura2017\nunits: cm\nregions: {}\nbindings: []\n", "utf-8")
    scene = tmp_path / "tap.yaml"
    scene.write_text(
        "desk: kitamura2017\nunits: cm\nquiet_s: 1.5\ntimeline:\n  - tap: {point: [0, 0]}\n"
    )
    events = tmp_path / "ev.jsonl"
    argv = ["run", "--layout", str(layout), "--source", f"sim:{scene}", "--speed", "0"]
    assert main([*argv, "--events", str(events)]) == 0
    assert events.read_text(encoding="utf-8") == ""
    assert "0 gestures" in capsys.readouterr().err


# --- a missing extra ------------------------------------------------------------------------


def test_check_png_without_matplotlib_names_the_plot_extra(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # as if not installed
    layout = EXAMPLES / "layouts" / "buttons.yaml"
    assert main(["check", str(layout), "--png", str(tmp_path / "b.png")]) == 1
    err = capsys.readouterr().err
    assert "matplotlib is not installed" in err
    assert "pip install 'hapticdesk[plot]'" in err
    assert "No module named" not in err and "unexpected" not in err


def test_the_page_without_its_extra_names_the_ui_extra(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "starlette", None)
    assert main(["ui", "--layout", str(tmp_path / "new.yaml")]) == 2
    assert "pip install 'hapticdesk[ui]'" in capsys.readouterr().err
    assert not (tmp_path / "new.yaml").exists()  # nothing written before the refusal
    layout = EXAMPLES / "layouts" / "buttons.yaml"
    scene = EXAMPLES / "scenes" / "buttons.yaml"
    run = ["run", "--layout", str(layout), "--source", f"sim:{scene}", "--speed", "0"]
    assert main([*run, "--ui", "0"]) == 2
    assert "pip install 'hapticdesk[ui]'" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("module", "extra"),
    [("matplotlib.pyplot", "plot"), ("amqtt.broker", "demo"), ("uvicorn", "ui"), ("ruamel", "ui")],
)
def test_each_optional_module_is_named_with_its_extra(module, extra):
    from hapticdesk.extras import install_hint

    hint = install_hint(module)
    assert hint is not None and hint.endswith(f"pip install 'hapticdesk[{extra}]'")


def test_a_module_no_extra_brings_is_not_given_a_made_up_hint():
    from hapticdesk.extras import install_hint

    assert install_hint("no_such_module_anywhere") is None
    assert install_hint("numpy") is None  # a dependency, not an extra: a broken install


# --- the log action -------------------------------------------------------------------------


def _log(options: dict[str, Any]) -> Any:
    from hapticdesk.plugins.log import LogAction

    return LogAction(options, ActionContext("study"))


def _slide(phase: str, value: float, t: float) -> GestureEvent:
    return GestureEvent(t, "slide", "dimmer", 0.0, 0.15, value=value, phase=phase)


def _run_a_slide_and_a_tap(action: Any) -> None:
    action(GestureEvent(0.5, "tap", "lamp", -0.2, -0.1, force_n=4.0))
    action(_slide("begin", 0.1, 1.0))
    for k in range(1, 41):
        action(_slide("update", 0.1 + k * 0.016, 1.0 + k * 0.05))
    action(_slide("end", 0.74, 3.1))


def test_log_prints_one_line_per_gesture_a_slides_updates_counted(capsys):
    _run_a_slide_and_a_tap(_log({}))
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 3  # the tap, the slide's begin, its end (not 40 updates)
    events = [json.loads(line.split("] ", 1)[1]) for line in lines]
    assert [(e["gesture"], e.get("phase")) for e in events] == [
        ("tap", None),
        ("slide", "begin"),
        ("slide", "end"),
    ]
    assert "updates" not in events[1] and events[2]["updates"] == 40
    assert all(line.startswith("[study] ") for line in lines)


def test_log_with_a_message_says_the_updates_after_it(capsys):
    _run_a_slide_and_a_tap(_log({"message": "{{ region }} {{ gesture }} {{ phase }}"}))
    assert capsys.readouterr().out.splitlines() == [
        "[study] lamp tap None",
        "[study] dimmer slide begin",
        "[study] dimmer slide end (40 updates, value 0.74)",
    ]


def test_log_updates_every_prints_each(capsys):
    _run_a_slide_and_a_tap(_log({"updates": "every"}))
    assert len(capsys.readouterr().out.splitlines()) == 1 + 1 + 40 + 1


def test_log_shows_the_first_update_of_a_binding_that_takes_no_begin(capsys):
    action = _log({"message": "{{ value }}"})
    for k in range(5):
        action(_slide("update", 0.2 + k / 10, 1.0 + k / 10))
    action(_slide("cancel", 0.6, 2.0))
    assert capsys.readouterr().out.splitlines() == [
        "[study] 0.2",
        "[study] 0.6 (4 updates, value 0.60)",
    ]


def test_log_refuses_an_updates_value_it_does_not_know():
    from hapticdesk.errors import ConfigError
    from hapticdesk.plugins.log import validate

    with pytest.raises(ConfigError, match="summary, every"):
        validate({"updates": "some"}, "layout.yaml:3:9")


# --- strokes classify -----------------------------------------------------------------------


def test_classifying_a_folder_of_a_shape_no_template_knows_says_why(capsys):
    zed = EXAMPLES / "strokes" / "zed"
    assert main(["strokes", "classify", str(zed), "--json"]) == 0
    out, err = capsys.readouterr()
    rows = [json.loads(line) for line in out.splitlines()]
    assert len(rows) == 3 and all(r["shape"] is None for r in rows)  # Z is no built-in shape
    assert "`zed` is not a shape the templates know" in err
    assert f"--templates {zed.parent}" in err
    assert main(["strokes", "classify", str(zed), "--templates", str(zed.parent), "--json"]) == 0
    out, err = capsys.readouterr()
    assert [json.loads(line)["shape"] for line in out.splitlines()] == ["zed"] * 3
    assert err == ""
