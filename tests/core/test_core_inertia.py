"""Vibration compensation (issue 15 item 6): an accelerometer on the desk top, simulated, and
the estimator removing the desk's inertial force before it locates a touch."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import scipy.signal

from hapticdesk.errors import ConfigError
from hapticdesk.estimator import ContactEstimator, estimate
from hapticdesk.estimator.contacts import FLAG_NO_ACCEL
from hapticdesk.estimator.filters import butter_lowpass_sos
from hapticdesk.estimator.inertia import InertiaSettings, InertiaStage, accelerometer_readings
from hapticdesk.files.profile_reader import load_profile
from hapticdesk.files.recording_io import read_recording, write_recording
from hapticdesk.sim import SimEffects, simulate
from hapticdesk.sim.desk import DeskModel
from hapticdesk.sim.scene import load_scene

SCENES = Path(__file__).resolve().parents[2] / "examples" / "scenes"
G = 9.80665


@pytest.fixture(scope="module")
def swipes(accel_desk):
    return simulate(accel_desk, load_scene(SCENES / "swipes.yaml"), 1)


@pytest.fixture(scope="module")
def kita(accel_desk):
    return simulate(accel_desk, load_scene(SCENES / "kita.yaml"), 1)


def test_a_still_desk_reads_gravity_and_its_columns_ride_in_recordings(accel_desk, tmp_path):
    path = tmp_path / "still.yaml"
    path.write_text("name: still\ndesk: kitamura2017-accel\ntimeline:\n  - idle: 0.5\n")
    scene = load_scene(path)
    rec = simulate(accel_desk, scene, 1, noise=False)
    acc = accelerometer_readings(accel_desk, rec.extra)
    assert acc is not None and acc.shape == (len(rec.t), 3)
    np.testing.assert_allclose(acc, np.tile([0.0, 0.0, G], (len(rec.t), 1)), atol=1e-9)
    # an addition to the formats: the columns come back from CSV and NPZ alike
    for suffix in (".csv", ".npz"):
        path = tmp_path / f"still{suffix}"
        write_recording(path, rec)
        back = read_recording(path, accel_desk.sensor_names)
        assert [c for c in back.extra if c.startswith("acc_")] == ["acc_x", "acc_y", "acc_z"]
        np.testing.assert_allclose(accelerometer_readings(accel_desk, back.extra), acc)


def test_the_simulated_accelerometer_reads_the_desks_own_acceleration(accel_desk, swipes):
    """Noise-free and with exact sensors, its x reading times the desk's mass is the
    supports' x force less the finger's: what the desk's sway adds to the readings."""
    rec = simulate(
        accel_desk,
        load_scene(SCENES / "swipes.yaml"),
        1,
        effects=SimEffects(noise=False, drift=False, quantisation=False, saturation=False),
    )
    model = DeskModel(accel_desk)
    # the balance the estimator relies on: Σ F_x (supports) = m a_x - u_x
    raw = accel_desk.wrench_map() @ rec.wrench.reshape(len(rec.t), -1).T
    balance = raw[0] + rec.extra["true_fx"]
    balance -= np.median(balance[:1000])
    m_ax = model.mass_kg * rec.extra["acc_x"]
    assert np.abs(balance).max() > 1.0  # the swipes do shake the desk
    np.testing.assert_allclose(m_ax, balance, atol=2e-3 * np.abs(balance).max() + 1e-3)


def _ring_peaks(profile, rec, compensate: bool) -> np.ndarray:
    """The desk's inertial force left in the resultant wrench (30 Hz low-pass, |F|) at its
    peak in the second after each swipe lifts off."""
    inertia = InertiaSettings.of(profile)
    assert inertia is not None
    raw = profile.wrench_map() @ rec.wrench.reshape(len(rec.t), -1).T
    if compensate:
        InertiaStage(inertia).process(raw, accelerometer_readings(profile, rec.extra))
    force = raw[:3] + np.vstack([rec.extra[c] for c in ("true_fx", "true_fy", "true_fz")])
    force -= np.median(force[:, :1200], axis=1, keepdims=True)
    left = np.linalg.norm(scipy.signal.sosfilt(butter_lowpass_sos(30.0, 1200.0), force), axis=0)
    touching = rec.extra["true_fn"] > 0
    peaks = []
    for r in np.flatnonzero(touching[:-1] & ~touching[1:]) + 1:
        a, b = r + 60, r + 1200
        if b <= len(left) and not touching[r:b].any():
            peaks.append(left[a:b].max())
    assert len(peaks) >= 3
    return np.array(peaks)


