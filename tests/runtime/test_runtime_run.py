"""`hapticdesk run` and `hapticdesk demo` from the command line; what a scene imports."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from hapticdesk.cli import main
from hapticdesk.files.recording_io import write_recording

from .taps import Tap, tap_recording

REPO = Path(__file__).resolve().parents[2]
EXAMPLES = REPO / "examples"
LOG_LAYOUT = """\
desk: kitamura2017
units: cm
regions:
  lamp: {rect: [-10, -10, 10, 10]}
bindings:
  - gesture: tap
    region: lamp
    do: %s
"""


@pytest.fixture
def recording(tmp_path, paper_desk) -> Path:
    path = tmp_path / "taps.csv"
    taps = [
        Tap(1.5, 0.0, 0.0),
        Tap(2.2, 0.05, 0.02),
        Tap(2.9, 0.3, 0.2),
    ]  # the last is off the lamp
    write_recording(path, tap_recording(paper_desk, taps, 3.5))
    return path


def layout(tmp_path: Path, do: str = "{log: {}}") -> Path:
    path = tmp_path / "layout.yaml"
    path.write_text(LOG_LAYOUT % do)
    return path


def test_events_file_holds_one_json_object_per_gesture(tmp_path, recording, capsys):
    events = tmp_path / "events.jsonl"
    code = main(["run", "--layout", str(layout(tmp_path)), "--source", f"replay:{recording}",
                 "--speed", "0", "--events", str(events)])  # fmt: skip
    assert code == 0
    rows = [json.loads(line) for line in events.read_text().splitlines()]
    assert [(r["gesture"], r["region"]) for r in rows] == [("tap", "lamp"), ("tap", "lamp")]
    assert rows[0]["x"] == pytest.approx(0.0, abs=0.005)
    assert rows[1]["x"] == pytest.approx(0.05, abs=0.005)
    assert 1.5 < rows[0]["t"] < 1.7 and 2.2 < rows[1]["t"] < 2.4
    out, err = capsys.readouterr()
    assert out.count("[kitamura2017] ") == 2  # the log action
    assert "the source ended: 4200 samples (3.50 s of sensor time)" in err
    assert "2 gestures (2 tap)" in err


def test_status_line_shows_contact_force_and_last_gesture(tmp_path, recording, capsys):
    main(["run", "--layout", str(layout(tmp_path)), "--source", f"replay:{recording}",
          "--speed", "0", "--status"])  # fmt: skip
    err = capsys.readouterr().err
    final = [line for line in err.split("\r\x1b[K") if line.startswith("t ")][-1]
    assert "last: lamp_tap at 2.3" in final
    assert "gestures 2" in final and "F " in final


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (
            ["--source", "usb:/dev/ttyUSB0"],
            "unknown source kind `usb`; installed: can, replay, serial, sim",
        ),
        (["--source", "taps.csv"], "expected KIND:ARGUMENT"),
        (["--source", "replay:nowhere.csv"], "replay: no such file: nowhere.csv"),
        # a folder (or a FIFO) is there, but not a recording: it was "no such file"
        (["--source", "replay:TMP"], "replay: not a regular file: TMP"),
        (["--source", "replay:LAYOUT"], "cannot replay a .yaml file; expected a recording (.csv"),
        (["--desk", "no_such_desk"], "no such desk profile; shipped profiles:"),
        (["--speed", "-1"], "--speed: must be 0 (as fast as possible) or 0.001 to"),
        (["--mqtt", "mqtt://u:secret@host"], "do not put a password in the broker URL"),
        (["--events", "/no/such/folder/e.jsonl"], "--events: cannot write /no/such/folder/e.jsonl"),
    ],
)
def test_mistakes_give_a_clear_error_and_no_traceback(tmp_path, recording, capsys, args, expected):
    base = {"--source": f"replay:{recording}", "--layout": str(layout(tmp_path))}
    for flag, value in zip(args[::2], args[1::2], strict=True):
        base[flag] = value.replace("LAYOUT", base["--layout"]).replace("TMP", str(tmp_path))
    argv = ["run", *[x for pair in base.items() for x in pair]]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert expected.replace("TMP", str(tmp_path)) in err
    assert "Traceback" not in err
    assert "secret" not in err


def test_a_bad_layout_names_file_line_and_column(tmp_path, recording, capsys):
    bad = layout(tmp_path, "{mqtt: {topic: lamp/set, qos: 7}}")
    assert main(["run", "--layout", str(bad), "--source", f"replay:{recording}"]) == 2
    assert f"{bad}:8:" in capsys.readouterr().err


def test_desk_overrides_the_layouts_desk(tmp_path, recording, capsys):
    profile = (REPO / "profiles" / "kitamura2017.yaml").read_text()
    other = tmp_path / "other.yaml"
    other.write_text(profile.replace("name: kitamura2017", "name: other_desk", 1))
    code = main(["run", "--layout", str(layout(tmp_path)), "--desk", str(other),
                 "--source", f"replay:{recording}", "--speed", "0"])  # fmt: skip
    assert code == 0
    assert capsys.readouterr().out.count("[other_desk] ") == 2  # the log action names the desk


def _modules_after(argv: list[str], status: int = 0) -> set[str]:
    code = (
        "import json, sys\n"
        "from hapticdesk.cli import main\n"
        f"rc = main({argv!r})\n"
        "print(json.dumps({'rc': rc, 'modules': sorted(sys.modules)}))\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert result["rc"] == status, done.stderr
    return {name.split(".")[0] for name in result["modules"]} | set(result["modules"])


def test_a_scene_imports_only_what_it_uses(tmp_path, recording):
    """No MQTT action: no paho; no CAN source: no python-can or cantools; no template: no jinja2."""
    modules = _modules_after(
        [
            "run",
            "--layout",
            str(layout(tmp_path)),
            "--source",
            f"replay:{recording}",
            "--speed",
            "0",
        ]
    )
    assert "hapticdesk.gestures.recognizers.taps" in modules  # it did run
    for heavy in ("paho", "can", "cantools", "jinja2", "amqtt", "matplotlib"):
        assert heavy not in modules, heavy


def test_a_simulated_scene_without_can_never_imports_python_can(tmp_path):
    scene = EXAMPLES / "scenes" / "buttons.yaml"
    buttons = EXAMPLES / "layouts" / "buttons.yaml"
    if not (scene.is_file() and buttons.is_file()):
        pytest.skip("the example scene and layout are not there")
    modules = _modules_after(
        ["run", "--layout", str(buttons), "--source", f"sim:{scene}", "--speed", "0"]
    )
    assert "hapticdesk.sim" in modules
    for heavy in ("paho", "can", "cantools"):
        assert heavy not in modules, heavy


def test_a_layout_with_mqtt_imports_paho_and_jinja2_only_then(tmp_path, recording):
    mqtt = layout(tmp_path, '{mqtt: {topic: lamp/set, payload: {v: "{{ x }}"}}}')
    modules = _modules_after(
        [
            "run",
            "--layout",
            str(mqtt),
            "--source",
            f"replay:{recording}",
            "--speed",
            "0",
            "--mqtt",
            "mqtt://127.0.0.1:9",
            "--drain",
            "0",
        ],
        status=3,
    )  # no broker there: nothing is delivered
    assert "paho" in modules and "jinja2" in modules
    assert "can" not in modules


def test_the_demo_runs_the_whole_path_through_an_embedded_broker():
    pytest.importorskip("amqtt", reason="the demo's embedded broker is the `demo` extra")
    done = subprocess.run(
        # (as fast as possible: the stroke's command and the last tap's, a second apart on
        # the desk, are dispatched by two actions within a millisecond; the `mqtt` actions'
        # order_key keeps them in the gestures' order at the lamp)
        [sys.executable, "-m", "hapticdesk", "demo", "--speed", "0"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    out = done.stdout
    assert "embedded MQTT broker on mqtt://127.0.0.1:" in out
    assert "gesture lamp_tap" in out
    assert "desk_lamp: ON " in out
    [commands] = [line for line in out.splitlines() if line.startswith("commands: ")]
    sent, received = (int(w) for w in commands.replace(",", "").split() if w.isdigit())
    assert sent == received and sent >= 3
    assert "desk_lamp ends OFF" in out  # tapped on, dimmed, tapped off
    # nothing alarming when all is well: its own broker speaks MQTT 3.1.1, which it says once
    # (the link's warning about falling back from MQTT 5 had greeted every new user)
    for alarming in ("WARNING", "warning", "does not speak", "error", "Traceback"):
        assert alarming not in out + done.stderr, out + done.stderr
    assert "(command " not in out  # the lamp's lines numbered the commands, which jumped
    [gestures] = [line for line in out.splitlines() if line.startswith("gestures: ")]
    assert "1 slide (" in gestures and " updates)" in gestures  # a slide counted once


def test_a_demo_layout_that_is_not_there_is_said_so(tmp_path, capsys):
    """`demo --layout L` with no L: it blamed the examples ("not installed?")."""
    missing = tmp_path / "mine.yaml"
    assert main(["demo", "--layout", str(missing)]) == 2
    assert capsys.readouterr().err == f"hapticdesk demo: error: {missing}: no such file\n"
