"""Fixtures shared by every test folder: the paper's desk, and desks mounted oddly, with three
legs and with eight (the simulator, stability and estimator tests all use them)."""

from __future__ import annotations

from pathlib import Path

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