def test_the_sway_ring_after_a_swipe_is_removed(accel_desk, swipes):
    """Without the accelerometer the desk rings with 2–3 N after a swipe lifts off (its
    5.9 Hz sway); with it, what is left is the noise (≈ 0.1 N)."""
    without = _ring_peaks(accel_desk, swipes, compensate=False)
    with_accel = _ring_peaks(accel_desk, swipes, compensate=True)
    print(
        f"[vibration] ring peak without {np.median(without):.3f} N, "
        f"with {np.median(with_accel):.3f} N"
    )
    assert np.median(without) > 1.0
    assert np.median(with_accel) < 0.25
    assert np.median(with_accel) < 0.15 * np.median(without)


def test_a_traced_stroke_ripples_less_with_the_accelerometer(accel_desk, kita, shape_error_p95):
    """The traced 北 (README Known limits: the sway's ripple): p95 4.7 mm without the
    accelerometer, 1.6 mm with it (seed 1)."""
    accel = accelerometer_readings(accel_desk, kita.extra)
    without = shape_error_p95(accel_desk, kita, None)
    with_accel = shape_error_p95(accel_desk, kita, accel)
    print(f"[vibration] 北 p95 without {without * 1e3:.2f} mm, with {with_accel * 1e3:.2f} mm")
    assert with_accel < 0.5 * without
    assert with_accel < 2.5e-3


def test_missing_and_saturated_readings_fall_back_with_a_flag(accel_desk, kita):
    k = 30_000
    t, wrench = kita.t[:k], kita.wrench[:k]
    accel = accelerometer_readings(accel_desk, kita.extra)[:k].copy()
    bad = np.zeros(k, bool)
    bad[[5_000, 12_000, 12_001, 20_000]] = True
    accel[5_000] = np.nan
    accel[12_000:12_002, 1] = np.inf
    accel[20_000, 2] = 19.6  # at the range: saturated
    block = ContactEstimator(accel_desk).push(t, wrench, accel)
    assert np.array_equal((block.flags & FLAG_NO_ACCEL) != 0, bad)
    for name in ("x", "y", "z", "force_n", "sigma_m"):
        assert np.isfinite(getattr(block, name)).all()
    # no readings at all: every sample flagged, estimated as without an accelerometer
    none = ContactEstimator(accel_desk).push(t, wrench)
    assert ((none.flags & FLAG_NO_ACCEL) != 0).all()
    # (the accelerometer desk does not fall back to the legs: auto leaves them out there)
    uncompensated = load_profile("kitamura2017").with_estimation(sway_compensation=False)
    plain = ContactEstimator(uncompensated).push(t, wrench)
    np.testing.assert_array_equal(none.x, plain.x)
    np.testing.assert_array_equal(none.in_contact, plain.in_contact)


def test_samples_without_readings_are_warned_once_per_spell(accel_desk, kita):
    """A recording without the desk's acc_* columns (or a source that drops them) is said,
    not only flagged: before, `hapticdesk contacts` ran it uncompensated without a word."""
    t, wrench = kita.t[:6_000], kita.wrench[:6_000]
    accel = accelerometer_readings(accel_desk, kita.extra)[:6_000]
    est = ContactEstimator(accel_desk)
    est.push(t[:2_000], wrench[:2_000], accel[:2_000])
    assert [n for n in est.notices if n.kind == "no_accel"] == []
    est.push(t[2_000:3_000], wrench[2_000:3_000])  # a spell without: one warning
    est.push(t[3_000:3_001], wrench[3_000:3_001])
    est.push(t[3_001:4_000], wrench[3_001:4_000])
    est.push(t[4_000:5_000], wrench[4_000:5_000], accel[4_000:5_000])  # back
    est.push(t[5_000:], wrench[5_000:])  # and a second spell
    said = [n for n in est.notices if n.kind == "no_accel"]
    assert [n.t for n in said] == [t[2_000], t[5_000]]
    assert "acc_x, acc_y, acc_z" in said[0].message and "not compensated" in said[0].message


