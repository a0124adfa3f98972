"""The browser UI left running: what a page, a stranger on the network or a flood of sockets
can do to it (issue 30, items 5, 7, 8 and 10). Each test says what it guards."""

from __future__ import annotations

import json
import logging
import shutil
import threading
import time
from pathlib import Path
from types import SimpleNamespace

import pytest

pytest.importorskip("starlette")
pytest.importorskip("httpx")

from starlette.testclient import TestClient  # noqa: E402

from hapticdesk.errors import ConfigError  # noqa: E402
from hapticdesk.files.profile_reader import load_profile  # noqa: E402
from hapticdesk.plugin_loading import load_registry  # noqa: E402
from hapticdesk.plugins.ui import hub as ui_hub  # noqa: E402
from hapticdesk.plugins.ui.guard import TOKEN_COOKIE  # noqa: E402
from hapticdesk.plugins.ui.page import STATIC  # noqa: E402
from hapticdesk.plugins.ui.server import UiServer  # noqa: E402

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
LOCAL = "http://127.0.0.1:8765"


@pytest.fixture
def layout(tmp_path: Path) -> Path:
    folder = tmp_path / "desk"
    folder.mkdir()
    path = folder / "buttons.yaml"
    shutil.copy(EXAMPLES / "layouts" / "buttons.yaml", path)
    return path


@pytest.fixture
def client(layout: Path) -> TestClient:
    return TestClient(UiServer(layout, load_registry(entry_points=False)).app(), base_url=LOCAL)


def test_a_confined_read_says_the_same_for_what_exists_outside_and_what_does_not(
    client: TestClient, layout: Path, tmp_path: Path
) -> None:
    """Guards item 5: a layout from the page naming a path outside its folder gets one answer
    whether the path exists or not (b5a43bd: `templates: /root` listed the folder, `layouts:
    {x: /etc/shadow}` passed where a missing file said "no such file")."""
    there = tmp_path / "outside"
    (there / "circle").mkdir(parents=True)
    (there / "circle" / "one.csv").write_text("x,y\n0,0\n1,1\n")
    (there / "secret.yaml").write_text("desk: kitamura2017\n")
    base = layout.read_text()
    cases = [
        ("templates: {}\n", str(there)),
        ("templates: {{x: {}}}\n", str(there / "circle")),
        ("templates: {{x: {}}}\n", str(there / "circle" / "one.csv")),
        ("layouts: {{x: {}}}\n", str(there / "secret.yaml")),
        ("desk: {}\n", str(there / "secret.yaml")),
    ]
    for line, path in cases:
        answers = []
        for named in (path, path.replace("outside", "missing")):
            text = base.replace("desk: kitamura2017\n", "desk: kitamura2017\n" + line.format(named))
            if line.startswith("desk"):
                text = base.replace("desk: kitamura2017\n", line.format(named))
            [error] = client.post("/api/check", content=text).json()["errors"]
            answers.append({**error, "message": error["message"].replace(named, "PATH")})
        assert answers[0] == answers[1], answers
        assert "lies outside the layout's folder" in answers[0]["message"]
        assert answers[0]["line"] > 0


def test_the_guard_confines_what_a_page_sends_not_the_operator_s_own_file(
    layout: Path, tmp_path: Path
) -> None:
    """Guards the guard (one middleware confining every request's reads): the operator's own
    layout file may name strokes outside its folder, and the page still shows them and
    scores against them (the file is read as the operator's); the same text sent by a page
    is refused at its place."""
    folder = tmp_path / "elsewhere" / "zig"
    folder.mkdir(parents=True)
    (folder / "one.csv").write_text("x,y\n0,0\n0.05,0.05\n0.1,0\n0.15,0.05\n")
    text = layout.read_text().replace(
        "desk: kitamura2017\n", f"desk: kitamura2017\ntemplates: {{zig: {folder}}}\n"
    )
    layout.write_text(text)
    client = TestClient(UiServer(layout, load_registry(entry_points=False)).app(), base_url=LOCAL)
    stroke = {"points": [[0, 0], [0.05, 0.05], [0.1, 0], [0.15, 0.05]]}
    scored = client.post("/api/strokes", json=stroke)
    assert scored.status_code == 200 and scored.json()["user_shapes"] == ["zig"]
    with client.websocket_connect("/ws", headers={"host": "127.0.0.1:8765"}) as socket:
        desk = json.loads(socket.receive_text())
    assert desk["type"] == "desk" and desk["templates"] == ["zig"]
    [error] = client.post("/api/check", content=text).json()["errors"]
    assert "lies outside the layout's folder" in error["message"]
    assert client.put("/api/layout", content=text).status_code == 422


