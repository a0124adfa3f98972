"""The UI's HTTP contract (README, "Browser UI") in process, without a browser."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("starlette")
pytest.importorskip("httpx")

from starlette.testclient import TestClient  # noqa: E402

from hapticdesk.errors import ConfigError  # noqa: E402
from hapticdesk.plugin_loading import load_registry  # noqa: E402
from hapticdesk.plugins.ui.layout_edit import apply_edit  # noqa: E402
from hapticdesk.plugins.ui.page import STATIC  # noqa: E402
from hapticdesk.plugins.ui.server import UiServer, parse_listen  # noqa: E402

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
#: where a page of the server itself sends from (the UI refuses other hosts and origins)
LOCAL = "http://127.0.0.1:8765"


@pytest.fixture
def layout(tmp_path: Path) -> Path:
    path = tmp_path / "buttons.yaml"
    shutil.copy(EXAMPLES / "layouts" / "buttons.yaml", path)
    return path


@pytest.fixture
def client(layout: Path) -> TestClient:
    server = UiServer(layout, load_registry(entry_points=False))
    return TestClient(server.app(), base_url=LOCAL)


def test_get_layout_and_page(client: TestClient, layout: Path) -> None:
    assert client.get("/api/layout").text == layout.read_text()
    page = client.get("/")
    assert page.status_code == 200 and "static/app.js" in page.text
    assert client.get("/static/app.js").status_code == 200


def test_check_reports_what_hapticdesk_check_reports(client: TestClient, layout: Path) -> None:
    broken = layout.read_text().replace("b7: {rect: [-10.5, -10.5, -5.5, -5.5]}", "b7: {rect: 3}")
    bad = layout.parent / "bad.yaml"
    bad.write_text(broken)
    cli = subprocess.run(
        [sys.executable, "-m", "hapticdesk", "check", str(bad)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert cli.returncode != 0
    line, column = map(int, re.search(r"bad\.yaml:(\d+):(\d+):", cli.stderr).groups())
    result = client.post("/api/check", content=broken).json()
    assert result["ok"] is False
    [error] = result["errors"]
    assert (error["line"], error["column"]) == (line, column)
    assert error["message"] in cli.stderr
    good = client.post("/api/check", content=layout.read_text()).json()
    assert good["ok"] is True and good["errors"] == []


def test_put_refuses_a_broken_layout_and_writes_nothing(client: TestClient, layout: Path) -> None:
    before = layout.read_text()
    response = client.put("/api/layout", content=before.replace("units: cm", "units: inch"))
    assert response.status_code == 422
    body = response.json()
    units_line = before.splitlines().index("units: cm") + 1
    assert body["ok"] is False and body["errors"][0]["line"] == units_line
    assert "inch" in body["errors"][0]["message"]
    assert layout.read_text() == before


def test_put_saves_keeping_comments(client: TestClient, layout: Path) -> None:
    text = apply_edit(
        layout.read_text(),
        {
            "op": "set_region",
            "name": "pad",
            "shape": "circle",
            "center": [0.2, -0.1],
            "radius": 0.03,
        },
    )
    response = client.put("/api/layout", content=text)
    assert response.json() == {"ok": True, "errors": [], "reloaded": False}
    saved = layout.read_text()
    assert saved == text
    assert saved.startswith("# A 3 × 3 grid")
    assert "  pad: {circle: {center: [20.0, -10.0], radius: 3.0}}\n" in saved
    assert "  - {gesture: tap, region: b1, do: {log: {}}}\n" in saved  # the dashes kept


def test_the_page_may_not_change_an_exec_there_is_or_name_other_layouts(
    tmp_path: Path, layout: Path
) -> None:
    """A file with one exec: a save that changed its argv, or moved it to another gesture,
    ran any program (only the count was compared); `layouts:` naming another file (which may
    hold exec actions) was taken too. Keeping the exec as it is, and editing the rest, still
    saves."""
    layout.write_text(
        layout.read_text()
        + "  - {gesture: double_tap, region: b5, do: {exec: {argv: [notify-send, desk, hi]}}}\n"
    )
    client = TestClient(UiServer(layout, load_registry(entry_points=False)).app(), base_url=LOCAL)
    before = layout.read_text()
    changed_argv = before.replace("[notify-send, desk, hi]", "[sh, -c, 'id > /tmp/pwned']")
    moved = before.replace("double_tap, region: b5, do: {exec", "tap, region: b4, do: {exec")
    (tmp_path / "other.yaml").write_text(before)
    other_file = before.replace("bindings:", "layouts: {evil: other.yaml}\nbindings:")
    header_file = before.replace(
        "region: b1, do: {log: {}}",
        "region: b1, do: {http: {url: 'http://127.0.0.1:9/x', headers: "
        "{Authorization: {file: secret.txt}}}}",
    )
    (tmp_path / "secret.txt").write_text("s3cret\n")
    for text in (changed_argv, moved, other_file, header_file):
        response = client.put("/api/layout", content=text)
        assert response.status_code == 422, text
        assert "the page may not" in response.json()["errors"][0]["message"]
        assert layout.read_text() == before
    kept = before.replace("region: b1, do: {log: {}}", "region: b1, do: {log: {message: hi}}")
    assert client.put("/api/layout", content=kept).status_code == 200
    assert layout.read_text() == kept


def test_the_page_may_not_add_exec(client: TestClient, layout: Path) -> None:
    before = layout.read_text()
    text = before + "  - {gesture: tap, region: b1, do: {exec: {argv: [touch, /tmp/pwned]}}}\n"
    response = client.put("/api/layout", content=text)
    assert response.status_code == 422
    assert "exec" in response.json()["errors"][0]["message"]
    assert response.json()["errors"][0]["line"] == text.count("\n")
    assert layout.read_text() == before
    schema = client.get("/api/schema").json()
    assert "exec" not in schema["actions"]
    # the forms come from what the plugins registered: the mqtt action's options, the tap's
    assert schema["actions"]["mqtt"]["options"]["topic"]["required"] is True
    assert schema["actions"]["mqtt"]["options"]["qos"]["choices"] == [0, 1, 2]
    assert "max_duration_s" in schema["gestures"]["tap"]


def test_edits_keep_comments_and_order() -> None:
    text = (
        "# mine\ndesk: kitamura2017\nunits: mm  # small\nregions:\n"
        "  a: {rect: [0, 0, 10, 10], axis: x}  # keep\nbindings: []\n"
    )
    out = apply_edit(
        text, {"op": "set_region", "name": "a", "shape": "rect", "rect": [0.01, 0.0, 0.03, 0.02]}
    )
    assert out.startswith("# mine\ndesk: kitamura2017\nunits: mm  # small\n")
    # the comment stays on its line (ruamel puts one space before it where there were two)
    assert re.search(r"\n  a: \{rect: \[10.0, 0.0, 30.0, 20.0\], axis: x\} +# keep\n", out)
    out = apply_edit(out, {"op": "rename_region", "name": "a", "new_name": "b"})
    assert "  b: {rect:" in out and "  a:" not in out
    with pytest.raises(ConfigError, match="region name"):
        apply_edit(
            text, {"op": "set_region", "name": "two words", "shape": "rect", "rect": [0, 0, 1, 1]}
        )


def test_other_hosts_need_a_token(layout: Path) -> None:
    registry = load_registry(entry_points=False)
    with pytest.raises(ConfigError, match="token"):
        UiServer(layout, registry, host="0.0.0.0")
    app = UiServer(layout, registry, host="0.0.0.0", token="s3cret-s3cret").app()
    # (a server on every address answers to IP addresses and the machine's names)
    client = TestClient(app, base_url="http://192.0.2.7:8765")
    assert client.get("/").status_code == 401
    assert client.get("/api/layout").status_code == 401
    assert client.put("/api/layout", content="x").status_code == 401
    assert client.get("/?token=wrong").status_code == 401
    assert client.get("/?token=s3cret-s3cret").status_code == 200
    assert (
        client.get("/api/layout", headers={"Authorization": "Bearer s3cret-s3cret"}).status_code
        == 200
    )
    stranger = TestClient(app, base_url="http://192.0.2.7:8765")  # (no cookie of the page's)
    with pytest.raises(Exception):  # noqa: B017 - the socket is closed before it is accepted
        with stranger.websocket_connect("/ws", headers={"host": "192.0.2.7:8765"}) as ws:
            ws.receive_text()
    with client.websocket_connect(
        "/ws?token=s3cret-s3cret", headers={"host": "192.0.2.7:8765"}
    ) as ws:
        assert '"type": "desk"' in ws.receive_text()


def test_listen_address() -> None:
    assert parse_listen("8765") == ("127.0.0.1", 8765)
    assert parse_listen("0.0.0.0:9000") == ("0.0.0.0", 9000)
    assert parse_listen("[::1]:9000") == ("::1", 9000)
    with pytest.raises(ConfigError, match="PORT"):
        parse_listen("localhost:http")


def test_the_page_fetches_nothing_from_elsewhere() -> None:
    for path in STATIC.iterdir():
        text = path.read_text()
        urls = re.findall(r"(?:https?:)?//[A-Za-z0-9.-]+\.[a-z]{2,}", text)
        assert urls in ([], ["http://www.w3.org"]), (path.name, urls)


@pytest.mark.parametrize("route", ["/api/edit", "/api/strokes", "/api/setup/start"])
@pytest.mark.parametrize("body", [b"x", b"[]", b"null", b"[" * 100_000, b"\xff\xfe"])
def test_a_body_that_is_not_a_json_object_is_a_400_not_a_trace(
    client: TestClient, route: str, body: bytes
) -> None:
    """The fuzzing pass's tracebacks: ``request.json()`` on such a body raised in the route
    (HTTP 500 and a trace on the server's log); now one error, no trace."""
    response = client.post(route, content=body)
    assert response.status_code == 400
    assert response.json()["errors"][0]["message"] == "the request's body must be a JSON object"


def test_an_edit_of_the_wrong_shape_is_a_400(client: TestClient) -> None:
    response = client.post("/api/edit", json={"op": "set_region", "name": "b", "shape": "rect",
                                              "rect": 3, "text": ""})  # fmt: skip
    assert response.status_code == 400
    assert "not an edit the designer makes" in response.json()["errors"][0]["message"]
    assert client.post("/api/edit", json={"text": []}).status_code == 400


@pytest.mark.parametrize(("method", "route"), [("post", "/api/check"), ("put", "/api/layout")])
def test_a_body_over_a_megabyte_is_refused_before_it_is_read(
    client: TestClient, method: str, route: str
) -> None:
    """Over 1 MB: 413 with one error (it was a ConfigError outside any handler: a trace),
    refused on its declared length before the body is read."""
    response = getattr(client, method)(route, content=b"a: 1\n" * 250_000)
    assert response.status_code == 413
    assert "larger than 1,000,000 bytes" in response.json()["errors"][0]["message"]


def test_another_site_cannot_reach_the_desk_through_the_browser(layout: Path) -> None:
    """On loopback without a token, any web page the user visited could save a layout (an
    Origin of its own) or read the live desk (a WebSocket), and through DNS rebinding (a Host
    of its own) everything: both are refused; the page itself, and curl, are served."""
    from starlette.websockets import WebSocketDisconnect

    app = UiServer(layout, load_registry(entry_points=False)).app()
    local = TestClient(app, base_url=LOCAL)
    text = layout.read_text()
    assert local.put("/api/layout", content=text, headers={"origin": LOCAL}).status_code == 200
    assert local.get("/api/layout").status_code == 200  # no Origin: curl, a same-origin GET
    evil = {"origin": "http://attacker.example"}
    assert local.put("/api/layout", content=text, headers=evil).status_code == 401
    assert local.post("/api/check", content=text, headers=evil).status_code == 401
    assert local.put("/api/layout", content=text, headers={"origin": "null"}).status_code == 401
    rebound = TestClient(app, base_url="http://attacker.example:8765")
    assert rebound.get("/api/layout").status_code == 401
    here = {"host": "127.0.0.1:8765"}  # (the test client's WebSocket says "testserver")
    with pytest.raises(WebSocketDisconnect):
        with local.websocket_connect("/ws", headers={**here, **evil}) as socket:
            socket.receive_text()
    with local.websocket_connect("/ws", headers={**here, "origin": LOCAL}) as socket:
        assert json.loads(socket.receive_text())["type"] == "desk"


def test_a_websocket_client_that_sends_is_closed(layout: Path) -> None:
    """The page sends nothing: what a client sends was left for the server to buffer (30
    clients of 3 × 15 MB took it past 1 GB). Now it is read and ends that client's socket."""
    from starlette.websockets import WebSocketDisconnect

    client = TestClient(UiServer(layout, load_registry(entry_points=False)).app(), base_url=LOCAL)
    with client.websocket_connect("/ws", headers={"host": "127.0.0.1:8765"}) as socket:
        assert json.loads(socket.receive_text())["type"] == "desk"
        socket.send_text("x" * 1000)
        with pytest.raises(WebSocketDisconnect) as closed:
            while True:
                socket.receive_text()
        assert closed.value.code == 1008


def test_an_edit_of_text_nested_too_deep_is_refused_at_its_place(client: TestClient) -> None:
    """ruamel recursed into 500 open brackets until Python's stack ran out: a 500, and a
    3,000-line traceback in the log."""
    text = "[" * 500 + "]" * 500
    response = client.post("/api/edit", json={"op": "remove_region", "name": "a", "text": text})
    assert response.status_code == 422
    [error] = response.json()["errors"]
    assert (error["line"], error["column"]) == (1, 65) and "nest more than 64" in error["message"]


def test_a_layout_from_the_page_reads_no_file_outside_its_folder(
    client: TestClient, layout: Path, tmp_path: Path
) -> None:
    """`desk: /etc/passwd` in a checked layout was read and quoted back whole in the error
    (and `../../etc/shadow` a line of it); a page's layout now reads files only in the
    layout's folder, its desk's, the shipped profiles and examples."""
    secret = tmp_path.parent / "secret.yaml"
    secret.write_text("root:x:0:0:root:/root:/bin/bash\n")
    text = layout.read_text()
    for desk in (str(secret), "../secret.yaml"):
        sent = text.replace("desk: kitamura2017", f"desk: {desk}")
        for answer in (
            client.post("/api/check", content=sent),
            client.put("/api/layout", content=sent),
        ):
            [error] = answer.json()["errors"]
            assert "outside the layout's folder" in error["message"], error
            assert "root:x" not in answer.text
    assert layout.read_text() == text
    assert client.post("/api/check", content=text).json()["ok"]  # the shipped desk still reads