def test_streaming_with_an_accelerometer_equals_batch(accel_desk, kita):
    k = 9_000
    t, wrench = kita.t[:k], kita.wrench[:k]
    accel = accelerometer_readings(accel_desk, kita.extra)[:k].copy()
    accel[4_000, 0] = np.nan  # one bad reading on the way
    batch = ContactEstimator(accel_desk).push(t, wrench, accel)
    est = ContactEstimator(accel_desk)
    cuts = [0, 1_500, 1_501, 3_999, 4_000, 4_001, 4_002, 6_000, k]
    parts = []
    for a, b in zip(cuts[:-1], cuts[1:], strict=True):
        parts.append(est.push(t[a:b], wrench[a:b], accel[a:b]).copy())
    streamed = type(batch).concat(parts)
    for name in ("in_contact", "located", "flags", "surface", "phase"):
        np.testing.assert_array_equal(getattr(streamed, name), getattr(batch, name))
    for name in ("x", "y", "z", "force_n", "sigma_m"):
        np.testing.assert_allclose(getattr(streamed, name), getattr(batch, name), atol=1e-9)


def test_single_sample_pushes_with_an_accelerometer_equal_batch(accel_desk, kita):
    k0, k1 = 3_000, 3_400  # the first stroke's touch-down lies in here (after the tare)
    t, wrench = kita.t[:k1], kita.wrench[:k1]
    accel = accelerometer_readings(accel_desk, kita.extra)[:k1].copy()
    accel[3_200, 1] = np.nan
    batch = ContactEstimator(accel_desk).push(t, wrench, accel)
    est = ContactEstimator(accel_desk)
    parts = [est.push(t[:k0], wrench[:k0], accel[:k0]).copy()]
    parts += [
        est.push(t[i : i + 1], wrench[i : i + 1], accel[i : i + 1]).copy() for i in range(k0, k1)
    ]
    streamed = type(batch).concat(parts)
    assert batch.in_contact[k0:k1].any()
    np.testing.assert_array_equal(streamed.flags, batch.flags)
    np.testing.assert_array_equal(streamed.in_contact, batch.in_contact)
    np.testing.assert_allclose(streamed.x, batch.x, atol=1e-9)
    np.testing.assert_allclose(streamed.force_n, batch.force_n, atol=1e-9)


def test_estimate_reads_the_columns_and_a_desk_without_one_ignores_them(accel_desk, kita):
    k = 6_000
    short = type(kita)(
        kita.t[:k], kita.wrench[:k], kita.sensor_names, {c: v[:k] for c, v in kita.extra.items()}
    )
    by_estimate = estimate(accel_desk, short)
    by_push = ContactEstimator(accel_desk).push(
        short.t, short.wrench, accelerometer_readings(accel_desk, short.extra)
    )
    np.testing.assert_array_equal(by_estimate.x, by_push.x)
    assert not (by_estimate.flags & FLAG_NO_ACCEL).any()
    plain_desk = load_profile("kitamura2017")
    accel = accelerometer_readings(accel_desk, short.extra)
    a = ContactEstimator(plain_desk).push(short.t, short.wrench, accel)
    b = ContactEstimator(plain_desk).push(short.t, short.wrench)
    np.testing.assert_array_equal(a.x, b.x)
    np.testing.assert_array_equal(a.flags, b.flags)


def test_a_wrong_shape_is_refused_clearly(accel_desk):
    est = ContactEstimator(accel_desk)
    with pytest.raises(ValueError, match=r"\(k, A\) = \(3, 3\).*acc_x, acc_y, acc_z"):
        est.push(np.arange(3) / 1200, np.zeros((3, 4, 6)), np.zeros((3, 2)))


def _profile_text(extra: str, desk: str = "desk: {mass_kg: 13.7}\n") -> str:
    return (
        "name: acc\nsample_rate_hz: 1000\n"
        + desk
        + extra
        + "sensors:\n  - {name: a, position: [0, 0, 0]}\n"
    )


