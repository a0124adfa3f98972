"""`contacts`, `plot` and `run --source replay:` on a C3D file: the plate is the desk, the
contacts come in the lab frame, and what is wrong is said in one line."""

from __future__ import annotations

import csv
import importlib.util
import json
import sys
from pathlib import Path

import numpy as np
import pytest

from hapticdesk.cli import main

from .conftest import PlateSpec, Press, write_plate_file, y_up_corners, z_up_corners

ROOT = Path(__file__).resolve().parents[2]
POINT = (1.08, 0.0, 0.41)  # on the top of a plate in a lab whose vertical is y


@pytest.fixture
def two_plates(tmp_path):
    """Plate 1 unloaded (a light touch only), plate 2 (y up, TYPE 2) under 650 N at POINT."""
    a = PlateSpec(2, z_up_corners(centre=(3.0, 3.0, 0.0)), (0.0, 0.0, -40.0))
    b = PlateSpec(2, y_up_corners(), (0.0, 0.0, -40.0))
    presses = [
        Press((3.0, 3.0, 0.0), (0.0, 0.0, 0.5)),
        Press(POINT, (0.0, 650.0, 0.0), seconds=1.5, quiet_s=0.5),
    ]
    return write_plate_file(tmp_path / "walk.c3d", [a, b], presses)


