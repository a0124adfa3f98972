"""Faults of the built-in actions (issue 11, "Hardening"): credentials in a webhook, a server
that answers a byte at a time, and a program that leaves children behind."""

from __future__ import annotations

import contextlib
import json
import logging
import os
import socket
import sys
import threading
import time
from pathlib import Path

import pytest

from hapticdesk.errors import ConfigError
from hapticdesk.plugin_loading import load_registry
from hapticdesk.runtime.lane import Lane

from .test_runtime_actions import TAP, build, load


@pytest.fixture(scope="module")
def registry():
    return load_registry(entry_points=False)


WEBHOOK_ID = "d3adb33f-secret-webhook-id"


class RawServer:
    """A TCP server on loopback that records requests and answers as ``reply`` says."""

    def __init__(self, reply) -> None:
        self.requests: list[bytes] = []
        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(8)
        self.port = self.sock.getsockname()[1]
        self.reply = reply
        self._accepting = threading.Thread(target=self._serve, daemon=True)
        self._accepting.start()

    def _serve(self) -> None:
        while True:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                return
            threading.Thread(target=self._answer, args=(conn,), daemon=True).start()

    def _answer(self, conn: socket.socket) -> None:
        with conn:
            data = b""
            while b"\r\n\r\n" not in data:
                chunk = conn.recv(4096)
                if not chunk:
                    return
                data += chunk
            head, _, body = data.partition(b"\r\n\r\n")
            length = next(
                (int(line.split(b":")[1]) for line in head.split(b"\r\n")
                 if line.lower().startswith(b"content-length")), 0,
            )  # fmt: skip
            while len(body) < length:
                body += conn.recv(4096)
            self.requests.append(head + b"\r\n\r\n" + body)
            try:
                self.reply(conn)
            except OSError:
                pass

    def close(self) -> None:
        # a close alone does not wake a thread blocked in accept() on Linux; a shutdown does
        with contextlib.suppress(OSError):
            self.sock.shutdown(socket.SHUT_RDWR)
        self.sock.close()
        self._accepting.join(5.0)
        assert not self._accepting.is_alive(), "the test server's accept thread did not end"


def ok(conn: socket.socket) -> None:
    conn.sendall(b"HTTP/1.1 200 OK\r\nContent-Length: 2\r\nConnection: close\r\n\r\nok")


def one_byte_at_a_time(conn: socket.socket) -> None:
    answer = b"HTTP/1.1 200 OK\r\nContent-Length: 200\r\n\r\n" + b"x" * 200
    for i in range(len(answer)):  # each read gets a byte well within any per-read timeout
        conn.sendall(answer[i : i + 1])
        time.sleep(0.05)


@pytest.mark.parametrize(
    ("do", "expected"),
    [
        ("{http: {url: 'http://user:hunter2@10.0.0.5/hook'}}", "must not hold `user:password@`"),
        (
            "{http: {url: 'http://10.0.0.5/hook', headers: {Authorization: 'Bearer abc'}}}",
            "header `Authorization` carries credentials",
        ),
        (
            "{http: {url: 'http://10.0.0.5/hook', headers: {X-Api-Key: abc}}}",
            "header `X-Api-Key` carries credentials",
        ),
        (
            "{http: {url: 'http://x/h', headers: {Authorization: {prefix: 'Bearer '}}}}",
            "needs `env: VARIABLE` or `file: PATH`",
        ),
    ],
)
def test_credentials_written_into_the_layout_are_refused(tmp_path, registry, do, expected):
    with pytest.raises(ConfigError, match=expected) as err:
        load(tmp_path, registry, do)
    assert "layout.yaml:" in str(err.value)
    assert "hunter2" not in str(err.value)


