"""`hapticdesk run ... --ui [HOST:]PORT` adds the page to a running service; a save is used."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

httpx = pytest.importorskip("httpx")
websockets_sync = pytest.importorskip("websockets.sync.client")
pytest.importorskip("uvicorn")


from .conftest import stop_process, watch_address  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]


def test_run_with_ui_serves_the_page_and_reloads_a_saved_layout(tmp_path: Path) -> None:
    layout = tmp_path / "buttons.yaml"
    shutil.copy(ROOT / "examples" / "layouts" / "buttons.yaml", layout)
    scene = tmp_path / "taps.yaml"
    scene.write_text(
        "name: t\ndesk: kitamura2017\nunits: cm\nquiet_s: 2.0\ntimeline:\n"
        + "  - tap: {point: [0, 0], wait_s: 0.5}\n" * 30
    )
    out = (tmp_path / "stdout.txt").open("w")  # the `log` actions print each tap here
    proc = subprocess.Popen(
        [sys.executable, "-m", "hapticdesk", "run", "--layout", str(layout)]
        + ["--source", f"sim:{scene}", "--ui", "127.0.0.1:0", "--drain", "1"],
        stderr=subprocess.PIPE,
        stdout=out,
        text=True,
    )
    lines: list[str] = []
    found, url = watch_address(proc, lines)
    try:
        assert found.wait(30), "".join(lines)
        base = url[0]
        assert "127.0.0.1" in base
        assert httpx.get(base + "api/layout").text == layout.read_text()
        ws_url = base.replace("http://", "ws://") + "ws"

        def wait_for(ws: object, kind: str, region: str | None = None) -> dict:
            deadline = time.monotonic() + 15
            while time.monotonic() < deadline:
                m = json.loads(ws.recv(timeout=15))  # type: ignore[attr-defined]
                if m["type"] == kind and (region is None or m.get("region") == region):
                    return m
            raise AssertionError(f"no {kind} {region or ''} within 15 s")

        with websockets_sync.connect(ws_url) as ws:
            desk = json.loads(ws.recv(timeout=10))
            assert desk["type"] == "desk"
            if not desk["live"]:
                # the page may open while the run still builds (the estimator's kernels load):
                # the desk message comes again, live, when the run starts
                desk = wait_for(ws, "desk")
            assert desk["live"] is True
            assert {r["name"] for r in desk["regions"]} == {f"b{i}" for i in range(1, 10)}
            contact = wait_for(ws, "contact")
            assert set(contact) >= {"t", "x", "y", "force_n", "phase", "surface"}
            assert wait_for(ws, "gesture", "b5")["gesture"] == "tap"
            text = layout.read_text().replace(
                "b5: {rect: [-2.5, -2.5, 2.5, 2.5]}", "centre: {rect: [-3, -3, 3, 3]}"
            )
            text = text.replace("region: b5,", "region: centre,")
            saved = httpx.put(base + "api/layout", content=text, timeout=30).json()
            assert saved == {"ok": True, "errors": [], "reloaded": True}
            assert "centre" in {r["name"] for r in wait_for(ws, "desk")["regions"]}
            assert wait_for(ws, "gesture", "centre")["gesture"] == "tap"
    finally:
        stop_process(proc)
    out.close()
    taps = [json.loads(line.split("] ", 1)[1]) for line in (tmp_path / "stdout.txt").open()]
    regions = [t["region"] for t in taps]
    # the service kept running and its log actions moved from b5 to the saved `centre`
    assert "b5" in regions and "centre" in regions, regions
    assert regions.index("centre") > max(i for i, r in enumerate(regions) if r == "b5")
