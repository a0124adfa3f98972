"""Whole runs: the estimator recovers simulated contacts, truth columns, determinism, the
source, and the ``hapticdesk simulate`` command."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hapticdesk.cli import main
from hapticdesk.estimator import estimate
from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.profile_reader import profile_from_mapping
from hapticdesk.files.recording_io import read_recording
from hapticdesk.files.yamlfile import load_marked_yaml
from hapticdesk.sim import (
    TRUTH_COLUMNS,
    Drag,
    HumanModel,
    LiftObject,
    Press,
    PutObject,
    Scene,
    SimEffects,
    SimSource,
    Stroke,
    Swipe,
    Tap,
    load_scene,
    shape_path,
    simulate,
)

SCENES = Path(__file__).resolve().parents[2] / "examples" / "scenes"
STILL = HumanModel(tremor=0.0, wander=0.0, roll_m=0.0, aim_sd_m=0.0)
PERFECT = SimEffects(dynamics=False, noise=False, drift=False, quantisation=False)


def static_press(point: tuple[float, float]) -> Scene:
    """A still finger (sideways push included) held long enough for every filter to settle."""
    return Scene([Press(point, peak_n=18.0, hold_s=4.0)], human=STILL)


def held(rec_fn: np.ndarray, t: np.ndarray, margin_s: float = 2.0) -> np.ndarray:
    """Samples of the hold, ``margin_s`` after the force reached its plateau."""
    plateau = np.flatnonzero(rec_fn >= rec_fn.max() - 1e-9)
    return (t >= t[plateau[0]] + margin_s) & (t <= t[plateau[-1]])


@pytest.mark.parametrize("point", [(0.15, 0.05), (-0.2, -0.15), (0.0, 0.0)])
def test_estimator_recovers_a_static_press_exactly(
    any_desk: DeskProfile, point: tuple[float, float]
) -> None:
    """Noise, drift, resolution and dynamics off: the contact to 1e-6 m, on every desk
    (upright, rotated, upside-down and `reports: load` sensors, 3 and 8 legs)."""
    rec = simulate(any_desk, static_press(point), seed=0, effects=PERFECT)
    block = estimate(any_desk, rec, method="force")
    hold = held(rec.extra["true_fn"], rec.t)
    assert np.count_nonzero(hold) > 1000
    assert block.located[hold].all()
    assert np.abs(block.x[hold] - point[0]).max() < 1e-6
    assert np.abs(block.y[hold] - point[1]).max() < 1e-6
    assert np.allclose(rec.extra["true_x"][hold], point[0]) and np.allclose(
        rec.extra["true_y"][hold], point[1]
    )


def test_with_dynamics_the_press_is_recovered_once_the_sway_settles(
    paper_desk: DeskProfile,
) -> None:
    rec = simulate(
        paper_desk,
        static_press((0.2, 0.1)),
        seed=0,
        effects=SimEffects(noise=False, drift=False, quantisation=False),
    )
    block = estimate(paper_desk, rec, method="force")
    hold = held(rec.extra["true_fn"], rec.t, margin_s=3.0)
    assert np.hypot(block.x[hold] - 0.2, block.y[hold] - 0.1).max() < 2e-5


def test_summed_readings_equal_the_applied_load_when_static(paper_desk: DeskProfile) -> None:
    scene = Scene(
        [Stroke(shape_path("circle", (0.0, 0.0), 0.2), speed=0.1), Tap((0.1, -0.1))],
    )
    rec = simulate(paper_desk, scene, seed=3, effects=PERFECT)
    supports = rec.wrench.reshape(len(rec), -1) @ paper_desk.wrench_map().T
    supports -= supports[0]  # the desk's weight
    force = np.column_stack([rec.extra[c] for c in ("true_fx", "true_fy", "true_fz")])
    np.testing.assert_allclose(supports[:, :3], -force, atol=1e-9)
    touching = rec.extra["true_fn"] > 0
    point = np.column_stack([rec.extra[c] for c in ("true_x", "true_y", "true_z")])
    moment = np.cross(point[touching], force[touching])
    np.testing.assert_allclose(supports[touching, 3:], -moment, atol=1e-9)


def test_truth_columns(paper_desk: DeskProfile) -> None:
    scene = Scene([Tap((0.1, 0.0)), Swipe((-0.1, 0.0), (0.1, 0.0)), Drag([(0, -0.1), (0, 0.1)])])
    rec = simulate(paper_desk, scene, seed=1)
    assert set(TRUTH_COLUMNS) <= set(rec.extra)
    fn = rec.extra["true_fn"]
    touching = fn > 0
    assert np.all(fn >= 0) and touching.any()
    for c in ("true_x", "true_y", "true_z"):
        assert np.all(np.isnan(rec.extra[c][~touching]))
        assert np.all(np.isfinite(rec.extra[c][touching]))
    assert np.all(rec.extra["true_action"][~touching] == -1)
    assert set(np.unique(rec.extra["true_action"][touching])) == {0.0, 1.0, 2.0}
    assert np.allclose(rec.extra["true_z"][touching], 0.733)
    assert np.isfinite(rec.wrench).all() and np.isfinite(rec.t).all()
    assert np.all(np.diff(rec.t) > 0) and rec.t[0] == 0.0


def test_two_fingers_give_their_centre_of_pressure(paper_desk: DeskProfile) -> None:
    scene = Scene(
        [
            Press((-0.2, 0.0), peak_n=10, hold_s=2),
            Press((0.2, 0.0), peak_n=10, hold_s=2, start_s=2.5),
        ],
        human=STILL,
    )
    rec = simulate(paper_desk, scene, seed=0, effects=PERFECT)
    both = rec.extra["true_fn"] >= 20.0 - 1e-9  # both fingers at their 10 N plateau
    assert both.any()
    np.testing.assert_allclose(rec.extra["true_x"][both], 0.0, atol=1e-9)


def test_objects_weigh_on_the_desk_but_are_no_touch(paper_desk: DeskProfile) -> None:
    scene = Scene(
        [PutObject(name="book", mass_kg=1.5, point=(0.3, 0.2)), LiftObject(name="book", wait_s=2.0)]
    )
    rec = simulate(paper_desk, scene, seed=0, effects=PERFECT)
    fz = (rec.wrench.reshape(len(rec), -1) @ paper_desk.wrench_map().T)[:, 2]
    lying = (rec.t > 2.4) & (rec.t < 4.2)
    np.testing.assert_allclose(fz[lying] - fz[0], 1.5 * 9.80665, atol=1e-9)
    np.testing.assert_allclose(fz[-1], fz[0], atol=1e-9)
    assert not np.any(rec.extra["true_fn"])


def test_same_seed_same_run_other_seed_other_run(paper_desk: DeskProfile) -> None:
    scene = Scene([Tap((0.01 * (i % 20) - 0.1, 0.0), wait_s=0.3) for i in range(200)])
    a = simulate(paper_desk, scene, seed=5)
    b = simulate(paper_desk, scene, seed=5)
    c = simulate(paper_desk, scene, seed=6)
    np.testing.assert_array_equal(a.wrench, b.wrench)
    for col in TRUTH_COLUMNS:
        np.testing.assert_array_equal(a.extra[col], b.extra[col])
    assert len(a) != len(c) or not np.array_equal(a.wrench, c.wrench)
    touching = a.extra["true_fn"] > 0
    assert np.count_nonzero(touching[1:] & ~touching[:-1]) == 200


def test_noise_off_keeps_the_same_human(paper_desk: DeskProfile) -> None:
    scene = Scene([Press((0.0, 0.1)), Tap((0.1, 0.0))])
    noisy = simulate(paper_desk, scene, seed=2)
    clean = simulate(paper_desk, scene, seed=2, noise=False)
    np.testing.assert_array_equal(noisy.extra["true_fn"], clean.extra["true_fn"])
    assert not np.array_equal(noisy.wrench, clean.wrench)
    assert np.abs(noisy.wrench - clean.wrench).max() < 2.0


@pytest.mark.parametrize("block_size", [1, 12, 5000])
def test_source_blocks_equal_the_batch_run(paper_desk: DeskProfile, block_size: int) -> None:
    scene = Scene([Tap((0.0, 0.0)), Press((0.1, 0.1), hold_s=0.7)], quiet_s=1.5, tail_s=0.5)
    rec = simulate(paper_desk, scene, seed=9)
    with SimSource(paper_desk, scene, seed=9, block_size=block_size) as source:
        assert source.sensor_names == paper_desk.sensor_names
        assert source.sample_rate_hz == 1200.0
        blocks = list(source.blocks())
    assert all(len(b.t) == block_size for b in blocks[:-1]) and 0 < len(blocks[-1].t) <= block_size
    np.testing.assert_array_equal(np.concatenate([b.t for b in blocks]), rec.t)
    np.testing.assert_array_equal(np.concatenate([b.wrench for b in blocks]), rec.wrench)
    truth = np.concatenate([b.truth["true_fn"] for b in blocks if b.truth is not None])
    np.testing.assert_array_equal(truth, rec.extra["true_fn"])


def test_closing_the_source_stops_it(paper_desk: DeskProfile) -> None:
    source = SimSource(paper_desk, Scene([Tap((0.0, 0.0))]), block_size=12)
    seen = 0
    for _ in source.blocks():
        seen += 1
        if seen == 3:
            source.close()
    source.close()
    assert seen == 3


# --- the command ------------------------------------------------------------------------------


def test_cli_round_trip_csv_and_npz(
    tmp_path: Path, paper_desk: DeskProfile, capsys: pytest.CaptureFixture[str]
) -> None:
    scene_path = SCENES / "demo.yaml"
    expected = simulate(paper_desk, load_scene(scene_path), seed=3)
    for suffix in (".csv", ".npz"):
        out = tmp_path / f"rec{suffix}"
        code = main(
            ["simulate", str(scene_path), "--desk", "kitamura2017", "-o", str(out), "--seed", "3"]
        )
        assert code == 0
        rec = read_recording(out, paper_desk.sensor_names)
        tol = 0 if suffix == ".npz" else 1e-8
        np.testing.assert_allclose(rec.wrench, expected.wrench, rtol=tol, atol=tol)
        np.testing.assert_allclose(rec.t, expected.t, rtol=tol, atol=tol)
        for col in ("true_x", "true_y", "true_fn"):
            np.testing.assert_allclose(
                rec.extra[col], expected.extra[col], rtol=tol, atol=tol, equal_nan=True
            )
    header = (tmp_path / "rec.csv").read_text().split("\n", 1)[0].split(",")
    assert header[:7] == ["t", "fl_fx", "fl_fy", "fl_fz", "fl_mx", "fl_my", "fl_mz"]
    assert {"true_x", "true_y", "true_fn"} <= set(header)
    assert "wrote" in capsys.readouterr().out


def test_cli_is_deterministic_and_takes_the_scenes_desk(tmp_path: Path) -> None:
    scene = tmp_path / "s.yaml"
    scene.write_text(
        "desk: kitamura2017-shelf\ntimeline:\n  - tap: {point: [0, 0.3], surface: shelf}\n"
    )
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    assert main(["simulate", str(scene), "-o", str(a)]) == 0
    assert main(["simulate", str(scene), "-o", str(b)]) == 0
    assert a.read_bytes() == b.read_bytes()
    rec = read_recording(a, ["fl", "fr", "bl", "br"])
    assert np.nanmax(rec.extra["true_z"]) == pytest.approx(1.20)  # on the shelf


def test_cli_options(
    tmp_path: Path, paper_desk: DeskProfile, capsys: pytest.CaptureFixture[str]
) -> None:
    scene = tmp_path / "s.yaml"
    scene.write_text("timeline:\n  - press: {point: [0.1, 0], peak_n: 20}\n")
    out = tmp_path / "r.npz"
    assert main(["simulate", str(scene), "-o", str(out), "--ideal", "--json"]) == 0
    assert '"touches": 1' in capsys.readouterr().out
    rec = read_recording(out, paper_desk.sensor_names)
    fz = (rec.wrench.reshape(len(rec), -1) @ paper_desk.wrench_map().T)[:, 2]
    np.testing.assert_allclose(fz - fz[0], rec.extra["true_fn"] * 1.0, atol=2.0)
    assert np.all(fz[rec.extra["true_fn"] == 0] == fz[0])  # no noise at all
    assert main(["simulate", str(scene), "-o", str(out), "--no-noise", "--static"]) == 0
    assert main(["simulate", str(scene), "-o", str(out), "--noise-amplitude", "1.0"]) == 0


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["{scene}", "-o", "{tmp}/r.txt"], "expected .csv or .npz"),
        (["{tmp}/missing.yaml", "-o", "{tmp}/r.csv"], "cannot read the file"),
        (["{bad}", "-o", "{tmp}/r.csv"], "bad.yaml:2:5: unknown action `tapp`"),
        (["{scene}", "--desk", "nodesk", "-o", "{tmp}/r.csv"], "no such desk profile"),
        (["{scene}", "-o", "{tmp}/r.csv", "--noise-amplitude", "-1"], "must be 0 to 1000 N"),
        (["{scene}", "-o", "{tmp}/r.csv", "--noise-amplitude", "1e308"], "must be 0 to 1000 N"),
        (
            ["{outside}", "-o", "{tmp}/r.csv"],
            "outside.yaml:2:10: tap: point (0.9, 0) m lies outside",
        ),
    ],
)
def test_cli_errors_are_messages_not_tracebacks(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], message: str
) -> None:
    (tmp_path / "ok.yaml").write_text("timeline:\n  - tap: {point: [0, 0]}\n")
    (tmp_path / "bad.yaml").write_text("timeline:\n  - tapp: {point: [0, 0]}\n")
    (tmp_path / "outside.yaml").write_text("timeline:\n  - tap: {point: [0.9, 0]}\n")
    names = {
        "scene": str(tmp_path / "ok.yaml"),
        "bad": str(tmp_path / "bad.yaml"),
        "outside": str(tmp_path / "outside.yaml"),
        "tmp": str(tmp_path),
    }
    code = main(["simulate", *[a.format(**names) for a in args]])
    err = capsys.readouterr().err
    assert code == 2
    assert message in err and "Traceback" not in err
    assert not (tmp_path / "r.csv").exists()


PANEL_DESK = """
name: with-front-panel
sample_rate_hz: 1200
sensors:
  - {name: fl, position: [-0.34, -0.22, 0.0]}
  - {name: fr, position: [0.34, -0.22, 0.0]}
  - {name: bl, position: [-0.34, 0.22, 0.0]}
  - {name: br, position: [0.34, 0.22, 0.0]}