def test_a_bearer_token_comes_from_the_environment_or_a_file(tmp_path, registry, monkeypatch):
    server = RawServer(ok)
    try:
        monkeypatch.setenv("HA_TOKEN", "tok-from-env")
        (tmp_path / "token.txt").write_text("tok-from-file\n")
        url = f"http://127.0.0.1:{server.port}/api/webhook/{WEBHOOK_ID}"
        env_action, file_action = build(
            tmp_path,
            registry,
            json.dumps(
                [
                    {
                        "http": {
                            "url": url,
                            "headers": {"Authorization": {"env": "HA_TOKEN", "prefix": "Bearer "}},
                        }
                    },
                    {"http": {"url": url, "headers": {"X-Token": {"file": "token.txt"}}}},
                ]
            ),  # fmt: skip
        )
        env_action(TAP)
        file_action(TAP)
    finally:
        server.close()
    assert b"Authorization: Bearer tok-from-env\r\n" in server.requests[0]
    assert b"X-Token: tok-from-file\r\n" in server.requests[1]
    assert f"/api/webhook/{WEBHOOK_ID}".encode() in server.requests[0]


def test_a_failing_webhook_is_logged_without_its_path_or_credentials(
    tmp_path, registry, monkeypatch, caplog
):
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]  # nobody listens here
    monkeypatch.setenv("HA_TOKEN", "tok-secret")
    url = f"http://127.0.0.1:{port}/api/webhook/{WEBHOOK_ID}?key=qsecret"
    [action] = build(
        tmp_path,
        registry,
        json.dumps({"http": {"url": url, "headers": {"Authorization": {"env": "HA_TOKEN"}}}}),
    )
    lane = Lane("binding 1 → http", action)
    with caplog.at_level(logging.WARNING):
        for _ in range(3):
            lane.submit(TAP)
        lane.close(time.monotonic() + 5)
    assert lane.stats.failed == 3
    assert caplog.text.count(f"POST http://127.0.0.1:{port}/… failed") == 3
    for secret in (WEBHOOK_ID, "qsecret", "tok-secret", "/api/webhook"):
        assert secret not in caplog.text


def test_a_url_that_renders_credentials_is_refused_at_call_time():
    # a template could render `user:pw@`; urllib took `user:pw@host` for the host
    from hapticdesk.plugins.http import call

    with pytest.raises(RuntimeError, match="holds `user:password@`") as err:
        call("GET", "http://lamp:hunter2@10.0.0.5/h", None, {}, 1.0)
    assert "hunter2" not in str(err.value)


def test_the_http_timeout_bounds_the_whole_call_not_each_read(tmp_path, registry):
    server = RawServer(one_byte_at_a_time)  # 240 bytes at 50 ms each: 12 s in all
    try:
        [action] = build(
            tmp_path,
            registry,
            json.dumps({"http": {"url": f"http://127.0.0.1:{server.port}/x", "timeout_s": 0.5}}),
        )
        started = time.monotonic()
        with pytest.raises(RuntimeError, match=r"took longer than 0.5 s in all"):
            action(TAP)
        took = time.monotonic() - started
    finally:
        server.close()
    assert took < 1.0, took


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split(")")[-1].split()[0] != "Z"  # a zombie is dead
    except FileNotFoundError:
        return False


def test_an_exec_timeout_ends_the_programs_children_too(tmp_path, registry):
    pids = tmp_path / "pids"
    script = f"sleep 40 & echo $! > {pids}; sleep 100"
    [action] = build(
        tmp_path, registry, json.dumps({"exec": {"argv": ["sh", "-c", script], "timeout_s": 0.5}})
    )
    started = time.monotonic()
    with pytest.raises(RuntimeError, match="ran longer than 0.5 s"):
        action(TAP)
    assert time.monotonic() - started < 3
    orphan = int(pids.read_text())
    deadline = time.monotonic() + 2
    while _alive(orphan) and time.monotonic() < deadline:
        time.sleep(0.02)
    alive = _alive(orphan)
    if alive:
        os.kill(orphan, 9)  # do not leave it behind for the next test
    assert not alive, "the program's background child outlived the timeout"


def test_exec_without_a_timeout_still_runs_normally(tmp_path, registry):
    out = tmp_path / "out.txt"
    [action] = build(
        tmp_path,
        registry,
        json.dumps({"exec": {"argv": [sys.executable, "-c",
                                      f"open({str(out)!r}, 'w').write('{{{{ region }}}}')"]}}),
    )  # fmt: skip
    action(TAP)
    assert Path(out).read_text() == "lamp"
