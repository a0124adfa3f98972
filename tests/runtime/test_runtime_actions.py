"""The built-in actions log, exec and http, and how their options are checked in a layout."""

from __future__ import annotations

import http.server
import json
import sys
import threading
import time
from pathlib import Path

import pytest

from hapticdesk.errors import ConfigError
from hapticdesk.gestures.event import GestureEvent
from hapticdesk.gestures.layout_reader import load_layout
from hapticdesk.plugin_loading import load_registry
from hapticdesk.runtime.dispatcher import ActionContext, Dispatcher, Route
from hapticdesk.runtime.lane import Lane

LAYOUT = """\
desk: kitamura2017
units: cm
regions:
  lamp: {rect: [-10, -10, 10, 10]}
bindings:
  - gesture: tap
    region: lamp
    do: %s
"""

TAP = GestureEvent(2.5, "tap", "lamp", 0.01, -0.02, force_n=9.5)


@pytest.fixture(scope="module")
def registry():
    return load_registry(entry_points=False)


def load(tmp_path: Path, registry, do: str):
    path = tmp_path / "layout.yaml"
    path.write_text(LAYOUT % do)
    return load_layout(
        path, action_names=registry.action_names, validate_action=registry.validate_action
    )


def build(tmp_path: Path, registry, do: str):
    layout = load(tmp_path, registry, do)
    context = ActionContext("study", layout_path=layout.path, settings=layout.raw)
    return [
        registry.action(use.name).load()(use.options, context) for use in layout.bindings[0].actions
    ]


@pytest.mark.parametrize(
    ("do", "at", "expected"),
    [
        ("{exec: {argv: []}}", "[]", "`argv` of `exec` must be a non-empty list"),
        ("{exec: {argv: [ls], shell: true}}", "shell", "unknown key `shell`"),
        ('{exec: {argv: [echo, "{{ regoin }}"]}}', '"{{', "regoin"),
        ("{http: {url: ftp://x}}", "ftp", "http:// or https://"),
        ("{http: {url: 'http://h:abc/x'}}", "'http", "no valid port (0-65535): 'h:abc'"),
        ("{http: {url: 'http://h:99999/x'}}", "'http", "no valid port (0-65535): 'h:99999'"),
        ("{http: {url: 'http://x', method: SEND}}", "SEND", "POST, PUT, PATCH, GET, DELETE"),
        ("{mqtt: {topic: 'a/+/set'}}", "'a/+", "must not be empty or hold + or #"),
        ("{mqtt: {topic: a/b, qos: 3}}", "3", "`qos` of `mqtt` must be 0, 1 or 2"),
        ("{log: {message: 5}}", "5", "`message` of `log` must be non-empty text"),
        ("{lamp: {}}", "lamp", "unknown action `lamp`"),
        # the fuzzing pass: an action's timeout had no upper bound
        (
            "{http: {url: 'http://x', timeout_s: 1e300}}",
            "1e300",
            "`timeout_s` in `http` must be <= 3600, found 1e+300; expected > 0 and <= 3600",
        ),
        ("{exec: {argv: [ls], timeout_s: 1e9}}", "1e9", "must be <= 3600, found 1e+09"),
    ],
)
def test_bad_action_options_name_file_line_and_column(tmp_path, registry, do, at, expected):
    with pytest.raises(ConfigError) as err:
        load(tmp_path, registry, do)
    column = len("    do: ") + do.index(at) + 1  # the layout's line 8 is "    do: <do>"
    assert str(err.value).startswith(f"{tmp_path / 'layout.yaml'}:8:{column}: "), str(err.value)
    assert expected in str(err.value)


def test_log_prints_the_event_or_a_message(tmp_path, registry, capsys):
    plain, custom = build(
        tmp_path, registry, '[{log: {}}, {log: {message: "{{ action }} {{ force_n }}"}}]'
    )
    plain(TAP)
    custom(TAP)
    lines = capsys.readouterr().out.splitlines()
    assert json.loads(lines[0].removeprefix("[study] ")) == TAP.to_dict()
    assert lines[1] == "[study] lamp_tap 9.5"


def test_exec_passes_templated_arguments_without_a_shell(tmp_path, registry):
    out = tmp_path / "args.json"
    script = "import json, sys; json.dump(sys.argv[1:], open(sys.argv[1], 'w'))"
    [action] = build(
        tmp_path,
        registry,
        json.dumps(
            {
                "exec": {
                    "argv": [
                        sys.executable,
                        "-c",
                        script,
                        str(out),
                        "{{ region }}; rm -rf /",
                        "$HOME",
                    ]
                }
            }
        ),
    )
    action(TAP)
    assert json.loads(out.read_text()) == [str(out), "lamp; rm -rf /", "$HOME"]


