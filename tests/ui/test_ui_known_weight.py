"""The page's set-up with a known weight (plugins/ui/known_weight_setup.py) against a running
desk: a simulated 1 kHz load-cell desk whose cells' gains are 5 % off and whose legs stand
2 cm from where its profile has them; 1 kg on the 4 spots the page marks; the profile the
page writes then lands presses within 5 mm."""

from __future__ import annotations

import shutil
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("starlette")
pytest.importorskip("httpx")

from starlette.testclient import TestClient  # noqa: E402

from hapticdesk.analysis.known_weight import suggested_spots  # noqa: E402
from hapticdesk.files.profile import DeskProfile  # noqa: E402
from hapticdesk.files.profile_reader import builtin_profile_path, load_profile  # noqa: E402
from hapticdesk.files.recording_io import write_recording  # noqa: E402
from hapticdesk.plugin_loading import load_registry  # noqa: E402
from hapticdesk.plugins.ui.server import UiServer  # noqa: E402
from hapticdesk.runtime.assembly import build_scene  # noqa: E402
from hapticdesk.runtime.service import Runtime  # noqa: E402
from hapticdesk.sim import Idle, LiftObject, PutObject, Scene, simulate  # noqa: E402
from hapticdesk.sim.loadcells import LoadCellParameters  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
LOCAL = "http://127.0.0.1:8765"
DESK = "kitamura2017-loadcells-1khz"
GAINS = (1.05, 0.95, 1.05, 0.95)
#: where the built desk's cells really are, from the profile's: 2 cm each
MOVES = np.array([[0.02, 0.0], [0.0, 0.02], [-0.0141, 0.0141], [0.0141, -0.0141]])
PRESSES = [(0.25, 0.15), (-0.3, -0.2), (0.0, 0.0), (0.33, -0.21), (-0.2, 0.2), (0.1, -0.05)]


def built_desk(nominal: DeskProfile) -> DeskProfile:
    sensors = tuple(
        replace(s, position=s.position + np.r_[d, 0.0])
        for s, d in zip(nominal.sensors, MOVES, strict=True)
    )
    return replace(nominal, sensors=sensors)


def weight_scene(points: Any, mass_kg: float = 1.0) -> Scene:
    """The weight put on each spot in turn (2 s still), lifted off between them."""
    actions: list[Any] = []
    for x, y in points:
        actions += [
            PutObject("weight", mass_kg, (float(x), float(y)), duration_s=0.4, wait_s=1.5),
            LiftObject("weight", duration_s=0.3, wait_s=2.0),
        ]
    return Scene([*actions, Idle(duration_s=1.0)], seed=5)


@pytest.fixture(scope="module")
def setup_files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """A layout and a copy of the desk's profile in a folder of their own, and the desk as
    built recorded with 1 kg on the page's 4 spots."""
    folder = tmp_path_factory.mktemp("weight")
    source = builtin_profile_path(DESK)
    assert source is not None
    desk_file = folder / f"{DESK}.yaml"
    shutil.copy(source, desk_file)
    layout = folder / "buttons.yaml"
    shutil.copy(ROOT / "examples" / "layouts" / "buttons.yaml", layout)
    nominal = load_profile(desk_file)
    built = built_desk(nominal)
    cells = LoadCellParameters.for_rate(nominal.sample_rate_hz, gains=GAINS)
    recording = folder / "weight.csv"
    scene = weight_scene(suggested_spots(nominal, 4))
    write_recording(recording, simulate(built, scene, cells=cells))
    return {"folder": folder, "desk": desk_file, "layout": layout, "recording": recording,
            "nominal": nominal, "built": built, "cells": cells}  # fmt: skip


#: the runs the tests built, released after each test (a run built and never started keeps
#: its dispatcher's watchdog thread until it is closed)
_BUILT: list[Any] = []


@pytest.fixture(autouse=True)
def _release_built_runs() -> Any:
    yield
    while _BUILT:
        _BUILT.pop().close()


def serve(files: dict[str, Any], **options: Any) -> tuple[UiServer, TestClient, Runtime]:
    """The page's server, with a run replaying the recording (not started yet) attached."""
    registry = load_registry(entry_points=False)
    assembly = build_scene(
        files["layout"],
        f"replay:{files['recording']}",
        registry,
        desk=str(files["desk"]),
        speed=0,
        actions=False,
    )
    _BUILT.append(assembly)
    server = UiServer(files["layout"], registry, **options)
    client = TestClient(server.app(), base_url=LOCAL)
    runtime = Runtime(assembly)
    server.attach(runtime)
    return server, client, runtime


