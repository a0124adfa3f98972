"""`hapticdesk check`: the verdict, the summary, the drawing, and errors with positions."""

from __future__ import annotations

from pathlib import Path

from hapticdesk.cli import main

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "layouts"


def test_check_explains_a_valid_layout(capsys):
    assert main(["check", str(EXAMPLES / "living-room.yaml")]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"OK: {EXAMPLES / 'living-room.yaml'} is a valid layout")
    assert "desk      kitamura2017 (4 sensors; top 75 × 50 cm)" in out
    assert "lamp    rect x -32..-20, y -20..-8 cm on top  [tap, long_press]" in out
    assert "slider 0→1 from (-30, 16) to (30, 16) cm" in out
    assert " 2. long_press in lamp (at 1 s) → mqtt" in out
    assert " 4. stroke anywhere (shape circle) → mqtt, log" in out
    assert " 5. stroke anywhere (shape zed) → mqtt" in out
    assert " 6. swipe anywhere (direction up) → mqtt" in out
    assert "slide in dimmer: interval_s 0.1 s" in out  # a setting differing from the default
    assert "templates built-in: 18 shapes; yours: zed (3)" in out
    # one gesture per touch: the order, and what each waits for where it can meet another
    assert "  2. swipe (anywhere): waits for stroke to fail; not after a long press fired" in out
    assert "  4. tap (lamp): waits for stroke, swipe to fail; not after a long press fired" in out
    assert "  beside, not arbitrated: slide" in out


def test_check_draws_the_layout(tmp_path, capsys):
    png = tmp_path / "buttons.png"
    assert main(["check", str(EXAMPLES / "buttons.yaml"), "--png", str(png)]) == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000
    assert f"drawn: {png}" in capsys.readouterr().out


def test_check_reports_errors_with_their_position(tmp_path, capsys):
    layout = tmp_path / "bad.yaml"
    layout.write_text(
        "desk: kitamura2017\nregions: {a: {rect: [0, 0, 0.1, 0.1]}}\n"
        "bindings:\n  - {gesture: tap, region: a, do: {mqtt: {}}}\n"
    )
    assert main(["check", str(layout)]) == 2
    err = capsys.readouterr().err
    # the action's own validation (the mqtt plugin) names the place too
    assert f"hapticdesk check: error: {layout}:4:42:" in err and "topic" in err
    layout.write_text(layout.read_text().replace("mqtt: {}", "mqt: {}"))
    assert main(["check", str(layout)]) == 2
    assert "4:36: unknown action `mqt`" in capsys.readouterr().err


def test_check_with_another_desk(tmp_path, capsys):
    layout = tmp_path / "shelf.yaml"
    layout.write_text(
        "desk: kitamura2017\nregions: {s: {rect: [0, 0.3, 0.1, 0.35], surface: shelf}}\n"
        "bindings:\n  - {gesture: tap, region: s, do: log}\n"
    )
    assert main(["check", str(layout)]) == 2
    assert "must be one of top, found str 'shelf'" in capsys.readouterr().err
    assert main(["check", str(layout), "--desk", "kitamura2017-shelf"]) == 0
    assert "s  rect x 0..0.1, y 0.3..0.35 m on shelf  [tap]" in capsys.readouterr().out


def test_check_says_a_long_press_repeats(tmp_path, capsys):
    layout = tmp_path / "dim.yaml"
    layout.write_text(
        "desk: kitamura2017\nregions: {lamp: {rect: [0, 0, 0.1, 0.1]}}\nbindings:\n"
        "  - {gesture: long_press, region: lamp, hold_s: 0.6, repeat: true, interval_s: 0.3,\n"
        "     do: {log: {}}}\n"
        "  - {gesture: long_press, region: lamp, hold_s: 0.6, do: {log: {}}}\n"
    )
    assert main(["check", str(layout)]) == 0
    out = capsys.readouterr().out
    assert " 1. long_press in lamp (at 0.6 s; then every 0.3 s while held) → log" in out
    assert " 2. long_press in lamp (at 0.6 s) → log" in out