@pytest.mark.parametrize(
    ("desk", "extra", "line", "needle"),
    [
        ("", "accelerometer: {position: [0, 0, 0.7]}\n", 3, "needs the desk's mass"),
        (None, "accelerometer: {position: [0, 0.7]}\n", 4, "3 numbers"),
        (None, "accelerometer: {position: [0, 0, 0.7], axes: [x, w]}\n", 4, "some of x, y, z"),
        (None, "accelerometer: {position: [0, 0, 0.7], range_m_s2: 0}\n", 4, "must be > 0"),
        (None, "accelerometer: {position: [0, 0, 0.7], tilt: 1}\n", 4, "unknown key"),
    ],
)
def test_accelerometer_errors_name_file_line_and_what_was_expected(
    tmp_path, desk, extra, line, needle
):
    path = tmp_path / "acc.yaml"
    path.write_text(_profile_text(extra) if desk is None else _profile_text(extra, desk))
    with pytest.raises(ConfigError) as info:
        load_profile(path)
    text = str(info.value)
    assert text.startswith(f"{path}:{line}:"), text
    assert needle in text


def test_the_accelerometer_entry_is_read(tmp_path):
    path = tmp_path / "acc.yaml"
    path.write_text(
        _profile_text(
            "accelerometer: {position: [0.1, 0, 0.7], rotation_rpy_deg: [0, 0, 90], "
            "axes: [y, x], noise_m_s2: 0.01, range_m_s2: 39.2}\n",
            "desk: {mass_kg: 10, center_of_mass_m: [0, 0.1, 0.5]}\n",
        )
    )
    profile = load_profile(path)
    spec = profile.accelerometer
    assert spec is not None
    assert spec.axes == ("x", "y") and spec.column_names() == ["acc_x", "acc_y"]
    np.testing.assert_allclose(spec.axis_matrix(), [[0, -1], [1, 0], [0, 0]], atol=1e-12)
    np.testing.assert_allclose(profile.center_of_mass(), [0, 0.1, 0.5])
    settings = InertiaSettings.of(profile)
    assert settings is not None
    # a horizontal reading of 1 m/s² along the accelerometer's x (the desk's y) is 10 N on y
    # and the moment of that force at the centre of mass
    np.testing.assert_allclose(settings.gain @ [1.0, 0.0], [0, 10, 0, -10 * 0.5, 0, 0], atol=1e-12)


def test_sources_carry_the_readings_to_the_estimator(accel_desk, tmp_path):
    """The simulator's source and a replayed recording give the blocks their readings
    (``WrenchBlock.accel``), so `hapticdesk run` compensates as `estimate` does."""
    from hapticdesk.plugins.replay import open_replay
    from hapticdesk.sim import SimSource

    scene = load_scene(SCENES / "swipes.yaml")
    rec = simulate(accel_desk, scene, 2)
    k = 6_000
    expected = accelerometer_readings(accel_desk, rec.extra)[:k]
    got = []
    for block in SimSource(accel_desk, scene, 2, block_size=50).blocks():
        got.append(block.accel)
        if sum(len(a) for a in got) >= k:
            break
    np.testing.assert_array_equal(np.concatenate(got)[:k], expected)
    short = type(rec)(
        rec.t[:k], rec.wrench[:k], rec.sensor_names, {c: v[:k] for c, v in rec.extra.items()}
    )
    path = tmp_path / "swipes.npz"
    write_recording(path, short)
    source = open_replay(str(path), accel_desk, speed=0)
    est = ContactEstimator(accel_desk)
    blocks = [est.push(b.t, b.wrench, b.accel).copy() for b in source.blocks()]
    source.close()
    streamed = type(blocks[0]).concat(blocks)
    batch = estimate(accel_desk, short)
    assert not (streamed.flags & FLAG_NO_ACCEL).any()
    np.testing.assert_allclose(streamed.x, batch.x, atol=1e-9)


def test_a_bad_accelerometer_cell_is_named_not_dropped(accel_desk, kita, tmp_path):
    """Other text columns are ignored, but losing the accelerometer's would silently turn
    its compensation off: a bad cell is an error with file:line:column."""
    k = 50
    short = type(kita)(
        kita.t[:k], kita.wrench[:k], kita.sensor_names, {c: v[:k] for c, v in kita.extra.items()}
    )
    path = tmp_path / "bad.csv"
    write_recording(path, short)
    lines = path.read_text().splitlines()
    header = lines[0].split(",")
    cells = lines[11].split(",")
    cells[header.index("acc_y")] = "oops"
    lines[11] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(ConfigError) as info:
        read_recording(path, accel_desk.sensor_names)
    assert str(info.value).startswith(f"{path}:12:{header.index('acc_y') + 1}:")
    assert "acc_y" in str(info.value)
