"""Simulated recordings for the analysis tests (each simulated once per session)."""

from __future__ import annotations

from pathlib import Path

import pytest

from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.profile_reader import load_profile
from hapticdesk.files.recording import Recording
from hapticdesk.sim import Idle, Scene, Swipe, load_scene, simulate

SCENES = Path(__file__).resolve().parents[2] / "examples" / "scenes"


def knock_scene(quiet_s: float = 30.0, knocks: int = 5) -> Scene:
    """A quiet desk, then sideways knocks: quick swipes whose friction lets go at once and
    sets the desk swaying, each followed by 4 s of quiet."""
    actions: list = [Idle(duration_s=quiet_s)]
    for i in range(knocks):
        actions += [Swipe((-0.1, 0.05 * i), (0.1, 0.05 * i)), Idle(duration_s=4.0)]
    return Scene(actions)


@pytest.fixture(scope="session")
def desk() -> DeskProfile:
    return load_profile("kitamura2017")


@pytest.fixture(scope="session")
def bench_sensor() -> DeskProfile:
    """One sensor on the bench, no surfaces (profiles/ati-bench.yaml)."""
    return load_profile("ati-bench")


@pytest.fixture(scope="session")
def paper_recording(desk: DeskProfile) -> Recording:
    """The paper's experiment: nine points, three presses each (88 s, with truth)."""
    return simulate(desk, load_scene(SCENES / "paper-experiment.yaml"), seed=0)


@pytest.fixture(scope="session")
def knock_recording(desk: DeskProfile) -> Recording:
    return simulate(desk, knock_scene(), seed=3)
