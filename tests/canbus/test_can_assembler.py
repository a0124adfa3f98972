"""Frames into samples: clean streams, and every kind of bad frame a real bus produces."""

from __future__ import annotations

import numpy as np
import pytest

from hapticdesk.canbus.assembler import FrameAssembler
from hapticdesk.canbus.config_reader import can_config
from hapticdesk.canbus.decoding import build_decoding
from hapticdesk.canbus.frame_encoder import FrameEncoder
from hapticdesk.canbus.frames import FrameArray
from hapticdesk.canbus.stats import SensorSilentError


def mix(frames: FrameArray, other: FrameArray) -> FrameArray:
    """Insert ``other`` frames in time order (stable: at equal times desk frames come first)."""
    both = FrameArray.concat([frames, other])
    return both.take(np.argsort(both.t, kind="stable"))


def check_equal(got_t, got, t, wrench, tol):
    assert len(got_t) == len(t)
    np.testing.assert_allclose(got_t, t, rtol=0, atol=1e-9)
    assert not np.isnan(got).any()
    assert (np.abs(got - wrench) <= tol).all()


# --- clean streams, any split -----------------------------------------------------------------


def test_counter_assembly_round_trip(can_desk, dbc_frames, run_assembler, dbc_tolerance):
    t, wrench, frames = dbc_frames(600)  # more than two wraps of the 8-bit counter
    got_t, got, asm = run_assembler(can_desk, can_config(can_desk), frames)
    check_equal(got_t, got, t, wrench, dbc_tolerance)
    assert asm.stats.samples == 600 and asm.stats.summary() == ["4800 frames, 600 samples"]


@pytest.mark.parametrize("chunks", [2, 7, 61, 4800])
def test_any_split_gives_the_same_samples(can_desk, dbc_frames, run_assembler, chunks):
    _, _, frames = dbc_frames(600)
    config = can_config(can_desk)
    whole_t, whole, _ = run_assembler(can_desk, config, frames)
    split_t, split, _ = run_assembler(can_desk, config, frames, chunks=chunks)
    np.testing.assert_array_equal(split_t, whole_t)
    np.testing.assert_array_equal(split, whole)


@pytest.mark.parametrize("chunks", [1, 5, 37, 600 * 12])
def test_ati_polled_any_split(ati_desk, make_samples, run_assembler, chunks):
    profile, config = ati_desk
    encoder = FrameEncoder(config, profile)
    t, wrench = make_samples(600, 4)
    frames = encoder.encode(t, wrench, polls=True)
    got_t, got, _ = run_assembler(profile, config, frames, encoder.calibrations, chunks=chunks)
    check_equal(got_t, got, t, wrench, 0.1)


def test_time_assembly_by_pauses_and_without_times(
    uncounted_desk, dbc_frames, run_assembler, dbc_tolerance
):
    profile = uncounted_desk
    config = can_config(profile)
    assert config.assemble == "time"
    t, wrench, frames = dbc_frames(300)
    # frames of one sample 20 µs apart, as a fast bus sends them
    frames.t = frames.t + np.tile(np.arange(8) * 20e-6, 300)
    got_t, got, _ = run_assembler(profile, config, frames, chunks=9)
    check_equal(got_t, got, t, wrench, dbc_tolerance)
    # a log without times: samples by the order of frames, times from the sample rate
    frames.t[:] = np.nan
    got_t, got, _ = run_assembler(profile, config, frames, chunks=9)
    check_equal(got_t, got, t, wrench, dbc_tolerance)


# --- other traffic ----------------------------------------------------------------------------