def test_contacts_writes_lab_frame_metres_for_the_chosen_plate(two_plates, tmp_path, capsys):
    out = tmp_path / "contacts.csv"
    assert main(["contacts", str(two_plates), "--plate", "2", "-o", str(out), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["plate"] == 2 and info["method"] == "force"
    rows = list(csv.DictReader(out.open()))
    located = np.array([[float(r["x"]), float(r["y"]), float(r["z"])] for r in rows if r["x"]])
    assert len(located) > 1400  # 1.5 s at 1 kHz
    assert np.abs(located - np.array(POINT)).max() < 1e-4
    assert min(float(r["t"]) for r in rows) >= 0.5  # (nothing before the step)


def test_contacts_on_plate_one_finds_no_contact_under_half_a_newton(two_plates, capsys):
    assert main(["contacts", str(two_plates), "-o", "-"]) == 0
    assert capsys.readouterr().out.strip().splitlines() == ["t,x,y,z,surface,force_n,source,phase"]


def test_plot_draws_the_plate(two_plates, tmp_path, capsys):
    pytest.importorskip("matplotlib")
    png = tmp_path / "plate.png"
    assert main(["plot", str(two_plates), "--plate", "2", "-o", str(png), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["located"]["force"] > 1400
    assert png.stat().st_size > 10_000


def test_run_replays_the_plate_as_the_desk(two_plates, tmp_path):
    layout = tmp_path / "plate.yaml"
    # the desk's frame is the plate's, z up: POINT lies 0.09 m along the plate's −x (the
    # lab's −z) and 0.08 m along the lab's x, which is the plate's −y: the desk's +y
    layout.write_text(
        "regions:\n  front: {rect: [-0.2, -0.3, 0.2, 0]}\n  back: {rect: [-0.2, 0, 0.2, 0.3]}\n"
        "bindings:\n  - gesture: press\n    region: back\n    do: log\n"
        "  - gesture: press\n    region: front\n    do: log\n"
    )
    events = tmp_path / "events.jsonl"
    argv = ["run", "--layout", str(layout), "--source", f"replay:{two_plates}", "--plate", "2"]
    assert main([*argv, "--speed", "0", "--events", str(events)]) == 0
    fired = [json.loads(line) for line in events.read_text().splitlines()]
    assert fired and {e["region"] for e in fired} == {"back"}
    assert all(abs(e["x"] + 0.09) < 1e-3 and abs(e["y"] - 0.08) < 1e-3 for e in fired)


def test_a_layouts_desk_a_plate_replay_does_not_use_is_said(two_plates, tmp_path, capsys):
    # the layout's `desk:` (which `check` needs) was silently left out for the plate's
    layout = tmp_path / "plate.yaml"
    layout.write_text(
        "desk: kitamura2017\nregions:\n  back: {rect: [-0.2, 0, 0.2, 0.3]}\n"
        "bindings:\n  - {gesture: press, region: back, do: log}\n"
    )
    argv = ["run", "--layout", str(layout), "--source", f"replay:{two_plates}", "--speed", "0"]
    assert main(argv) == 0
    err = capsys.readouterr().err
    assert (
        "the layout's `desk: kitamura2017` is not used: a C3D replay's desk is its force "
        "plate 1 (--desk chooses another)" in err
    )


def test_check_takes_a_plate_as_the_desk(two_plates, tmp_path, capsys):
    # a lab checks its layout against the plate `run --source replay:` makes the desk
    layout = tmp_path / "plate.yaml"
    layout.write_text(
        "regions:\n  back: {rect: [-0.2, 0, 0.2, 0.3]}\n"
        "bindings:\n  - {gesture: press, region: back, do: log}\n"
    )
    assert main(["check", str(layout), "--desk", str(two_plates), "--plate", "2"]) == 0
    out = capsys.readouterr().out
    assert "OK:" in out and "desk      walk-plate2 (1 sensor; top 0.4 × 0.6 m)" in out
    # a region off the plate is refused, as run refuses it
    layout.write_text(
        "regions:\n  off: {rect: [0.5, 0.5, 0.7, 0.7]}\n"
        "bindings:\n  - {gesture: press, region: off, do: log}\n"
    )
    assert main(["check", str(layout), "--desk", str(two_plates), "--plate", "2"]) == 2
    err = capsys.readouterr().err
    assert "plate.yaml:2:" in err and "Traceback" not in err


def test_init_starts_a_layout_for_a_plate_that_check_and_run_take(two_plates, tmp_path, capsys):
    layout = tmp_path / "start.yaml"
    argv = ["init", str(layout), "--desk", str(two_plates), "--plate", "2", "--units", "m"]
    assert main(argv) == 0
    said = capsys.readouterr().out
    assert f"hapticdesk check {layout} --desk {two_plates} --plate 2" in said
    text = layout.read_text()
    assert "\ndesk:" not in text and "- gesture: press" in text  # (the replay brings the desk)
    assert f"--source replay:{two_plates} --plate 2" in text
    assert main(["check", str(layout), "--desk", str(two_plates), "--plate", "2"]) == 0
    run = ["run", "--layout", str(layout), "--source", f"replay:{two_plates}", "--plate", "2"]
    events = tmp_path / "events.jsonl"
    assert main([*run, "--speed", "0", "--events", str(events)]) == 0
    assert "is not used" not in capsys.readouterr().err  # (no desk: in it to leave out)
    # the button sits where the step comes down (not the top's middle, 0.12 m from it), a
    # foot's 0.2 m (half the 0.4 m plate), and the step presses it once: one level, 100 N
    fired = [json.loads(line) for line in events.read_text().splitlines()]
    assert [(e["gesture"], e["region"]) for e in fired] == [("press", "button")]
    assert abs(fired[0]["x"] + 0.09) < 1e-3 and abs(fired[0]["y"] - 0.08) < 1e-3
    assert "button: {rect: [-0.19, -0.02, 0.01, 0.18]}" in text
    assert "levels: {step: 100}" in text and "the recording's steps come down" in text


def test_init_on_a_plate_nobody_stepped_on_puts_the_button_in_the_middle(
    two_plates, tmp_path, capsys
):
    layout = tmp_path / "start.yaml"
    assert main(["init", str(layout), "--desk", str(two_plates), "--units", "m"]) == 0
    text = layout.read_text()
    assert "button: {rect: [-0.1, -0.1, 0.1, 0.1]}" in text  # (0.5 N at most on plate 1)
    assert "no step of the recording reaches 100 N: the button is in the middle" in text


@pytest.mark.parametrize(("name", "plate"), [("BTS.c3d", 1), ("BTS.c3d", 4), ("Qualisys.c3d", 2)])
def test_init_on_a_real_recording_puts_the_button_under_its_step(name, plate, tmp_path, capsys):
    from .conftest import shared_file

    recording = shared_file(name)
    layout = tmp_path / "start.yaml"
    assert main(["init", str(layout), "--desk", str(recording), "--plate", str(plate)]) == 0
    assert main(["check", str(layout), "--desk", str(recording), "--plate", str(plate)]) == 0
    assert "warning" not in capsys.readouterr().err  # (the button kept on the plate)
    events = tmp_path / "events.jsonl"
    source = ["--source", f"replay:{recording}", "--plate", str(plate)]
    assert (
        main(["run", "--layout", str(layout), *source, "--speed", "0", "--events", str(events)])
        == 0
    )
    fired = [json.loads(line) for line in events.read_text().splitlines()]
    assert [(e["gesture"], e["region"]) for e in fired] == [("press", "button")]


@pytest.mark.parametrize(
    ("argv", "said"),
    [
        (
            ["contacts", "{f}", "--plate", "3"],
            "walk.c3d has 2 force plates: expected --plate 1 to 2",
        ),
        (["contacts", "{f}", "--desk", "kitamura2017"], "a desk's sensors are its force plates"),
        (["contacts", "{f}", "--desk", "kitamura2017", "--plate", "1"], "--plate"),
        (["contacts", "{d}/x.csv", "--plate", "1"], "is not a .c3d file"),
        # a C3D file given as the desk: said so, not "larger than 1 MB" or "a NUL byte"
        (["contacts", "{f}", "--desk", "{f}"], "walk.c3d: a C3D file is not a desk profile"),
        (["init", "{d}/plate.yaml", "--plate", "2"], "of a C3D file given as --desk FILE.c3d"),
        (["check", "{d}/plate.yaml", "--plate", "2"], "of a C3D file given as --desk FILE.c3d"),
        (["check", "{d}/plate.yaml", "--desk", "{f}", "--plate", "3"], "expected --plate 1 to 2"),
    ],
)
def test_wrong_combinations_are_one_line(two_plates, capsys, argv, said):
    argv = [a.format(f=two_plates, d=two_plates.parent) for a in argv]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert said in err and "Traceback" not in err


def test_without_ezc3d_the_install_command_is_named(two_plates, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "ezc3d", None)  # (import ezc3d now fails)
    assert main(["contacts", str(two_plates), "-o", "-"]) == 2
    err = capsys.readouterr().err
    assert "pip install 'hapticdesk[c3d]'" in err and "Traceback" not in err


def test_the_accuracy_script_without_the_files_says_where_to_give_them(tmp_path, capsys):
    """A clone has no real recordings: the script says so and fails (it printed an empty
    table and exited 0)."""
    pytest.importorskip("ezc3d")
    script = ROOT / "scripts" / "forceplate_accuracy.py"
    spec = importlib.util.spec_from_file_location("forceplate_accuracy", script)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert module.main(["--data", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert f"is in {tmp_path}: give their folder with --data DIR" in err
