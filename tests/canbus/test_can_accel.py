"""The accelerometer board over CAN (issue 15 item 6): its ACCEL frames in a real log format
written and read by python-can, decoded with the legs' sensors by the shared counter, and the
estimator compensating from the decoded readings as from the simulator's."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hapticdesk.canbus.config_reader import can_config
from hapticdesk.canbus.frame_encoder import FrameEncoder
from hapticdesk.canbus.logs.desk_samples import open_can_log, read_can_log
from hapticdesk.canbus.logs.writer import write_frames
from hapticdesk.errors import ConfigError
from hapticdesk.estimator import ContactEstimator, estimate
from hapticdesk.estimator.contacts import FLAG_NO_ACCEL
from hapticdesk.estimator.inertia import accelerometer_readings
from hapticdesk.files.profile_reader import load_profile
from hapticdesk.files.recording import Recording
from hapticdesk.sim import simulate
from hapticdesk.sim.scene import load_scene

SCENES = Path(__file__).resolve().parents[2] / "examples" / "scenes"


@pytest.fixture(scope="module")
def accel_desk():
    return load_profile("kitamura2017-accel")


@pytest.fixture(scope="module")
def swipes(accel_desk) -> Recording:
    rec = simulate(accel_desk, load_scene(SCENES / "swipes.yaml"), 3)
    k = 8_000  # the tare and the first two swipes
    return Recording(
        rec.t[:k], rec.wrench[:k], rec.sensor_names, {c: v[:k] for c, v in rec.extra.items()}
    )


@pytest.mark.parametrize("suffix", [".asc", ".blf"])
def test_an_accelerometer_desk_round_trips_through_a_can_log(tmp_path, accel_desk, swipes, suffix):
    config = can_config(accel_desk)
    accel = accelerometer_readings(accel_desk, swipes.extra)
    frames = FrameEncoder(config, accel_desk).encode(swipes.t, swipes.wrench, accel=accel)
    assert len(frames) == 9 * len(swipes.t)  # eight frames of the legs, one ACCEL a sample
    path = tmp_path / f"desk{suffix}"
    write_frames(path, [frames])
    rec = read_can_log(path, accel_desk)
    assert len(rec.t) == len(swipes.t)
    decoded = accelerometer_readings(accel_desk, rec.extra)
    assert decoded is not None
    np.testing.assert_allclose(decoded, accel, atol=0.0005 + 1e-9)  # the DBC's 1 mm/s² step
    # compensated from the log's readings as from the simulator's exact ones (on the log's
    # wrench): the same contacts, the same places within the DBC's 1 mm/s² step (14 mN)
    _compensates_as_from_exact_readings(accel_desk, rec, accel, path, 300, 2e-4)


def _compensates_as_from_exact_readings(desk, rec, accel, path, least: int, tol_m: float) -> None:
    """The log's decoded readings (``rec``, read from ``path``) compensate as the exact ones
    (``accel``): samples flagged only where a reading was lost, the same contacts, at least
    ``least`` samples located by both within ``tol_m``; and the streaming source hands the
    blocks the same readings."""
    decoded = accelerometer_readings(desk, rec.extra)
    assert decoded is not None
    # uncompensated where a reading is lost; with several boards, only where none is left
    several = len(desk.accelerometers) > 1
    lost = np.isnan(decoded).all(axis=1) if several else np.isnan(decoded).any(axis=1)
    from_log = estimate(desk, rec)
    exact = ContactEstimator(desk).push(rec.t, rec.wrench, accel)
    np.testing.assert_array_equal((from_log.flags & FLAG_NO_ACCEL) != 0, lost)
    np.testing.assert_array_equal(from_log.in_contact, exact.in_contact)
    both = from_log.located & exact.located
    assert both.sum() > least
    assert np.abs(from_log.x[both] - exact.x[both]).max() < tol_m
    source = open_can_log(path, desk)
    streamed = np.concatenate([b.accel for b in source.blocks()])
    source.close()
    np.testing.assert_array_equal(streamed, decoded)


def test_lost_accel_frames_leave_those_samples_uncompensated_and_flagged(
    tmp_path, accel_desk, swipes
):
    config = can_config(accel_desk)
    accel = accelerometer_readings(accel_desk, swipes.extra).copy()
    lost = np.zeros(len(accel), bool)
    lost[[2_000, 5_000, 5_001]] = True
    accel[lost] = np.nan  # the encoder sends no ACCEL frame for these samples
    frames = FrameEncoder(config, accel_desk).encode(swipes.t, swipes.wrench, accel=accel)
    path = tmp_path / "lossy.asc"
    write_frames(path, [frames])
    rec = read_can_log(path, accel_desk)
    assert len(rec.t) == len(swipes.t)  # the legs' samples all there
    block = ContactEstimator(accel_desk).push(
        rec.t, rec.wrench, accelerometer_readings(accel_desk, rec.extra)
    )
    np.testing.assert_array_equal((block.flags & FLAG_NO_ACCEL) != 0, lost)
    assert np.isfinite(block.x).all() and np.isfinite(block.force_n).all()


def test_can_accelerometer_needs_one_on_the_desk_and_its_axes(profile_text):
    base = """name: d