class _FakeRuntime(SimpleNamespace):
    """What the set-up check reads of a run: its profile, and the block taps it adds to."""

    def __init__(self) -> None:
        profile = load_profile("kitamura2017")
        super().__init__(scene=SimpleNamespace(profile=profile), block_taps=())


@pytest.mark.parametrize(
    ("payload", "said"),
    [
        ({}, "`points`: a list of 4 to 64 points [x, y] in metres, found NoneType"),
        ({"points": "abc"}, "found str"),
        ({"points": [[0, 0]]}, "found 1 (mark at least as many points"),
        ({"points": [[0, 0]] * 65}, "found 65"),
        ({"points": [[0, 0], [0.1], "x", [1, 2]]}, "`points` item 2: expected [x, y] in metres"),
        ({"points": [[0, 0], [0, 1e300], [0, 0], [0, 0]]}, "item 2: expected [x, y]"),
        ({"points": [[0, 0], [0, 0], [True, 0], [0, 0]]}, "item 3"),
    ],
)
def test_setup_start_refuses_what_is_not_points_saying_what(
    layout: Path, payload: dict, said: str, caplog: pytest.LogCaptureFixture
) -> None:
    """Guards item 7: `/api/setup/start` validates its JSON with a clear error (b5a43bd took
    any JSON, and `/api/setup/finish` then failed with a traceback in the log)."""
    server = UiServer(layout, load_registry(entry_points=False))
    server.runtime = _FakeRuntime()  # (what the set-up check reads of a run)
    client = TestClient(server.app(), base_url=LOCAL)
    answer = client.post("/api/setup/start", json=payload)
    assert answer.status_code == 422
    assert said in answer.json()["errors"][0]["message"]
    assert client.post("/api/setup/finish").status_code == 422  # none was started
    assert "Traceback" not in caplog.text
    good = {"points": [[0, 0], [0.1, 0.1], [-0.1, 0.1], [0.1, -0.1]]}
    assert client.post("/api/setup/start", json=good).json() == {"ok": True}


