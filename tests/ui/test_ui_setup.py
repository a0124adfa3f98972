"""The page's set-up check API against a running service: a recorded session of presses at
marked points, read through a profile with one sensor's sign wrong, finds it."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

pytest.importorskip("starlette")
pytest.importorskip("httpx")

from starlette.testclient import TestClient  # noqa: E402

from hapticdesk.files.profile_reader import load_profile  # noqa: E402
from hapticdesk.files.recording_io import write_recording  # noqa: E402
from hapticdesk.plugin_loading import load_registry  # noqa: E402
from hapticdesk.plugins.ui.server import UiServer  # noqa: E402
from hapticdesk.runtime.assembly import build_scene  # noqa: E402
from hapticdesk.runtime.service import Runtime  # noqa: E402
from hapticdesk.sim import load_scene, simulate  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
POINTS = [[-0.25, -0.15], [0.25, -0.15], [0.25, 0.15], [-0.25, 0.15], [0.0, 0.0], [0.1, -0.05]]

LOCAL = "http://127.0.0.1:8765"  # the UI answers its own address only


def test_the_set_up_check_finds_a_wrong_sign_in_a_live_session(tmp_path: Path) -> None:
    desk = load_profile("kitamura2017")
    scene = tmp_path / "presses.yaml"
    scene.write_text(
        "name: setup\ndesk: kitamura2017\nquiet_s: 2.0\ntimeline:\n"
        + "".join(
            f"  - press: {{point: [{x}, {y}], hold_s: 1.0, wait_s: 0.6}}\n" for x, y in POINTS
        )
    )
    recording = tmp_path / "presses.csv"
    write_recording(recording, simulate(desk, load_scene(scene), seed=3))
    wrong = tmp_path / "new-desk.yaml"  # the person got `fr`'s sign wrong
    text = (ROOT / "profiles" / "kitamura2017.yaml").read_text()
    text = text.replace(
        "[0.34, -0.22, 0.0], rotation_rpy_deg: [0, 0, 0], reports: reaction",
        "[0.34, -0.22, 0.0], rotation_rpy_deg: [0, 0, 0], reports: load",
    )
    wrong.write_text(text)
    layout = tmp_path / "buttons.yaml"
    shutil.copy(ROOT / "examples" / "layouts" / "buttons.yaml", layout)
    registry = load_registry(entry_points=False)
    assembly = build_scene(
        layout, f"replay:{recording}", registry, desk=str(wrong), speed=0, actions=False
    )
    server = UiServer(layout, registry)
    client = TestClient(server.app(), base_url=LOCAL)
    runtime = Runtime(assembly)
    assert client.post("/api/setup/start", json={"points": POINTS}).status_code == 422  # no run
    server.attach(runtime)
    assert client.post("/api/setup/start", json={"points": POINTS[:2]}).status_code == 422
    assert client.post("/api/setup/start", json={"points": POINTS}).json() == {"ok": True}
    runtime.run(handle_signals=False)
    result = client.post("/api/setup/finish").json()
    assert result["ok"] is True
    assert [(f["sensor"], f["kind"]) for f in result["findings"]] == [("fr", "sign")]
    assert (
        "{name: fr, position: [0.34, -0.22, 0.0], reports: reaction}" in result["profile_snippet"]
    )
    assert result["captured_s"] > 15
    assert result["noise_fz_n"] is not None and result["noise_fz_n"] > 0
    assert runtime.block_taps == ()  # the session let go of the sensing thread
    assert client.post("/api/setup/finish").status_code == 422  # nothing left to finish