surfaces:
  - name: top
    origin: [0.0, 0.0, 0.733]
    normal: [0, 0, 1]
    polygon: [[-0.375, -0.25], [0.375, -0.25], [0.375, 0.25], [-0.375, 0.25]]
  - name: front
    origin: [0.0, -0.25, 0.6]
    normal: [0, -1, 0]
    u_axis: [1, 0, 0]
    polygon: [[-0.375, -0.1], [0.375, -0.1], [0.375, 0.1], [-0.375, 0.1]]
"""


def test_pressing_a_vertical_panel() -> None:
    """Positions are in the surface's own (u, v); the finger pushes along its normal."""
    desk = profile_from_mapping(load_marked_yaml("panel.yaml", PANEL_DESK), Path("panel.yaml"))
    scene = Scene([Press((0.1, 0.05), peak_n=15.0, hold_s=4.0, surface="front")], human=STILL)
    rec = simulate(desk, scene, seed=0, effects=PERFECT)
    touching = rec.extra["true_fn"] > 0
    assert np.allclose(rec.extra["true_x"][touching], 0.1)
    assert np.allclose(rec.extra["true_y"][touching], -0.25)
    assert np.allclose(rec.extra["true_z"][touching], 0.65)
    assert np.all(rec.extra["true_fy"][touching] > 0)  # pushing into the desk, along +y
    block = estimate(desk, rec, method="force")
    hold = held(rec.extra["true_fn"], rec.t)
    assert np.all(block.surface[hold] == 1)
    assert np.abs(block.x[hold] - 0.1).max() < 1e-6
    assert np.abs(block.z[hold] - 0.65).max() < 1e-6
