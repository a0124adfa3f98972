"""The ATI NETCANOEM protocol: identifiers, frames, calibration, units and the status word."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from hapticdesk.canbus import ati_netcanoem as ati
from hapticdesk.canbus.config import AtiSensor
from hapticdesk.canbus.config_reader import can_config
from hapticdesk.canbus.frame_encoder import FrameEncoder


def test_identifiers_are_base_and_opcode():
    assert ati.frame_id(0x20, ati.OP_GAUGES_A) == 0x200
    assert ati.frame_id(0x7F, ati.OP_FIRMWARE) == 0x7FF
    assert ati.ati_frame_ids(0x21) == set(range(0x210, 0x220))


def test_sample_frames_are_big_endian_as_the_manual_says():
    a, b = ati.encode_gauge_frames(
        np.array([0x1234]), np.array([[-2, 1, 300, -300, 32767, -32768]])
    )
    assert a[0].tobytes() == bytes([0x12, 0x34, 0xFF, 0xFE, 0x01, 0x2C, 0x7F, 0xFF])
    assert b[0, :6].tobytes() == bytes([0x00, 0x01, 0xFE, 0xD4, 0x80, 0x00])
    fields_a = ati.decode_gauges_a(a)
    fields_b = ati.decode_gauges_b(b)
    assert fields_a[0].tolist() == [0x1234, -2, 300, 32767]
    assert fields_b[0].tolist() == [1, -300, -32768]
    assert ati.gauges_from_fields(fields_a[:, 1:], fields_b)[0].tolist() == [
        -2,
        1,
        300,
        -300,
        32767,
        -32768,
    ]


def test_random_gauges_round_trip():
    rng = np.random.default_rng(0)
    gauges = rng.integers(-32768, 32768, (500, 6))
    status = rng.integers(0, 65536, 500)
    a, b = ati.encode_gauge_frames(status, gauges)
    fa, fb = ati.decode_gauges_a(a), ati.decode_gauges_b(b)
    np.testing.assert_array_equal(fa[:, 0], status)
    np.testing.assert_array_equal(ati.gauges_from_fields(fa[:, 1:], fb), gauges)


def test_units_and_counts_scale_the_matrix():
    cal = ati.AtiCalibration(np.eye(6) * 2.0, 1000.0, 500.0, "lbf", "lbf-in")
    g = cal.gauge_map()
    assert g[0, 0] == pytest.approx(2.0 / 1000.0 * 4.4482216152605)
    assert g[5, 5] == pytest.approx(2.0 / 500.0 * 0.1129848290276167)
    wrench = np.array([[10.0, -5.0, 100.0, 0.5, -0.25, 1.0]])
    back = cal.gauges_for(wrench) @ g.T
    np.testing.assert_allclose(back, wrench, atol=np.abs(g).sum(axis=1).max())


def test_example_calibration_covers_the_rated_ranges():
    rng = np.random.default_rng(1)
    lim = np.array([150, 150, 300, 4, 4, 4.0])
    wrench = rng.uniform(-1, 1, (20000, 6)) * lim
    for seed in range(4):
        cal = ati.example_calibration(seed)
        gauges = np.linalg.solve(cal.gauge_map(), wrench.T).T
        assert np.abs(gauges).max() < 32767  # nothing clips inside the ratings
        assert np.abs(cal.gauge_map()[:3]).sum(axis=1).max() < 0.1  # N per gauge count


def _exchange(base, cal, *, with_requests=True):
    out = []
    for ident, payload in ati.calibration_requests(base):
        if with_requests:
            out.append((ident, payload))
        out += ati.replies(base, ident, payload, cal)
    return out


def test_calibration_collected_from_the_replies():
    cal = ati.example_calibration(2)
    cal = ati.AtiCalibration(cal.matrix, 2_000_000, 500_000, "kN", "N-mm", "FT12345")
    collector = ati.CalibrationCollector(0x21)
    collector.feed(0x201, bytes(8))  # other boards' traffic is ignored
    for ident, payload in _exchange(0x21, cal):
        collector.feed(ident, payload)
    got = collector.calibration()
    assert got is not None and collector.missing() == []
    np.testing.assert_array_equal(got.matrix, cal.matrix)  # float32 replies carry it exactly
    assert (got.counts_per_force, got.counts_per_torque) == (2_000_000, 500_000)
    assert (got.force_unit, got.torque_unit, got.serial) == ("kN", "N-mm", "FT12345")


def test_row_replies_without_requests_are_not_guessed():
    collector = ati.CalibrationCollector(0x20)
    for ident, payload in _exchange(0x20, ati.example_calibration(0), with_requests=False):
        collector.feed(ident, payload)
    assert collector.calibration() is None
    assert collector.unpaired_rows == 18 and "matrix row 0" in collector.missing()


def test_counts_reply_layout():
    cal = ati.AtiCalibration(np.eye(6), 1_000_000, 1_000_000)
    ((ident, data),) = ati.replies(0x20, 0x207, b"", cal)
    assert ident == 0x207 and struct.unpack(">ii", data) == (1_000_000, 1_000_000)
    assert ati.replies(0x20, 0x208, b"", cal) == [(0x208, bytes([2, 3]))]  # N, N-m


def bench_frames(bench, status, n=40):
    config = can_config(bench)
    encoder = FrameEncoder(config, bench)
    rng = np.random.default_rng(5)
    t = np.arange(n) / bench.sample_rate_hz
    wrench = rng.normal(0, 10, (n, 1, 6))
    wrench[:, :, 3:] *= 0.05  # moments within the sensor's range
    frames = encoder.encode(t, wrench, status=status, polls=True)
    return config, encoder, t, wrench, frames


def test_critical_status_bits_void_the_sample(bench, run_assembler):
    n = 40
    status = np.zeros((n, 1), dtype=np.int64)
    status[10] = 1 << 3  # analog ground: critical
    status[11] = 1 << 12  # temperature: critical
    status[20] = 1 << 14  # CAN bus error seen: not critical
    status[21] = (1 << 0) | (1 << 15)  # watchdog reset, any error: not critical
    config, encoder, t, wrench, frames = bench_frames(bench, status, n)
    got_t, got, asm = run_assembler(bench, config, frames, encoder.calibrations)
    assert len(got_t) == n
    bad = np.isnan(got).any(axis=(1, 2))
    assert bad.tolist() == [i in (10, 11) for i in range(n)]
    np.testing.assert_allclose(got[~bad], wrench[~bad], atol=0.1)
    assert asm.stats.invalid["ft"] == 2
    bits = asm.stats.status["ft"]
    assert bits[ati.status_bit_name(3)] == 1 and bits[ati.status_bit_name(14)] == 1
    assert bits[ati.status_bit_name(15)] == 1 and bits[ati.status_bit_name(0)] == 1
    assert any("status bit 14" in line for line in asm.stats.summary())


def test_calibration_from_the_profile_is_used(bench, run_assembler):
    cal = ati.AtiCalibration(np.eye(6) * 1000.0, 1_000_000, 1_000_000)
    config, _, t, wrench, _ = bench_frames(bench, None)
    config = type(config)(**{**config.__dict__, "sensors": {"ft": AtiSensor(0x20, cal)}})
    frames = FrameEncoder(config, bench).encode(t, wrench, polls=True)
    _, got, _ = run_assembler(bench, config, frames)
    np.testing.assert_allclose(got, wrench, atol=0.0006)  # 1 gauge count = 0.001 N
