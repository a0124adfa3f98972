"""The layouts a layout names under ``layouts:`` (those a running desk switches to) are
checked by ``check``, and by ``run`` as it starts, as the switch would load them: ``check``
said OK for a named layout the switch then refused, hours into the run."""

from __future__ import annotations

from pathlib import Path

import pytest

from hapticdesk.cli import main

MAIN = """\
desk: kitamura2017
layouts: {evening: evening.yaml}
regions:
  lamp: {rect: [-0.1, -0.1, 0.1, 0.1]}
bindings:
  - {gesture: tap, region: lamp, do: log}
"""
EVENING = "desk: %s\n%sbindings:\n  - {gesture: %s, shape: circle, do: log}\n"


def _layouts(tmp_path: Path, evening: str) -> Path:
    (tmp_path / "evening.yaml").write_text(evening)
    path = tmp_path / "main.yaml"
    path.write_text(MAIN)
    return path


@pytest.mark.parametrize(
    ("evening", "said"),
    [
        (
            EVENING % ("kitamura2017", "", "strok"),
            "evening.yaml:3:15: `gesture` in binding 1 must be one of",
        ),
        (
            EVENING % ("kitamura2017-panel", "", "stroke"),
            "evening.yaml: the layout is for desk `kitamura2017-panel` but this run senses "
            "desk `kitamura2017`",
        ),
        (
            EVENING % ("kitamura2017", "desk_name: study\n", "stroke"),
            "evening.yaml: the layout names the desk `study` but this run is `kitamura2017`",
        ),
    ],
    ids=["unknown-gesture", "another-desk", "another-desk-name"],
)
def test_check_refuses_a_named_layout_the_switch_would_refuse(tmp_path, capsys, evening, said):
    path = _layouts(tmp_path, evening)
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(
        f"hapticdesk check: error: {path}:2:20: `layouts.evening` would be refused when the "
        f"desk switches to it: {tmp_path / said}"
    ), err
    assert err.count("\n") == 1 and "Traceback" not in err


def test_run_refuses_it_as_it_starts_as_check_does(tmp_path, capsys):
    """One rule for both: `check` passing means `run` starts (it refuses before the source
    is opened, as for any layout error)."""
    path = _layouts(tmp_path, EVENING % ("kitamura2017", "", "strok"))
    scene = tmp_path / "scene.yaml"
    scene.write_text("name: s\ndesk: kitamura2017\ntimeline:\n  - idle: 0.1\n")
    assert main(["check", str(path)]) == 2
    checked = capsys.readouterr().err
    assert main(["run", "--layout", str(path), "--source", f"sim:{scene}", "--speed", "0"]) == 2
    ran = capsys.readouterr().err
    assert ran == checked.replace("hapticdesk check:", "hapticdesk run:")


def test_check_passes_named_layouts_the_switch_takes(tmp_path, capsys):
    path = _layouts(tmp_path, EVENING % ("kitamura2017", "", "stroke"))
    assert main(["check", str(path)]) == 0
    assert capsys.readouterr().out.startswith(f"OK: {path} is a valid layout")
