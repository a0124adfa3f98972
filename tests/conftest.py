"""Fixtures shared by every test folder: the paper's desk, and desks mounted oddly, with three
legs and with eight (the simulator, stability and estimator tests all use them)."""

from __future__ import annotations

from pathlib import Path

import pytest

from hapticdesk.files.profile import DeskProfile, load_profile, profile_from_mapping
from hapticdesk.files.yamlfile import load_marked_yaml


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


RANGE = "range: {force_n: [150, 150, 300], moment_nm: [4, 4, 4]}"

# Every sensor mounted differently: turned about z, upside down, reporting the load instead of
# the reaction, and tilted about all three axes.
ODD_DESK = f"""
name: odd-mounts
sample_rate_hz: 1200
sensors:
  - {{name: fl, position: [-0.34, -0.22, 0.0], rotation_rpy_deg: [0, 0, 90], {RANGE}}}
  - {{name: fr, position: [0.34, -0.22, 0.0], rotation_rpy_deg: [180, 0, 0], {RANGE}}}
  - {{name: bl, position: [-0.34, 0.22, 0.0], reports: load, {RANGE}}}
  - {{name: br, position: [0.34, 0.22, 0.0], rotation_rpy_deg: [10, -20, 35], reports: load,
     {RANGE}}}
surfaces:
  - name: top
    origin: [0.0, 0.0, 0.733]
    normal: [0, 0, 1]
    polygon: [[-0.375, -0.25], [0.375, -0.25], [0.375, 0.25], [-0.375, 0.25]]
"""

TRI_DESK = """
name: three-legs
sample_rate_hz: 1000
desk: {mass_kg: 9.0, natural_frequency_hz: 7.5}
sensors:
  - {name: a, position: [-0.3, -0.2, 0.0]}
  - {name: b, position: [0.3, -0.2, 0.0]}
  - {name: c, position: [0.0, 0.3, 0.0], rotation_rpy_deg: [0, 0, 120]}
surfaces:
  - name: top
    origin: [0.0, 0.0, 0.72]
    normal: [0, 0, 1]
    polygon: [[-0.35, -0.25], [0.35, -0.25], [0.0, 0.35]]
"""

OCTO_DESK = f"""
name: eight-legs
sample_rate_hz: 1200
desk: {{mass_kg: 40.0, natural_frequency_hz: 4.2}}
sensors:
  - {{name: s1, position: [-0.7, -0.35, 0.0], {RANGE}}}
  - {{name: s2, position: [-0.23, -0.35, 0.0], {RANGE}}}
  - {{name: s3, position: [0.23, -0.35, 0.0], {RANGE}}}
  - {{name: s4, position: [0.7, -0.35, 0.0], {RANGE}}}
  - {{name: s5, position: [-0.7, 0.35, 0.0], rotation_rpy_deg: [0, 0, 180], {RANGE}}}
  - {{name: s6, position: [-0.23, 0.35, 0.0], reports: load, {RANGE}}}
  - {{name: s7, position: [0.23, 0.35, 0.0], rotation_rpy_deg: [180, 0, 90], {RANGE}}}
  - {{name: s8, position: [0.7, 0.35, 0.0], {RANGE}}}
surfaces:
  - name: top
    origin: [0.0, 0.0, 0.75]
    normal: [0, 0, 1]
    polygon: [[-0.75, -0.4], [0.75, -0.4], [0.75, 0.4], [-0.75, 0.4]]
"""


def desk_from_text(text: str, name: str = "desk.yaml") -> DeskProfile:
    path = Path(name)
    return profile_from_mapping(load_marked_yaml(path, text), path)


@pytest.fixture(scope="session")
def odd_desk() -> DeskProfile:
    return desk_from_text(ODD_DESK, "odd.yaml")


@pytest.fixture(scope="session")
def tri_desk() -> DeskProfile:
    return desk_from_text(TRI_DESK, "tri.yaml")


@pytest.fixture(scope="session")
def octo_desk() -> DeskProfile:
    return desk_from_text(OCTO_DESK, "octo.yaml")


@pytest.fixture(params=["paper", "odd", "tri", "octo"])
def any_desk(request: pytest.FixtureRequest) -> DeskProfile:
    """Each kind of desk in turn."""
    if request.param == "paper":
        return load_profile("kitamura2017")
    return request.getfixturevalue(f"{request.param}_desk")  # type: ignore[no-any-return]