def test_a_known_weight_on_four_spots_calibrates_the_desk(
    setup_files: dict[str, Any], press_errors: Any
) -> None:
    files = setup_files
    server, client, runtime = serve(files)
    spots = client.get("/api/setup/weight/spots?count=4").json()
    assert spots["ok"] is True
    np.testing.assert_allclose(spots["spots_m"], suggested_spots(files["nominal"], 4), atol=1e-5)
    started = client.post("/api/setup/weight/start", json={"mass_kg": 1, "count": 4}).json()
    assert started == {"ok": True, "mass_kg": 1.0, "spots_m": spots["spots_m"]}
    runtime.run(handle_signals=False)
    result = client.post("/api/setup/weight/finish").json()
    assert result["ok"] is True, result
    assert runtime.block_taps == ()  # the session let go of the sensing thread
    # fitted on the first three spots, checked on the fourth, which the fit did not use
    assert result["spots_used"] == 3 and result["check_index"] == 3
    assert result["check"]["point_m"] == spots["spots_m"][3]
    assert result["check"]["error_m"] < 0.005 and result["passed"] is True
    assert result["check_before_m"] > 0.01  # the profile as it was: centimetres off
    assert len(result["leave_one_out"]) == 4
    gains = np.array([c["gain"] for c in result["cells"]])
    np.testing.assert_allclose(gains, 1 / np.array(GAINS), rtol=0.02)
    written = Path(result["profile_path"])
    assert written == files["folder"] / f"{DESK}-calibrated.yaml"
    assert "the page's set-up" in written.read_text().splitlines()[0]
    calibrated = load_profile(written)
    before = press_errors(files["nominal"], files["built"], files["cells"], PRESSES)
    after = press_errors(calibrated, files["built"], files["cells"], PRESSES)
    assert before.max() > 0.01, before  # uncalibrated: centimetres off
    assert after.max() < 0.005, after  # the floor: within 5 mm
    assert client.post("/api/setup/weight/finish").status_code == 422  # nothing to finish


@pytest.mark.parametrize(
    ("body", "needle"),
    [
        ({"mass_kg": 0, "count": 4}, "a mass above 0, found 0"),
        ({"mass_kg": -1, "count": 4}, "a mass above 0, found -1"),
        ({"mass_kg": "a bag", "count": 4}, "a number from 0.2 to 100"),
        ({"mass_kg": True, "count": 4}, "found True"),
        ({"count": 4}, "none was given"),
        ({"mass_kg": 1e9, "count": 4}, "found 1e+09"),
        ({"mass_kg": 1, "count": 2}, "mark 3 to 5 spots for the weight"),
        ({"mass_kg": 1, "count": "four"}, "found 'four'"),
    ],
)
def test_bad_input_is_named_without_a_traceback(
    setup_files: dict[str, Any], body: dict[str, Any], needle: str
) -> None:
    _, client, _ = serve(setup_files)
    answer = client.post("/api/setup/weight/start", json=body)
    assert answer.status_code == 422
    (error,) = answer.json()["errors"]
    assert needle in error["message"] and "Traceback" not in error["message"]


def test_a_spot_with_no_weight_on_it_is_said(setup_files: dict[str, Any]) -> None:
    """Asked for five spots, the weight went on four: Finish says so, nothing is written."""
    files = setup_files
    for old in files["folder"].glob("*-calibrated.yaml"):
        old.unlink()
    _, client, runtime = serve(files)
    assert client.post("/api/setup/weight/start", json={"mass_kg": 1, "count": 5}).json()["ok"]
    runtime.run(handle_signals=False)
    answer = client.post("/api/setup/weight/finish")
    assert answer.status_code == 422
    message = answer.json()["errors"][0]["message"]
    assert "expected the 1 kg weight on 5 spots one after another, found it 4 times" in message
    assert list(files["folder"].glob("*-calibrated.yaml")) == []


def test_the_guards_and_a_desk_without_load_cells(setup_files: dict[str, Any]) -> None:
    """The token and the origin guard these routes as every other; no run, or a desk of
    six-axis sensors, is an error that says why."""
    files = setup_files
    _, client, _ = serve(files, token="s3cret")
    assert client.get("/api/setup/weight/spots").status_code == 401
    assert client.post("/api/setup/weight/start", json={"mass_kg": 1}).status_code == 401
    assert client.post("/api/setup/weight/finish").status_code == 401
    bearer = {"Authorization": "Bearer s3cret"}
    assert client.get("/api/setup/weight/spots?count=3", headers=bearer).json()["ok"]
    _, open_client, _ = serve(files)
    evil = {"Origin": "http://evil.example"}
    assert open_client.post("/api/setup/weight/finish", headers=evil).status_code == 401
    assert open_client.post("/api/setup/weight/start", content=b"[1]").status_code == 400
    idle = TestClient(UiServer(files["layout"], None).app(), base_url=LOCAL)
    answer = idle.post("/api/setup/weight/start", json={"mass_kg": 1, "count": 4})
    assert answer.status_code == 422 and "needs a running desk" in answer.text
    registry = load_registry(entry_points=False)
    six_axis = UiServer(files["layout"], registry)
    assembly = build_scene(
        files["layout"], "sim:" + str(ROOT / "examples" / "scenes" / "buttons.yaml"), registry,
        speed=0, actions=False,
    )  # fmt: skip
    _BUILT.append(assembly)
    six_axis.attach(Runtime(assembly))
    answer = TestClient(six_axis.app(), base_url=LOCAL).get("/api/setup/weight/spots")
    assert answer.status_code == 422
    assert "fits load cells that measure the vertical force" in answer.text
