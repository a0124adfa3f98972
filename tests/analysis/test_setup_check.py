"""The set-up check: presses at known points on a simulated desk, checked against a profile
with one sensor's sign and another's position wrong, find both and propose the fix."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from hapticdesk.analysis.setup_check import check_setup
from hapticdesk.errors import ConfigError
from hapticdesk.sim import load_scene, simulate

POINTS = np.array(
    [[-0.25, -0.15], [0.25, -0.15], [0.25, 0.15], [-0.25, 0.15], [0.0, 0.0], [0.1, -0.05]]
)


@pytest.fixture(scope="module")
def recording(tmp_path_factory, paper_desk):
    scene = tmp_path_factory.mktemp("setup") / "presses.yaml"
    scene.write_text(
        "name: setup\ndesk: kitamura2017\nquiet_s: 2.0\ntimeline:\n"
        + "".join(
            f"  - press: {{point: [{x}, {y}], hold_s: 1.0, wait_s: 0.6}}\n" for x, y in POINTS
        )
    )
    return simulate(paper_desk, load_scene(scene), seed=3)


def test_a_right_profile_has_no_findings_and_small_residuals(paper_desk, recording):
    report = check_setup(paper_desk, recording.t, recording.wrench, POINTS)
    assert report.findings == [], [f.message for f in report.findings]
    assert report.placed.all()
    assert report.residual_m.max() < 0.01
    assert (
        np.abs(report.fitted_positions - [s.position[:2] for s in paper_desk.sensors]).max() < 0.005
    )


def test_a_wrong_sign_and_a_wrong_position_are_found_and_fixed(paper_desk, recording):
    sensors = list(paper_desk.sensors)
    sensors[1] = replace(sensors[1], reports="load")  # the sign flipped
    moved = sensors[2].position + np.array([0.06, -0.04, 0.0])
    sensors[2] = replace(sensors[2], position=moved)  # 7 cm off
    wrong = replace(paper_desk, sensors=tuple(sensors))
    report = check_setup(wrong, recording.t, recording.wrench, POINTS)
    kinds = {(f.sensor, f.kind) for f in report.findings}
    assert kinds == {(sensors[1].name, "sign"), (sensors[2].name, "position")}, report.findings
    assert report.corrected is not None
    fixed = report.corrected.sensors
    assert fixed[1].reports == "reaction"
    assert np.allclose(fixed[2].position[:2], paper_desk.sensors[2].position[:2], atol=0.005)
    # the corrected profile places the presses where they were made
    again = check_setup(report.corrected, recording.t, recording.wrench, POINTS)
    assert again.findings == []
    assert again.residual_m.max() < 0.01
    assert not (report.placed.all() and report.residual_m.max() < 0.01)  # the wrong one did not
    assert "reports: reaction" in report.profile_snippet()


def test_the_wrong_number_of_presses_is_said(paper_desk, recording):
    with pytest.raises(ConfigError, match="expected 5 presses .* found 6"):
        check_setup(paper_desk, recording.t, recording.wrench, POINTS[:5])