sample_rate_hz: 1200
desk: {{mass_kg: 13.7}}
{accel}sensors:
  - {{name: fl, position: [-0.34, -0.22, 0.0]}}
  - {{name: fr, position: [0.34, -0.22, 0.0]}}
  - {{name: bl, position: [-0.34, 0.22, 0.0]}}
can:
  database: kitamura2017.dbc
  sensors:
    fl: {{fx: FL_FORCE.Fx, fy: FL_FORCE.Fy, fz: FL_FORCE.Fz}}
    fr: {{fx: FR_FORCE.Fx, fy: FR_FORCE.Fy, fz: FR_FORCE.Fz}}
    bl: {{fx: BL_FORCE.Fx, fy: BL_FORCE.Fy, fz: BL_FORCE.Fz}}
  accelerometer: {{{signals}}}
"""
    none = profile_text(base.format(accel="", signals="x: ACCEL.Ax"))
    with pytest.raises(ConfigError, match=r"desk.yaml:14:\d+: .*has none"):
        can_config(none)
    fewer = profile_text(
        base.format(
            accel="accelerometer: {position: [0, 0, 0.7]}\n", signals="x: ACCEL.Ax, y: ACCEL.Ay"
        )
    )
    with pytest.raises(ConfigError, match=r"each of the accelerometer's axes \(x, y, z\)"):
        can_config(fewer)
    wrong = profile_text(
        base.format(
            accel="accelerometer: {position: [0, 0, 0.7], axes: [x]}\n", signals="x: ACCEL.Ux"
        )
    )
    with pytest.raises(ConfigError, match=r"desk.yaml:15:\d+: .*no signal `Ux`"):
        can_config(wrong)
    two = base.format(
        accel="accelerometers: [{position: [0, 0, 0.7]}, {position: [0.3, 0, 0.7]}]\n",
        signals="x: ACCEL.Ax, y: ACCEL.Ay, z: ACCEL.Az",
    )
    with pytest.raises(ConfigError, match=r"desk.yaml:15:\d+: .*has 2: list them as"):
        can_config(profile_text(two))
    short = profile_text(
        two.replace(
            "  accelerometer: {x: ACCEL.Ax, y: ACCEL.Ay, z: ACCEL.Az}",
            "  accelerometers: [{x: ACCEL.Ax, y: ACCEL.Ay, z: ACCEL.Az}]",
        )
    )
    with pytest.raises(ConfigError, match=r"desk.yaml:15:\d+: .*a list of 2 entries"):
        can_config(short)


@pytest.mark.parametrize("suffix", [".asc", ".blf"])
def test_three_accelerometers_round_trip_through_a_can_log(tmp_path, suffix):
    """kitamura2017-panel-accel's three boards (ACCEL, ACCEL2, ACCEL3 with the legs' counter):
    each one's readings come back in the profile's order, a lost ACCEL2 frame leaves that
    sample to the other two boards (unflagged), and the estimator places presses on the
    panel from the log's readings as from the simulator's."""
    from hapticdesk.sim import Scene, Tap

    desk = load_profile("kitamura2017-panel-accel")
    config = can_config(desk)
    assert [name for name, _ in config.groups()][-3:] == [
        "accelerometer",
        "accelerometer2",
        "accelerometer3",
    ]
    scene = Scene(actions=[Tap(point=(-0.25, 0.0), surface="front", peak_n=5.0)])
    rec = simulate(desk, scene, 4)
    accel = accelerometer_readings(desk, rec.extra)
    assert accel is not None and accel.shape == (len(rec.t), 9)
    sent = accel.copy()
    sent[3_000, 3:6] = np.nan  # no ACCEL2 frame for this sample
    frames = FrameEncoder(config, desk).encode(rec.t, rec.wrench, accel=sent)
    assert len(frames) == 11 * len(rec.t) - 1  # eight of the legs, three ACCEL* a sample
    path = tmp_path / f"panel{suffix}"
    write_frames(path, [frames])
    back = read_can_log(path, desk)
    assert len(back.t) == len(rec.t)
    assert [c for c in back.extra if c.startswith("acc")] == desk.accelerometer_columns()
    decoded = accelerometer_readings(desk, back.extra)
    assert decoded is not None
    lost = np.isnan(decoded).any(axis=1)
    assert np.flatnonzero(lost).tolist() == [3_000]
    assert (
        np.isnan(decoded[3_000, 3:6]).all()
        and np.isfinite(decoded[3_000, [0, 1, 2, 6, 7, 8]]).all()
    )
    np.testing.assert_allclose(decoded[~lost], accel[~lost], atol=0.0005 + 1e-9)
    _compensates_as_from_exact_readings(desk, back, accel, path, 50, 5e-4)