def test_interleaved_canopen_traffic_is_ignored(
    can_desk, dbc_frames, run_assembler, dbc_tolerance, canopen_traffic
):
    t, wrench, frames = dbc_frames(600)
    traffic = canopen_traffic(3000, t[-1], seed=1)
    got_t, got, asm = run_assembler(can_desk, can_config(can_desk), mix(frames, traffic), chunks=13)
    check_equal(got_t, got, t, wrench, dbc_tolerance)
    assert sum(asm.stats.foreign.values()) == 3000
    text = " ".join(asm.stats.summary())
    for kind in ("CANopen SYNC", "CANopen PDO", "CANopen SDO", "CANopen heartbeat", "CANopen NMT"):
        assert kind in text


def test_unknown_and_extended_ids_are_ignored(can_desk, dbc_frames, run_assembler, dbc_tolerance):
    t, wrench, frames = dbc_frames(300)
    rng = np.random.default_rng(2)
    n = 500
    ident = rng.integers(0x150, 0x7FF, n)
    data = [bytes(rng.integers(0, 256, 8, dtype=np.uint8)) for _ in range(n)]
    unknown = FrameArray.build(rng.uniform(0, t[-1], n), ident, data, extended=rng.random(n) < 0.3)
    extended_twin = FrameArray.build(t, 0x110, [bytes(8)] * len(t), extended=True)  # 0x110, 29-bit
    got_t, got, asm = run_assembler(
        can_desk, can_config(can_desk), mix(frames, FrameArray.concat([unknown, extended_twin]))
    )
    check_equal(got_t, got, t, wrench, dbc_tolerance)
    assert sum(asm.stats.foreign.values()) == n + len(t)


def test_ati_boards_among_canopen_drives(ati_desk, make_samples, run_assembler, canopen_traffic):
    """Base 0x20 shares 0x201 with node 1's RPDO: length tells them apart, else it is flagged."""
    profile, config = ati_desk
    encoder = FrameEncoder(config, profile)
    t, wrench = make_samples(300, 4)
    frames = encoder.encode(t, wrench, polls=True)
    traffic = canopen_traffic(1500, t[-1], seed=3)
    got_t, got, asm = run_assembler(profile, config, mix(frames, traffic), encoder.calibrations)
    ok = ~np.isnan(got).any(axis=2)  # (k, S)
    # an RPDO of 6 bytes on 0x201 inside a sample makes fl's frame doubled: voided, not used
    rpdo6 = (traffic.ident == 0x201) & (traffic.dlc == 6)
    assert (~ok[:, 0]).sum() <= rpdo6.sum()
    assert ok[:, 1:].all()
    np.testing.assert_allclose(got[ok[:, 0], 0], wrench[ok[:, 0], 0], atol=0.1)
    np.testing.assert_allclose(got[:, 1:], wrench[:, 1:], atol=0.1)
    assert (
        asm.stats.wrong_length.get(0x201, 0)
        == ((traffic.ident == 0x201) & (traffic.dlc != 6)).sum()
    )


# --- order, loss, length, counters ------------------------------------------------------------


def test_frames_in_any_order(can_desk, dbc_frames, run_assembler, dbc_tolerance):
    t, wrench, frames = dbc_frames(600)
    rng = np.random.default_rng(4)
    order = np.concatenate([w + rng.permutation(16) for w in range(0, 4800, 16)])  # 2 samples
    got_t, got, asm = run_assembler(can_desk, can_config(can_desk), frames.take(order), chunks=11)
    check_equal(got_t, got, t, wrench, dbc_tolerance)
    assert asm.stats.late == 0