def test_exec_failures_and_timeouts_raise_with_the_reason(tmp_path, registry):
    failing, slow = build(
        tmp_path,
        registry,
        json.dumps(
            [
                {"exec": {"argv": [sys.executable, "-c", "import sys; sys.exit('no lamp here')"]}},
                {
                    "exec": {
                        "argv": [sys.executable, "-c", "import time; time.sleep(30)"],
                        "timeout_s": 0.3,
                    }
                },
            ]
        ),
    )
    with pytest.raises(RuntimeError, match="exited with status 1: no lamp here"):
        failing(TAP)
    with pytest.raises(RuntimeError, match="ran longer than 0.3 s and was killed"):
        slow(TAP)
    assert slow.timeout_s > 0.3  # the dispatcher's watchdog waits for the program's own timeout


class Webhook(http.server.BaseHTTPRequestHandler):
    received: list[tuple[str, str, dict]] = []

    def do_POST(self) -> None:  # noqa: N802 (the stdlib's name)
        body = self.rfile.read(int(self.headers["Content-Length"]))
        Webhook.received.append((self.command, self.path, json.loads(body)))
        self.send_response(404 if self.path == "/missing" else 200)
        self.end_headers()

    def log_message(self, *args: object) -> None:
        pass


@pytest.fixture
def webhook():
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Webhook)
    Webhook.received = []
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{server.server_address[1]}"
    server.shutdown()
    server.server_close()


def test_http_posts_the_event_or_a_templated_document(tmp_path, registry, webhook):
    whole, custom, missing = build(
        tmp_path,
        registry,
        json.dumps(
            [
                {"http": {"url": f"{webhook}/hook"}},
                {
                    "http": {
                        "url": f"{webhook}/{{{{ region }}}}",
                        "json": {"force": "{{ force_n }}"},
                    }
                },
                {"http": {"url": f"{webhook}/missing"}},
            ]
        ),
    )
    whole(TAP)
    custom(TAP)
    with pytest.raises(RuntimeError, match="answered 404"):
        missing(TAP)
    assert Webhook.received[0] == ("POST", "/hook", TAP.to_dict())
    assert Webhook.received[1] == ("POST", "/lamp", {"force": 9.5})


class SlowFirst(http.server.BaseHTTPRequestHandler):
    """Answers `/on` after 0.4 s and `/off` at once; notes each path as it answers."""

    answered: list[str] = []

    def do_POST(self) -> None:  # noqa: N802 (the stdlib's name)
        self.rfile.read(int(self.headers["Content-Length"]))
        if self.path == "/on":
            time.sleep(0.4)
        SlowFirst.answered.append(self.path)
        self.send_response(200)
        self.end_headers()

    def log_message(self, *args: object) -> None:
        pass


def test_two_webhooks_to_one_server_keep_the_gestures_order(tmp_path, registry):
    """`on` then, a moment later on another binding's lane, `off`, to one server that is slow
    to answer the first: `off` waits for it (both `http` actions share the server's
    order_key), so the light ends off. A server written with a template has no key."""
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), SlowFirst)
    SlowFirst.answered = []
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    url = f"http://127.0.0.1:{server.server_address[1]}"
    try:
        uses = [{"http": {"url": f"{url}/on"}}, {"http": {"url": f"{url}/off"}}]
        on, off = build(tmp_path, registry, json.dumps(uses))
        assert on.order_key == off.order_key == f"http http://127.0.0.1:{server.server_address[1]}"
        dispatcher = Dispatcher(watchdog_interval_s=0.01)
        dispatcher.add_route(Route("on", lambda e: e.region == "on", [Lane("on", on)]))
        dispatcher.add_route(Route("off", lambda e: e.region == "off", [Lane("off", off)]))
        dispatcher.submit(GestureEvent(1.0, "tap", "on", 0.0, 0.0))
        dispatcher.submit(GestureEvent(2.0, "tap", "off", 0.0, 0.0))
        assert dispatcher.close(10.0).totals.ok == 2
        assert SlowFirst.answered == ["/on", "/off"]  # (["/off", "/on"] without the key)
    finally:
        server.shutdown()
        server.server_close()
    [templated] = build(tmp_path, registry, json.dumps({"http": {"url": "http://{{ region }}/x"}}))
    assert templated.order_key is None


def test_http_to_a_closed_port_fails_with_the_reason(tmp_path, registry):
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    [action] = build(
        tmp_path,
        registry,
        json.dumps({"http": {"url": f"http://127.0.0.1:{port}/x", "timeout_s": 2}}),
    )
    with pytest.raises(RuntimeError, match="failed: .*refused"):
        action(TAP)
