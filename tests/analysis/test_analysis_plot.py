"""`hapticdesk plot`: a readable PNG of a recording, with and without ground truth."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from hapticdesk.analysis.plotting import plot_recording
from hapticdesk.cli import main
from hapticdesk.errors import ConfigError
from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.recording import Recording
from hapticdesk.files.recording_io import write_recording
from hapticdesk.sim import Idle, Scene, simulate

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def assert_png(path, min_bytes: int = 10_000) -> None:
    data = path.read_bytes()
    assert data[:8] == PNG_SIGNATURE
    assert len(data) > min_bytes
    # IHDR: width and height of the image, big-endian, after the signature and chunk header
    width, height = int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")
    assert width >= 1000 and height >= 500


def without_truth(rec: Recording) -> Recording:
    return Recording(rec.t, rec.wrench, rec.sensor_names)


def test_one_press_with_truth(desk: DeskProfile, paper_recording: Recording, tmp_path) -> None:
    out = tmp_path / "press.png"
    summary = plot_recording(
        desk, paper_recording, out, method="switched", start_s=34.9, end_s=36.8
    )
    assert_png(out)
    assert summary.truth and summary.method == "switched"
    assert summary.samples == pytest.approx(1.9 * 1200, abs=2)
    # one press: in contact, located by both candidates as the switched method chooses
    assert 0 < summary.contact_samples < summary.samples
    assert summary.located["force"] > 0 and summary.located["diff"] > 0
    assert summary.located["fused"] == 0


def test_whole_recording_without_truth_and_another_method(
    desk: DeskProfile, paper_recording: Recording, tmp_path
) -> None:
    out = tmp_path / "all.png"
    summary = plot_recording(desk, without_truth(paper_recording), out, method="fused")
    assert_png(out)
    assert not summary.truth and summary.method == "fused"
    assert summary.samples == len(paper_recording)
    assert summary.located["fused"] > 0


def test_a_bench_sensor_plots_its_force_channels(bench_sensor: DeskProfile, tmp_path) -> None:
    rec = simulate(bench_sensor, Scene([Idle(duration_s=3.0)]), seed=0)
    out = tmp_path / "bench.png"
    summary = plot_recording(bench_sensor, without_truth(rec), out)
    assert_png(out)
    assert summary.contact_samples == 0 and sum(summary.located.values()) == 0


def test_an_empty_window_is_refused(desk: DeskProfile, paper_recording: Recording, tmp_path):
    with pytest.raises(ConfigError, match="holds no samples"):
        plot_recording(desk, paper_recording, tmp_path / "x.png", start_s=500.0, end_s=600.0)
    assert not (tmp_path / "x.png").exists()


def test_cli_writes_the_png_and_reports(tmp_path, paper_recording, capsys) -> None:
    rec = tmp_path / "paper.csv"
    write_recording(rec, without_truth(paper_recording))
    out = tmp_path / "plot.png"
    argv = ["plot", str(rec), "--desk", "kitamura2017", "-o", str(out)]
    assert main([*argv, "--start", "60", "--end", "64", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["truth"] is False and info["bytes"] == out.stat().st_size
    assert_png(out)
    assert main([*argv, "--method", "diff"]) == 0
    assert "wrote" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--start", "5", "--end", "2"], "must be after --start"),
        (["--start", "nan"], "finite"),
        (["--start", "1000"], "holds no samples"),
    ],
)
def test_cli_rejects_bad_windows(tmp_path, paper_recording, capsys, extra, message) -> None:
    rec = tmp_path / "paper.npz"
    write_recording(rec, paper_recording)
    argv = ["plot", str(rec), "--desk", "kitamura2017", "-o", str(tmp_path / "p.png"), *extra]
    assert main(argv) == 2
    assert message in capsys.readouterr().err


def test_cli_errors_exit_2_with_a_clear_message(tmp_path, capsys) -> None:
    missing = tmp_path / "gone.csv"
    png = str(tmp_path / "p.png")
    assert main(["plot", str(missing), "--desk", "kitamura2017", "-o", png]) == 2
    err = capsys.readouterr().err
    assert "gone.csv" in err and "cannot read" in err
    assert main(["plot", str(missing), "--desk", "kitamura2071", "-o", png]) == 2
    assert "no such desk profile" in capsys.readouterr().err
    assert (
        main(["plot", str(missing), "--desk", "kitamura2017", "-o", str(tmp_path / "p.jpg")]) == 2
    )
    assert "expected a .png" in capsys.readouterr().err


def test_cli_unwritable_output(tmp_path, paper_recording, capsys) -> None:
    rec = tmp_path / "paper.npz"
    write_recording(rec, paper_recording)
    out = tmp_path / "no-such-dir" / "p.png"
    assert main(["plot", str(rec), "--desk", "kitamura2017", "-o", str(out), "--end", "3"]) == 2
    assert "cannot write" in capsys.readouterr().err


def test_analysis_imports_no_matplotlib_until_a_plot_is_drawn() -> None:
    code = (
        "import sys\n"
        "import hapticdesk.analysis.thresholds, hapticdesk.analysis.characterize\n"
        "import hapticdesk.commands.plot, hapticdesk.commands.thresholds\n"
        "import hapticdesk.commands.characterize\n"
        "assert 'matplotlib' not in sys.modules, 'matplotlib imported'\n"
        "import hapticdesk.analysis.plotting\n"
        "assert 'matplotlib' not in sys.modules, 'matplotlib imported by plotting'\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


def test_a_recording_of_a_header_alone_is_named(tmp_path, capsys):
    """It was "recording: the recording has no samples": which file?"""
    path = tmp_path / "header.csv"
    axes = ("fx", "fy", "fz", "mx", "my", "mz")
    columns = ["t"] + [f"{s}_{a}" for s in ("fl", "fr", "bl", "br") for a in axes]
    path.write_text(",".join(columns) + "\n")
    assert main(["plot", str(path), "--desk", "kitamura2017", "-o", str(tmp_path / "p.png")]) == 2
    assert capsys.readouterr().err == (
        f"hapticdesk plot: error: {path}: the recording holds no samples\n"
    )


@pytest.mark.parametrize("desk_name", ["kitamura2017", "kitamura2017-accel"])
def test_plot_and_contacts_count_the_same_points(tmp_path, capsys, desk_name) -> None:
    """The plot's legend said 15,230 located points where ``contacts --json`` said 71,661:
    that was one candidate's count (the force's 56,431 were drawn under it); and on a desk
    with an accelerometer the plot estimated without its readings. Now both count the same
    samples, in contact and located, and the legend's counts add up to that."""
    from hapticdesk.files.profile_reader import load_profile
    from hapticdesk.sim import Press, Swipe

    desk = load_profile(desk_name)
    scene = Scene([Press(point=(0.2, 0.1)), Swipe(from_point=(-0.2, 0.0), to_point=(0.2, 0.05))])
    rec = tmp_path / "rec.csv"
    write_recording(rec, simulate(desk, scene, seed=2))
    assert main(["contacts", str(rec), "--desk", desk_name, "--json"]) == 0
    contacts = json.loads(capsys.readouterr().out)
    png = tmp_path / "rec.png"
    assert main(["plot", str(rec), "--desk", desk_name, "-o", str(png), "--json"]) == 0
    plotted = json.loads(capsys.readouterr().out)
    assert plotted["located_samples"] == contacts["located_samples"] > 0
    assert sum(plotted["located"].values()) == contacts["located_samples"]
    assert plotted["contact_samples"] == contacts["contact_samples"]