def test_an_unexpected_error_is_one_line_in_the_log_and_json_to_the_page(
    layout: Path, caplog: pytest.LogCaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Guards item 7's "no traceback in the log": an error no handler expected (a bug) is
    answered 500 as JSON and logged as one line."""
    from hapticdesk.plugins.ui import setup_api

    server = UiServer(layout, load_registry(entry_points=False))
    server.runtime = _FakeRuntime()  # (what the set-up check reads of a run)
    client = TestClient(server.app(), base_url=LOCAL, raise_server_exceptions=False)
    good = {"points": [[0, 0], [0.1, 0.1], [-0.1, 0.1], [0.1, -0.1]]}
    assert client.post("/api/setup/start", json=good).status_code == 200

    def broken(self: object) -> dict:
        raise ValueError("shapes (3,) and (2,) not aligned")

    monkeypatch.setattr(setup_api.SetupSession, "finish", broken)
    with caplog.at_level(logging.DEBUG, logger="hapticdesk"):
        answer = client.post("/api/setup/finish")
    assert answer.status_code == 500
    assert answer.json()["errors"][0]["message"] == "internal error: ValueError"
    lines = [r for r in caplog.records if r.levelno >= logging.ERROR]
    assert [r.getMessage() for r in lines] == [
        "ui: POST /api/setup/finish failed: ValueError: shapes (3,) and (2,) not aligned"
    ]
    assert all(r.exc_info is None for r in lines)


def test_websocket_clients_are_capped_and_the_next_is_told_why(
    layout: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Guards item 8: at most MAX_WS_CLIENTS pages at once; one more gets a notice saying
    why and is closed with 1013 (try again later); a place freed is taken again (b5a43bd
    accepted 1,500 idle clients, 229 MB)."""
    from starlette.websockets import WebSocketDisconnect

    monkeypatch.setattr(ui_hub, "MAX_WS_CLIENTS", 3)
    server = UiServer(layout, load_registry(entry_points=False))
    client = TestClient(server.app(), base_url=LOCAL)
    here = {"host": "127.0.0.1:8765"}
    with (
        client.websocket_connect("/ws", headers=here) as a,
        client.websocket_connect("/ws", headers=here) as b,
        client.websocket_connect("/ws", headers=here) as c,
    ):
        for socket in (a, b, c):
            assert json.loads(socket.receive_text())["type"] == "desk"
        with client.websocket_connect("/ws", headers=here) as refused:
            notice = json.loads(refused.receive_text())
            assert notice == {
                "type": "notice",
                "kind": "refused",
                "message": "3 pages are open already, the most served at once",
            }
            with pytest.raises(WebSocketDisconnect) as closed:
                refused.receive_text()
            assert closed.value.code == 1013
        assert server.hub.refused_sockets == 1
    with client.websocket_connect("/ws", headers=here) as again:
        assert json.loads(again.receive_text())["type"] == "desk"


def test_static_files_are_behind_the_token_and_the_page_gets_them(layout: Path) -> None:
    """Guards item 10: with a token, /static answers 401 without it (b5a43bd served it to
    anyone); the page itself gets a SameSite=Strict cookie, so the browser's requests for
    its scripts carry the token."""
    server = UiServer(
        layout, load_registry(entry_points=False), host="0.0.0.0", token="s3cret-s3cret"
    )
    app = server.app()
    stranger = TestClient(app, base_url="http://192.0.2.7:8765")
    assert stranger.get("/static/app.js").status_code == 401
    assert stranger.get("/static/../layout_edit.py").status_code in (401, 404)
    page = TestClient(app, base_url="http://192.0.2.7:8765")
    answer = page.get("/?token=s3cret-s3cret")
    assert answer.status_code == 200
    cookie = answer.headers["set-cookie"]
    assert f"{TOKEN_COOKIE}=s3cret-s3cret" in cookie and "HttpOnly" in cookie
    assert "SameSite=strict" in cookie or "SameSite=Strict" in cookie
    script = page.get("/static/app.js")
    assert script.status_code == 200 and "function onContact" in script.text
    assert page.get("/static/nothing.js").status_code == 404


def test_the_host_header_is_checked_on_a_server_listening_everywhere(layout: Path) -> None:
    """Guards item 10: on 0.0.0.0 a request must name the server by an IP address or one of
    its own names (or $HAPTICDESK_UI_HOSTS), even with the token: a site of an attacker's
    whose name resolves to the desk (DNS rebinding) is refused (b5a43bd: not checked)."""
    import socket

    server = UiServer(
        layout, load_registry(entry_points=False), host="0.0.0.0", token="s3cret-s3cret"
    )
    app = server.app()
    bearer = {"Authorization": "Bearer s3cret-s3cret"}
    for host, status in [
        ("192.0.2.7:8765", 200),
        ("[2001:db8::7]:8765", 200),
        (f"{socket.gethostname()}:8765", 200),
        ("attacker.example:8765", 401),
        ("desk.attacker.example", 401),
    ]:
        answer = TestClient(app).get("/api/layout", headers={**bearer, "host": host})
        assert answer.status_code == status, host


def test_a_paused_desk_says_so_to_the_page(layout: Path, paper_desk) -> None:
    """Guards item 10 ("a desk paused by `/set` says so ... in the page"): the contact frames
    the page draws carry `paused`, true from the pause until the resume (b5a43bd: not said;
    the page shows "paused: gestures are not sent" from it)."""
    websockets = pytest.importorskip("websockets.sync.client")
    from hapticdesk.hookspecs import hookimpl
    from hapticdesk.runtime.assembly import build_scene
    from hapticdesk.runtime.service import Runtime

    from ..runtime.taps import Tap, tap_recording
    from ..runtime.test_runtime_control import ScriptedSource

    recording = tap_recording(paper_desk, [Tap(1.5, 0.0, 0.0)], 60.0)
    holder: dict[str, Runtime] = {}
    go_on = threading.Event()

    def pace() -> None:  # the page is connected before the pause
        go_on.wait(20)

    script = {1.0: pace, 2.0: lambda: holder["rt"].request("pause")}
    # wall time before the pause too, so the page is sent a frame of the unpaused desk
    # (replayed as fast as possible, a second of samples passed between two frames)
    script.update({1.0 + 0.05 * k: (lambda: time.sleep(0.01)) for k in range(1, 20)})
    script.update({2.0 + 0.05 * k: (lambda: time.sleep(0.01)) for k in range(1, 100)})
    script[7.0] = lambda: holder["rt"].request("resume")
    script.update({7.0 + 0.05 * k: (lambda: time.sleep(0.01)) for k in range(1, 100)})
    source = ScriptedSource(recording, script)
    plugin = SimpleNamespace(
        register_sources=hookimpl(lambda register: register("s", lambda a, p, **o: source))
    )
    registry = load_registry(entry_points=False, plugins=[("s", plugin)])
    scene = build_scene(layout, "s:", registry, speed=0, actions=False)
    server = UiServer(layout, registry, port=0)
    server.start()
    runtime = holder["rt"] = Runtime(scene, drain_timeout_s=0.5)
    server.attach(runtime)
    sensing = threading.Thread(target=runtime.run, kwargs={"handle_signals": False})
    sensing.start()
    seen: list[bool] = []
    try:
        url = f"ws://127.0.0.1:{server.port}/ws"
        with websockets.connect(url, origin=f"http://127.0.0.1:{server.port}") as socket:
            # the run goes on once the page is fed (its first contact frame came): let go at
            # connecting, the run had often paused before the page's first frame
            while (first := json.loads(socket.recv(timeout=10)))["type"] != "contact":
                pass
            seen.append(first["paused"])
            go_on.set()
            deadline = time.monotonic() + 30
            while time.monotonic() < deadline and not (seen and seen[-1] is False and True in seen):
                message = json.loads(socket.recv(timeout=10))
                if message["type"] == "contact":
                    if not seen or seen[-1] != message["paused"]:
                        seen.append(message["paused"])
    finally:
        go_on.set()
        runtime.stop()
        sensing.join(30)
        server.close()
    assert seen == [False, True, False]
    page = (STATIC / "app.js").read_text()
    assert 'm.paused ? "paused: gestures are not sent"' in page


def test_listening_everywhere_without_a_token_writes_no_new_layout(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """`hapticdesk ui --layout new.yaml --host 0.0.0.0` without a token was refused only
    after it had written new.yaml (and said `--ui`, an option of `run`, not of `ui`)."""
    from hapticdesk.cli import main

    monkeypatch.delenv("HAPTICDESK_UI_TOKEN", raising=False)
    layout = tmp_path / "new.yaml"
    assert main(["ui", "--layout", str(layout), "--host", "0.0.0.0", "--port", "0"]) == 2
    err = capsys.readouterr().err
    assert err == (
        "hapticdesk ui: error: --host: listening on 0.0.0.0 lets other machines in: give a "
        "token (--token-file PATH or HAPTICDESK_UI_TOKEN)\n"
    )
    assert not layout.exists()


def test_the_token_is_asked_by_the_page_and_never_in_the_address(layout: Path) -> None:
    """The printed address carried the token (``http://…/?token=…``: a secret in a URL and
    in the terminal's log). Now it is bare; a browser opening it gets a form that posts the
    token to /login, which sets the page's cookie; a wrong token gets the form again."""
    server = UiServer(
        layout, load_registry(entry_points=False), host="0.0.0.0", token="long-enough-s3cret"
    )
    assert "s3cret" not in server.url and "s3cret" not in server.said
    assert "asks for its token" in server.said
    app = server.app()
    here = "http://192.0.2.7:8765"
    browser = TestClient(app, base_url=here, follow_redirects=False)
    asked = browser.get("/")
    assert asked.status_code == 401 and 'action="/login"' in asked.text
    assert "s3cret" not in asked.text and "<script" not in asked.text
    assert browser.get("/api/layout").status_code == 401  # (an API call gets no form)
    wrong = browser.post("/login", data={"token": "guess"}, headers={"origin": here})
    assert wrong.status_code == 401 and "not the token" in wrong.text
    assert TOKEN_COOKIE not in wrong.headers.get("set-cookie", "")
    elsewhere = browser.post(
        "/login", data={"token": "long-enough-s3cret"}, headers={"origin": "http://evil.example"}
    )
    assert elsewhere.status_code == 401 and TOKEN_COOKIE not in elsewhere.headers.get(
        "set-cookie", ""
    )
    right = browser.post("/login", data={"token": "long-enough-s3cret"}, headers={"origin": here})
    assert right.status_code == 303 and right.headers["location"] == "/"
    cookie = right.headers["set-cookie"]
    assert "HttpOnly" in cookie and f"{TOKEN_COOKIE}=long-enough-s3cret" in cookie
    assert browser.get("/").status_code == 200  # (the cookie kept by the client)
    assert browser.get("/static/app.js").status_code == 200


def test_the_server_of_run_ui_refuses_a_short_token_beyond_loopback(layout: Path) -> None:
    """`run --ui 0.0.0.0:PORT` builds the server from the layout's `ui:` or the environment:
    it holds the same rule as `ui`'s options (guard.check_token), not `ui`'s alone."""
    with pytest.raises(ConfigError, match="a token of 6 characters"):
        UiServer(layout, load_registry(entry_points=False), host="0.0.0.0", token="s3cret")
    with pytest.raises(ConfigError, match="give a token"):
        UiServer(layout, load_registry(entry_points=False), host="0.0.0.0")
    UiServer(layout, load_registry(entry_points=False), host="127.0.0.1", token="s3cret")


def test_a_short_token_is_refused_where_other_machines_reach_the_page(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A one-character token was taken for a page listening on every address."""
    from hapticdesk.cli import main

    monkeypatch.setenv("HAPTICDESK_UI_TOKEN", "a")
    layout = tmp_path / "new.yaml"
    assert main(["ui", "--layout", str(layout), "--host", "0.0.0.0", "--port", "0"]) == 2
    err = capsys.readouterr().err
    assert "HAPTICDESK_UI_TOKEN" in err and "12 or more" in err and "Traceback" not in err
    assert not layout.exists()
