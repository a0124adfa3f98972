"""F_tth and F_rth from presses (paper §5.2), on the simulated paper experiment."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import yaml

from hapticdesk.analysis.thresholds import ThresholdSummary, derive_thresholds, local_slope
from hapticdesk.cli import main
from hapticdesk.errors import ConfigError
from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.recording import Recording
from hapticdesk.files.recording_io import write_recording
from hapticdesk.sim import Idle, Scene, SensorParameters, load_scene, simulate

from .conftest import SCENES

NINE_POINTS = [(x, y) for y in (0.2, 0.0, -0.2) for x in (-0.3, 0.0, 0.3)]


@pytest.fixture(scope="module")
def paper_report(desk: DeskProfile, paper_recording: Recording):
    return derive_thresholds(desk, paper_recording)


def test_every_press_of_the_paper_experiment_is_found_where_it_was_made(paper_report) -> None:
    presses = paper_report.presses
    assert len(presses) == 27
    for i, press in enumerate(presses):  # three presses per point, in the scene's order
        target = NINE_POINTS[i // 3]
        assert math.hypot(press.x - target[0], press.y - target[1]) < 0.01
        assert 15.0 * 0.9 < press.peak_n < 25.0 * 1.1  # the human model's 15–25 N peaks


def test_thresholds_lie_in_the_papers_range_and_follow_its_rule(paper_report) -> None:
    touch, release = paper_report.touch, paper_report.release
    print(f"F_tth triggered {touch.triggered}/27, mean {touch.mean_n:.2f} N")
    print(f"F_rth triggered {release.triggered}/27, mean {release.mean_n}")
    assert touch.triggered >= 20  # measured: 27 of 27 (the simulated desk settles at once)
    assert release.triggered >= 1  # measured: 4 of 27
    for summary in (touch, release):
        assert summary.presses == 27
        assert 1.8 <= summary.min_n <= summary.mean_n <= summary.max_n <= 12.0
        # only values >= the contact force count; candidates never fall below it
        assert summary.min_n >= 2.0
        assert all(c >= 2.0 for c in summary.candidates_n)
        assert summary.suggested_n == max(summary.candidates_n)
        assert summary.suggested_n == pytest.approx(summary.mean_n + summary.std_n, abs=0.006)
    values = [p.touch_n for p in paper_report.presses if p.touch_n is not None]
    assert touch.mean_n == pytest.approx(np.mean(values))


def test_presses_without_a_trigger_say_why(paper_report) -> None:
    for p in paper_report.presses:
        assert (p.release_n is None) == (p.release_reason != "diverged")
        assert (p.touch_n is None) == (not p.touch_reason.startswith("converged"))
        if p.release_n is not None:  # found while releasing, above the 2 N floor
            assert p.release_t is not None and p.touch_t is not None
            assert p.touch_t < p.release_t <= p.t_end
            assert p.release_n >= 2.0
    untriggered = [p for p in paper_report.presses if p.release_n is None]
    assert untriggered, "the simulated desk leaves some presses without a divergence"
    assert all("did not diverge" in p.release_reason for p in untriggered)


def test_criteria_that_never_trigger_are_reported_not_invented(
    desk: DeskProfile, paper_recording: Recording
) -> None:
    report = derive_thresholds(desk, paper_recording, converged_m_s=1e-9, diverged_m=10.0)
    assert len(report.presses) == 27
    assert report.touch.triggered == 0 and report.touch.mean_n is None
    assert report.release.triggered == 0 and report.release.suggested_n is None
    assert all("still moving" in p.touch_reason for p in report.presses)
    assert all(p.touch_n is None and p.release_n is None for p in report.presses)
    assert report.snippet() is None


def test_a_noisier_desk_needs_higher_thresholds(desk: DeskProfile, paper_report) -> None:
    noisy = simulate(
        desk,
        load_scene(SCENES / "paper-experiment.yaml"),
        seed=0,
        sensors=SensorParameters(noise_amplitude_n=1.6),
    )
    report = derive_thresholds(desk, noisy)
    # measured: F_tth mean 2.06 -> 4.29 N, F_rth triggered 4 -> 14 of 27
    assert report.touch.mean_n > paper_report.touch.mean_n + 1.0
    assert report.release.triggered > paper_report.release.triggered
    assert report.touch.max_n <= 12.0 * 1.5


def test_the_snippet_is_valid_profile_yaml(paper_report) -> None:
    snippet = paper_report.snippet()
    parsed = yaml.safe_load(snippet)
    assert parsed == {
        "estimation": {
            "touch_threshold_n": paper_report.touch.suggested_n,
            "release_threshold_n": paper_report.release.suggested_n,
        }
    }


def test_summary_follows_the_papers_candidates() -> None:
    s = ThresholdSummary.of([3.0, 4.0, 5.0], presses=4, floor_n=2.0)
    assert (s.mean_n, s.std_n, s.low_n, s.high_n) == (4.0, 1.0, 3.0, 5.0)
    assert s.candidates_n == [3.0, 4.0, 5.0] and s.suggested_n == 5.0
    # the paper: mean 3.74, std 1.93 -> 1.81 is kept, but below 2 N it would be dropped
    low = ThresholdSummary.of([2.0, 2.1, 3.5], presses=3, floor_n=2.0)
    assert low.low_n < 2.0 and low.low_n not in low.candidates_n
    assert len(low.candidates_n) == 2
    one = ThresholdSummary.of([4.2], presses=9, floor_n=2.0)
    assert one.std_n == 0.0 and one.candidates_n == [4.2]
    assert ThresholdSummary.of([], presses=3, floor_n=2.0).suggested_n is None


def test_local_slope_is_the_least_squares_slope() -> None:
    t = 100.0 + np.arange(200) / 1200.0
    y = 0.3 - 0.7 * (t - t[0]) + 0.01 * np.sin(40 * t)
    slope = local_slope(t, y, 10)
    for i in (0, 5, 100, 199):  # windows clipped at the ends
        a, b = max(i - 10, 0), min(i + 10, 199) + 1
        assert slope[i] == pytest.approx(np.polyfit(t[a:b], y[a:b], 1)[0], rel=1e-7)
    y[50] = np.nan
    s = local_slope(t, y, 10)
    assert np.isnan(s[40:61]).all() and np.isfinite(s[:40]).all() and np.isfinite(s[61:]).all()
    assert len(local_slope(t[:0], y[:0], 3)) == 0
    assert np.isnan(local_slope(t[:1], y[:1], 3)).all()


def test_cli_prints_table_summary_and_snippet(tmp_path, paper_recording, capsys) -> None:
    path = tmp_path / "paper.npz"
    write_recording(path, paper_recording)
    assert main(["thresholds", str(path), "--desk", "kitamura2017"]) == 0
    out = capsys.readouterr().out
    assert "F_tth: triggered in" in out and "F_rth: triggered in" in out
    assert "estimation: {touch_threshold_n:" in out
    assert out.count("\n") > 27  # one row per press
    assert main(["thresholds", str(path), "--desk", "kitamura2017", "--json"]) == 0
    text = capsys.readouterr().out
    info = json.loads(text, parse_constant=lambda c: pytest.fail(f"{c} in JSON"))
    assert len(info["presses"]) == 27 and info["desk"] == "kitamura2017"
    assert info["snippet"].startswith("estimation: {")
    assert info["touch"]["triggered"] >= 20


def test_cli_without_presses_exits_1_and_says_why(tmp_path, desk, capsys) -> None:
    quiet = simulate(desk, Scene([Idle(duration_s=3.0)]), seed=1)
    path = tmp_path / "quiet.csv"
    write_recording(path, quiet)
    assert main(["thresholds", str(path), "--desk", "kitamura2017"]) == 1
    captured = capsys.readouterr()
    assert "no presses found" in captured.err
    assert "(no presses found)" in captured.out


def test_cli_errors_exit_2_with_a_clear_message(tmp_path, capsys) -> None:
    missing = tmp_path / "nope.csv"
    assert main(["thresholds", str(missing), "--desk", "kitamura2017"]) == 2
    err = capsys.readouterr().err
    assert str(missing) in err and "cannot read" in err
    assert main(["thresholds", str(missing), "--desk", "no-such-desk"]) == 2
    assert "no such desk profile" in capsys.readouterr().err
    assert main(["thresholds", str(missing), "--desk", "kitamura2017", "--diverged", "-1"]) == 2
    assert "--diverged" in capsys.readouterr().err


def test_a_desk_without_surfaces_is_refused(bench_sensor, tmp_path, capsys) -> None:
    rec = simulate(bench_sensor, Scene([Idle(duration_s=2.0)]), seed=0)
    with pytest.raises(ConfigError, match="no surfaces"):
        derive_thresholds(bench_sensor, rec)
    path = tmp_path / "bench.csv"
    write_recording(path, rec)
    assert main(["thresholds", str(path), "--desk", "ati-bench"]) == 2
    assert "no surfaces" in capsys.readouterr().err


def test_a_recording_for_another_desk_is_refused(tmp_path, bench_sensor, capsys) -> None:
    rec = simulate(bench_sensor, Scene([Idle(duration_s=2.0)]), seed=0)
    path = tmp_path / "bench.csv"
    write_recording(path, rec)
    assert main(["thresholds", str(path), "--desk", "kitamura2017"]) == 2
    assert "missing column" in capsys.readouterr().err
