"""Fixtures shared by every test folder: the paper's desk, and desks mounted oddly, with three
legs and with eight (the simulator, stability and estimator tests all use them)."""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.profile_reader import load_profile


@pytest.fixture(autouse=True)
def _no_installed_plugins(monkeypatch: pytest.MonkeyPatch) -> None:
    """Tests never auto-load installed entry points (STYLE.md 10); the test that checks
    entry-point loading turns this off itself. Subprocesses inherit it. Nor does a block list
    in the environment take built-ins away."""
    from hapticdesk.registry import BLOCK_ENV, DISABLE_AUTOLOAD_ENV

    monkeypatch.setenv(DISABLE_AUTOLOAD_ENV, "1")
    monkeypatch.delenv(BLOCK_ENV, raising=False)


@pytest.fixture(scope="session")
def paper_desk() -> DeskProfile:
    """The paper's desk (profiles/kitamura2017.yaml)."""
    return load_profile("kitamura2017")


# Desks mounted oddly, with three legs and with eight: profiles in examples/desks/ (so that
# the scripts measure on them too, e.g. `scripts/swipe_accuracy.py --desk`)
DESKS = Path(__file__).resolve().parents[1] / "examples" / "desks"


@pytest.fixture(scope="session")
def odd_desk() -> DeskProfile:
    """Every sensor mounted differently (examples/desks/odd-mounts.yaml)."""
    return load_profile(DESKS / "odd-mounts.yaml")


@pytest.fixture(scope="session")
def tri_desk() -> DeskProfile:
    """Three legs (examples/desks/three-legs.yaml)."""
    return load_profile(DESKS / "three-legs.yaml")


@pytest.fixture(scope="session")
def octo_desk() -> DeskProfile:
    """Eight legs, a slow sway (examples/desks/eight-legs.yaml)."""
    return load_profile(DESKS / "eight-legs.yaml")


@pytest.fixture(params=["paper", "odd", "tri", "octo"])
def any_desk(request: pytest.FixtureRequest) -> DeskProfile:
    """Each kind of desk in turn."""
    if request.param == "paper":
        return load_profile("kitamura2017")
    return request.getfixturevalue(f"{request.param}_desk")  # type: ignore[no-any-return]


def _press_errors(profile: DeskProfile, built: DeskProfile, cells: object, points: list) -> object:
    """Presses of 10 N held 1 s at ``points`` on the desk ``built`` (its load cells
    ``cells``: LoadCellParameters), located with ``profile``: each press's distance from
    where it was made (the medians over its hold), metres."""
    import numpy as np

    from hapticdesk.estimator import estimate
    from hapticdesk.sim import Press, Scene, simulate

    scene = Scene([Press(p, peak_n=10.0, hold_s=1.0) for p in points], seed=4)
    rec = simulate(built, scene, cells=cells)  # type: ignore[arg-type]
    contacts = estimate(profile, rec)
    action = rec.extra["true_action"]
    errors = []
    for k in range(len(points)):
        held = (action == k) & contacts.located & (contacts.force_n > 5.0)
        assert held.sum() > 20
        dx = np.median(contacts.x[held]) - np.median(rec.extra["true_x"][held])
        dy = np.median(contacts.y[held]) - np.median(rec.extra["true_y"][held])
        errors.append(np.hypot(dx, dy))
    return np.array(errors)


@pytest.fixture(scope="session")
def press_errors() -> object:
    """``press_errors(profile, built, cells, points)``: how far presses on a load-cell desk as
    built land with ``profile`` (the set-up with a known weight's tests, analysis and page)."""
    return _press_errors


def _python_probe(code: str, *args: str, timeout: float = 120.0) -> Any:
    """Run ``code`` in a fresh interpreter (so what it imports starts from nothing) and return
    its last line of output read as JSON; a child that fails shows its stderr."""
    done = subprocess.run(
        [sys.executable, "-c", code, *args], capture_output=True, text=True, timeout=timeout
    )
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(done.stdout.splitlines()[-1])


@pytest.fixture(scope="session")
def python_probe() -> Callable[..., Any]:
    """``python_probe(code, *argv, timeout=120)``: what a snippet run in a fresh interpreter
    prints last, as JSON (the start-up and import tests ask what a new process loaded)."""
    return _python_probe
