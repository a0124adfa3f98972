"""Sections a plugin claims (the MQTT plugin's ``mqtt:``) are checked while the layout loads:
``hapticdesk check`` refuses exactly what ``run`` refuses, at the same file:line:column."""

from __future__ import annotations

from pathlib import Path

import pytest

from hapticdesk.cli import main

SCENE = Path(__file__).resolve().parents[2] / "examples" / "scenes" / "demo.yaml"
HEAD = "desk: kitamura2017\n"
BINDINGS = (
    "regions: {b: {rect: [-0.3, -0.2, -0.1, 0]}}\n"
    "bindings:\n  - {gesture: tap, region: b, do: log}\n"
)


@pytest.mark.parametrize(
    ("section", "at", "expected"),
    [
        ("mqtt: {qos: '2'}\n", "'2'", "`qos` of `mqtt` must be 0, 1 or 2, found '2'"),
        ("mqtt: {broker: 'ftp://host'}\n", "'ftp", "broker must be mqtt://host[:port]"),
        ("mqtt: {password: secret}\n", "password", "unknown key `password` in `mqtt`"),
        ("desk_name: a/b#\n", "a/b#", "`desk_name` must be letters, digits, _ and -"),
        ("mqtt: {keepalive: 100000000000}\n", "1000", "keepalive"),
    ],
)
@pytest.mark.parametrize("command", ["check", "run"])
def test_check_and_run_refuse_a_bad_section_at_its_line_and_column(
    tmp_path, capsys, command, section, at, expected
):
    path = tmp_path / "layout.yaml"
    path.write_text(HEAD + section + BINDINGS)
    argv = (
        ["check", str(path)]
        if command == "check"
        else ["run", "--layout", str(path), "--source", f"sim:{SCENE}", "--speed", "0"]
    )
    assert main(argv) == 2
    err = capsys.readouterr().err
    column = section.index(at) + 1
    assert f"layout.yaml:2:{column}: " in err, err
    assert expected in err
    assert "Traceback" not in err


def test_a_good_mqtt_section_passes_check(tmp_path, capsys):
    path = tmp_path / "layout.yaml"
    path.write_text(HEAD + "mqtt: {qos: 1, keepalive: 30}\ndesk_name: study\n" + BINDINGS)
    assert main(["check", str(path)]) == 0
    assert "OK:" in capsys.readouterr().out


def test_a_section_no_plugin_claims_is_refused_with_the_allowed_keys(tmp_path, capsys):
    path = tmp_path / "layout.yaml"
    path.write_text(HEAD + "mqttt: {qos: 1}\n" + BINDINGS)
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err
    assert "layout.yaml:2:1: unknown key `mqttt` in the layout" in err
    assert "mqtt" in err.split("allowed:")[1]  # the plugin's section is among the allowed
