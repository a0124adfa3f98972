"""The WebSocket hub: a browser that does not read costs the publisher nothing and the
server bounded memory (README, "Cost on sensing")."""

from __future__ import annotations

import json
import shutil
import socket
import time
from pathlib import Path

import pytest

pytest.importorskip("uvicorn")
websockets_sync = pytest.importorskip("websockets.sync.client")

from hapticdesk.plugin_loading import load_registry  # noqa: E402
from hapticdesk.plugins.ui.hub import CLIENT_QUEUE  # noqa: E402
from hapticdesk.plugins.ui.server import UiServer  # noqa: E402

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def test_a_browser_that_does_not_read_drops_frames_and_never_blocks(tmp_path: Path) -> None:
    layout = tmp_path / "buttons.yaml"
    shutil.copy(EXAMPLES / "layouts" / "buttons.yaml", layout)
    server = UiServer(layout, load_registry(entry_points=False), port=0)
    server.start()
    slow = None
    try:
        # a client with a tiny receive buffer that reads the first message and then nothing
        slow = websockets_sync.connect(f"ws://127.0.0.1:{server.port}/ws", max_size=None)
        slow.socket.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        assert json.loads(slow.recv(timeout=10))["type"] == "desk"
        deadline = time.monotonic() + 5
        while server.clients < 1 and time.monotonic() < deadline:
            time.sleep(0.01)
        assert server.clients == 1
        frame = {"type": "contact", "t": 0.0, "x": 0.01, "y": 0.02, "force_n": 5.0}
        started = time.perf_counter()
        for k in range(5_000):
            server.hub.publish(dict(frame, t=k / 1200, phase="hold", surface="top", pad="x" * 200))
            if k % 10 == 0:
                server.hub.publish({"type": "gesture", "t": k / 1200, "gesture": "tap", "n": k})
        spent = time.perf_counter() - started
        # what the sensing side pays: a JSON encoding and a hand-off per frame, no waiting
        assert spent / 5_500 < 200e-6, f"{spent / 5_500 * 1e6:.0f} µs per publish"
        time.sleep(1.0)  # let the server's loop push what the socket takes
        [client] = list(server.hub.clients)
        assert len(client.queue) <= CLIENT_QUEUE  # bounded, oldest gestures dropped
        assert server.hub.contacts_dropped > 2_500  # the slow page lost frames, not the desk
        slow.socket.close()  # gone without a goodbye, as a crashed browser
    finally:
        server.close()
        if slow is not None:
            slow.close()  # (the client's own threads: its socket is gone, they end)
    # the close does not wait on the page that stopped reading: the server's thread has ended
    assert server._thread is not None and not server._thread.is_alive()