def test_a_lost_frame_leaves_only_its_channels_nan(
    can_desk, dbc_frames, run_assembler, dbc_tolerance
):
    t, wrench, frames = dbc_frames(400)
    lost = (frames.ident == 0x111) & np.isin(np.arange(len(frames)) // 8, [100, 250])  # FL_MOMENT
    got_t, got, asm = run_assembler(can_desk, can_config(can_desk), frames.take(~lost))
    assert len(got_t) == 400
    assert np.isnan(got[[100, 250], 0, 3:]).all()
    assert not np.isnan(np.delete(got, [100, 250], axis=0)).any()
    assert (np.abs(got[:, 0, :3] - wrench[:, 0, :3]) <= dbc_tolerance[:3]).all()
    assert asm.stats.incomplete == {"fl": 2, "fr": 0, "bl": 0, "br": 0}


def test_a_frame_of_the_wrong_length_is_dropped(can_desk, dbc_frames, run_assembler):
    t, wrench, frames = dbc_frames(200)
    i = 8 * 50 + 2  # FR_FORCE of sample 50
    assert frames.ident[i] == 0x120
    frames.dlc[i] = 7
    got_t, got, asm = run_assembler(can_desk, can_config(can_desk), frames)
    assert len(got_t) == 200
    assert np.isnan(got[50, 1, :3]).all() and not np.isnan(got[50, 1, 3:]).any()
    assert np.isnan(got).sum() == 3
    assert asm.stats.wrong_length == {0x120: 1}


def test_a_doubled_frame_is_not_trusted(can_desk, dbc_frames, run_assembler):
    t, wrench, frames = dbc_frames(100)
    twin = frames.take(np.array([8 * 40 + 4]))  # BL_FORCE of sample 40 …
    twin.data = twin.data.copy()
    twin.data[0, 0] ^= 0xFF  # … sent again with other values
    got_t, got, asm = run_assembler(
        can_desk,
        can_config(can_desk),
        FrameArray.concat([frames.take(slice(0, 8 * 41)), twin, frames.take(slice(8 * 41, None))]),
    )
    assert np.isnan(got[40, 2, :3]).all() and np.isnan(got).sum() == 3
    assert asm.stats.duplicates == 2


def test_counters_that_jump(can_desk, dbc_frames, run_assembler, dbc_tolerance):
    t, wrench, frames = dbc_frames(1000)
    sample = np.arange(len(frames)) // 8
    gone = ((sample >= 200) & (sample < 205)) | ((sample >= 500) & (sample < 800))  # 5, then 300
    got_t, got, asm = run_assembler(can_desk, can_config(can_desk), frames.take(~gone), chunks=5)
    keep = np.ones(1000, bool)
    keep[200:205] = keep[500:800] = False
    # 300 lost samples are more than the 8-bit counter's range: the frame times tell the wraps
    check_equal(got_t, got, t[keep], wrench[keep], dbc_tolerance)
    assert asm.stats.lost_samples == 305


def test_one_sensor_counter_off_is_never_merged(can_desk, dbc_frames, run_assembler, dbc_tolerance):
    """fl restarts its counter at 0 (a reboot) while the others go on: fl's data is not used."""
    t, wrench, frames = dbc_frames(600)
    sample = np.arange(len(frames)) // 8
    fl = np.isin(frames.ident, [0x110, 0x111]) & (sample >= 300)
    frames.data[fl, 6] = (sample[fl] - 300) % 256  # Seq of fl from 0 again
    got_t, got, asm = run_assembler(can_desk, can_config(can_desk), frames)
    ok = ~np.isnan(got[:, 0]).any(axis=1)
    good = got[ok, 0]
    # every fl value given out is fl's own value of that very sample
    idx = np.rint(got_t[ok] * 1200).astype(int)
    assert (np.abs(good - wrench[idx, 0]) <= dbc_tolerance).all()
    assert not ok[np.rint(got_t * 1200).astype(int) >= 300].any()
    others = np.rint(got_t * 1200).astype(int)
    valid_others = ~np.isnan(got[:, 1:]).any(axis=(1, 2))
    assert (np.abs(got[valid_others, 1:] - wrench[others[valid_others], 1:]) <= dbc_tolerance).all()
    assert asm.stats.late == 2 * 300 and asm.stats.incomplete["fl"] == 300
    assert [n.kind for n in asm.notices] == ["silent"]
    assert "sensor fl sends, but none of its frames fit" in asm.notices[0].message


# --- a sensor that stops ----------------------------------------------------------------------


def test_a_silent_sensor_continue(can_desk, dbc_frames, run_assembler, dbc_tolerance):
    t, wrench, frames = dbc_frames(1200)
    sample = np.arange(len(frames)) // 8
    silent = np.isin(frames.ident, [0x140, 0x141]) & (sample >= 300) & (sample < 900)
    got_t, got, asm = run_assembler(can_desk, can_config(can_desk), frames.take(~silent), chunks=10)
    assert len(got_t) == 1200
    assert np.isnan(got[300:900, 3]).all() and not np.isnan(got[:300]).any()
    assert not np.isnan(got[900:]).any() and not np.isnan(got[:, :3]).any()
    kinds = [(n.kind, round(n.t, 3)) for n in asm.notices]
    # silent after silent_timeout_s (0.2 s) without br, back when it sends again
    assert kinds == [("silent", round((299 + 1 + 0.2 * 1200) / 1200, 3)), ("back", 0.75)]
    assert "sensor br" in asm.notices[0].message and "t=0.249" in asm.notices[0].message


def test_a_silent_sensor_stop(can_desk, dbc_frames, run_assembler):
    t, wrench, frames = dbc_frames(1200)
    sample = np.arange(len(frames)) // 8
    silent = np.isin(frames.ident, [0x130, 0x131]) & (sample >= 300)
    with pytest.raises(SensorSilentError, match=r"sensor bl has sent nothing for 0.2 s .*stopping"):
        run_assembler(
            can_desk, can_config(can_desk), frames.take(~silent), chunks=4, silent_sensor="stop"
        )
    # the samples before the silence are given out before the error
    asm = FrameAssembler(
        build_decoding(can_config(can_desk), can_desk),
        1200,
        assemble="counter",
        silent_sensor="stop",
    )
    out = asm.push(frames.take(~silent))
    # bl's last data at sample 299; 0.2 s (240 samples) later, at sample 540, it is silent
    assert out.stop is not None and len(out.t) == 540
    assert np.isnan(out.wrench[300:, 2]).all() and not np.isnan(out.wrench[:300]).any()
    assert len(asm.push(frames).t) == 0  # stopped stays stopped


def test_a_database_status_signal_voids_the_sample(can_desk, dbc_frames, run_assembler):
    status = np.zeros((300, 4), dtype=np.int64)
    status[[17, 18, 200], 1] = [1, 2, 3]  # fr: saturated, sensor fault, overtemperature
    t, wrench, frames = dbc_frames(300, status=status)
    got_t, got, asm = run_assembler(can_desk, can_config(can_desk), frames)
    voided = np.isnan(got).any(axis=2)
    assert voided[:, 1].tolist() == [i in (17, 18, 200) for i in range(300)]
    assert not voided[:, [0, 2, 3]].any()
    assert asm.stats.invalid == {"fl": 0, "fr": 3, "bl": 0, "br": 0}
    assert asm.stats.status["fr"] == {"FR_FORCE.Status non-zero": 3, "FR_MOMENT.Status non-zero": 3}


def test_the_notices_of_a_flapping_sensor_are_bounded(
    can_desk, dbc_frames, run_assembler, monkeypatch
):
    """Issue 11 item 16: a sensor that keeps dropping out must not grow the notices for the
    whole run; the latest are kept."""
    import hapticdesk.canbus.assembler as assembler

    monkeypatch.setattr(assembler, "NOTICES_KEPT", 3)
    t, wrench, frames = dbc_frames(3600)
    sample = np.arange(len(frames)) // 8
    # br silent for 0.5 s of every second: a silent and a back notice each second
    silent = np.isin(frames.ident, [0x140, 0x141]) & ((sample // 600) % 2 == 1)
    got_t, got, asm = run_assembler(can_desk, can_config(can_desk), frames.take(~silent), chunks=10)
    assert [n.kind for n in asm.notices] == ["silent", "back", "silent"]  # of 5
    assert asm.notices[-1].t > 2.5  # the latest, not the first ones
