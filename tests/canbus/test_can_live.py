"""Live on python-can's virtual bus, in one process: emulator → CAN source → estimator."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import can
import numpy as np
import pytest
from can.interfaces.virtual import VirtualBus

from hapticdesk.canbus.bus_spec import CanSourceError
from hapticdesk.canbus.config_reader import can_config
from hapticdesk.canbus.emulator import CanEmulator
from hapticdesk.canbus.frame_encoder import FrameEncoder
from hapticdesk.canbus.source import open_can_source
from hapticdesk.canbus.stats import SensorSilentError
from hapticdesk.estimator import ContactEstimator, estimate
from hapticdesk.estimator.contacts import ContactBlock, contact_events
from hapticdesk.files.profile_reader import load_profile
from hapticdesk.files.recording import Recording
from hapticdesk.sim import load_scene, simulate

SCENE = """name: can-e2e
desk: kitamura2017-can
units: cm
quiet_s: 1.5
tail_s: 0.6
timeline:
  - tap: {point: [-12, 6]}
  - press: {point: [15, -8], peak_n: 12}
  - tap: {point: [3, 10]}
"""


def read_until(source, done, timeout_s: float = 20.0):
    """Blocks from ``source`` until ``done(blocks)`` or the timeout; closes the source."""
    blocks = []
    deadline = time.monotonic() + timeout_s
    try:
        for block in source.blocks():
            blocks.append(block)
            if done(blocks) or time.monotonic() > deadline:
                break
    finally:
        source.close()
    return blocks


@pytest.fixture(scope="module")
def scene_recording(tmp_path_factory):
    path = tmp_path_factory.mktemp("scene") / "scene.yaml"
    path.write_text(SCENE)
    profile = load_profile("kitamura2017-can")
    return profile, simulate(profile, load_scene(path), seed=4)


def test_emulator_source_estimator_matches_the_recording_path(
    scene_recording, dbc_tolerance, virtual_channel
):
    profile, rec = scene_recording
    name = virtual_channel
    source = open_can_source(f"can:virtual:{name}", profile)
    bus = can.Bus(interface="virtual", channel=name, preserve_timestamps=True)
    emulator = CanEmulator(
        FrameEncoder(can_config(profile), profile), rec.t, rec.wrench, bus, speed=0
    )
    thread = emulator.start()
    estimator = ContactEstimator(profile)
    contacts = []
    count = 0

    def done(blocks):
        nonlocal count
        block = blocks[-1]
        contacts.append(estimator.push(block.t, block.wrench).copy())  # (a view till the next)
        count += len(block.t)
        return count >= len(rec)

    blocks = read_until(source, done)
    thread.join(5)
    bus.shutdown()
    t = np.concatenate([b.t for b in blocks])
    wrench = np.concatenate([b.wrench for b in blocks])
    assert len(t) == len(rec) and source.stats.summary() == [
        f"{8 * len(rec)} frames, {len(rec)} samples"
    ]
    np.testing.assert_allclose(t, rec.t, atol=1e-9)
    assert (np.abs(wrench - rec.wrench) <= dbc_tolerance).all()

    live = ContactBlock.concat(contacts)
    # the recording path, on the same samples as the bus carried them
    batch = estimate(profile, Recording(t, wrench, profile.sensor_names))
    for field in ("in_contact", "located", "source", "phase", "flags"):
        np.testing.assert_array_equal(getattr(live, field), getattr(batch, field), err_msg=field)
    np.testing.assert_allclose(live.x, batch.x, atol=1e-9)
    # and the recording as simulated, before the DBC's 0.01 N steps: the same touches, at
    # the same places but for what those steps move
    original = estimate(profile, rec)
    downs = [e for e in contact_events(live) if e.kind == "down"]
    assert len(downs) == len([e for e in contact_events(original) if e.kind == "down"]) == 3
    both = live.located & original.located
    assert both.sum() > 0.9 * max(live.located.sum(), original.located.sum())
    distance = np.hypot(live.x - original.x, live.y - original.y)[both]
    assert np.median(distance) < 1e-3 and np.percentile(distance, 99) < 5e-3


def test_ati_bench_calibration_and_polls_on_the_bus(bench, profile_text, virtual_channel):
    # polled at 100 Hz: the test's threads share two cores with everything else
    bench = profile_text(
        Path(str(bench.path)).read_text().replace("sample_rate_hz: 500", "sample_rate_hz: 100"),
        "bench.yaml",
    )
    n = 150
    rng = np.random.default_rng(8)
    t = np.arange(n) / bench.sample_rate_hz
    wrench = rng.normal(0, 20, (n, 1, 6))
    wrench[:, :, 3:] *= 0.02
    name = virtual_channel
    bus = can.Bus(interface="virtual", channel=name)
    encoder = FrameEncoder(can_config(bench), bench)
    emulator = CanEmulator(encoder, t, wrench, bus)
    thread = emulator.start()
    seen = []
    source = open_can_source(f"virtual:{name}", bench, frame_sink=seen.extend)
    # the calibration came over the bus, exactly (float32 replies)
    np.testing.assert_array_equal(
        source.calibrations["ft"].matrix, encoder.calibrations["ft"].matrix
    )
    ended_at: list[int] = []

    def one_block_after_the_end(blocks) -> bool:
        """The board answered its last poll a block ago (that poll is read with a block
        after the one in which the board's thread ended)."""
        if not ended_at and not thread.is_alive():
            ended_at.append(len(blocks))
        return bool(ended_at) and len(blocks) > ended_at[0]

    blocks = read_until(source, one_block_after_the_end, timeout_s=10)
    emulator.stop()
    thread.join(2)
    bus.shutdown()
    got = np.concatenate([b.wrench for b in blocks])[:, 0]
    ok = ~np.isnan(got).any(axis=1)
    assert emulator.stats.polls == n and ok.sum() >= 0.5 * n
    # every sample given out is one the board sent, whole, in the order it sent them
    diff = np.abs(got[ok][:, None, :] - wrench[None, :, 0, :]).max(axis=2)
    match = diff.argmin(axis=1)
    assert (diff.min(axis=1) < 0.05).all()
    assert (np.diff(match) > 0).all()
    # the frame sink saw the calibration exchange and the polls, both directions
    sent = [m for m in seen if not m.is_rx]
    assert any(m.arbitration_id == 0x202 and len(m.data) == 1 for m in sent)
    assert sum(m.arbitration_id == 0x200 and len(m.data) == 0 for m in sent) >= n


class FlakyBus(VirtualBus):
    """A virtual bus whose driver reports bus-off once, after ``fail_after`` frames."""

    fail_after: int | None = None
    opened = 0

    def __init__(self, *args, **kwargs):
        type(self).opened += 1
        super().__init__(*args, **kwargs)
        self.received = 0

    def recv(self, timeout=None):
        cls = type(self)
        if cls.fail_after is not None and self.received >= cls.fail_after:
            cls.fail_after = None
            raise can.CanOperationError("bus-off (from the test)")
        msg = super().recv(timeout)
        self.received += msg is not None
        return msg


def test_bus_off_then_reconnect(can_desk, make_samples, dbc_tolerance, virtual_channel):
    t, wrench = make_samples(1200, 4)
    name = virtual_channel
    FlakyBus.fail_after, FlakyBus.opened = 3000, 0
    source = open_can_source(
        f"can:virtual:{name}", can_desk, bus_factory=lambda **kw: FlakyBus(**kw)
    )
    bus = can.Bus(interface="virtual", channel=name)
    emulator = CanEmulator(FrameEncoder(can_config(can_desk), can_desk), t, wrench, bus, speed=1)
    thread = emulator.start()
    blocks = read_until(source, lambda b: b[-1].t[-1] * 1200 > 1198.5, timeout_s=10)
    thread.join(2)
    bus.shutdown()
    assert FlakyBus.opened == 2 and source.reconnects == 1
    kinds = [n.kind for n in source.notices]
    assert "bus" in kinds and any("is back" in n.message for n in source.notices)
    got_t = np.concatenate([b.t for b in blocks])
    got = np.concatenate([b.wrench for b in blocks])
    valid = ~np.isnan(got).any(axis=(1, 2))
    idx = np.rint(got_t * 1200).astype(int)
    # samples go on after the reconnect, and what was given out is right
    assert idx.max() > 1100 and valid.sum() > 600
    assert (np.abs(got[valid] - wrench[idx[valid]]) <= dbc_tolerance).all()


def test_ati_bus_off_then_reconnect(bench_board, virtual_channel):
    """The poller thread reads the bus: the failure it meets is the reader's to reconnect,
    and polling goes on over the new bus."""
    board = bench_board(rate=200, n=2000, seed=5)
    FlakyBus.fail_after, FlakyBus.opened = 40, 0  # (after the calibration's replies)
    source = open_can_source(
        f"can:virtual:{virtual_channel}", board.profile, bus_factory=lambda **kw: FlakyBus(**kw)
    )
    try:
        polled = board.emulator.stats
        blocks = read_until(source, lambda _: source.reconnects and polled.polls > 150)
    finally:
        board.stop()
    assert FlakyBus.opened == 2 and source.reconnects == 1
    got = np.concatenate([b.wrench for b in blocks])[:, 0]
    ok = ~np.isnan(got).any(axis=1)
    assert ok.sum() >= 100 and source.stats.duplicates == 0
    diff = np.abs(got[ok][:, None, :] - board.wrench[None, :, 0, :]).max(axis=2)
    assert (diff.min(axis=1) < 0.05).all()  # each sample given out is one the board sent


class FloodedBus(VirtualBus):
    """A virtual bus that never runs dry once polling starts: whenever no frame waits, a
    foreign frame (a CANopen PDO) is there, as on a bus faster than the host can read."""

    flooding = False

    def recv(self, timeout=None):
        msg = super().recv(0.0 if type(self).flooding else timeout)
        if msg is None and type(self).flooding:
            return can.Message(arbitration_id=0x181, data=b"\x01" * 8, is_extended_id=False)
        return msg


def test_a_flooded_bus_still_gets_its_polls(bench_board, virtual_channel):
    """The poller reads what waits for a sample period at most, then polls: a bus that never
    runs dry does not stop the samples."""
    board = bench_board(rate=200, n=2000, seed=6)
    FloodedBus.flooding = False  # (the calibration first)
    source = open_can_source(
        f"can:virtual:{virtual_channel}", board.profile, bus_factory=lambda **kw: FloodedBus(**kw)
    )
    FloodedBus.flooding = True
    start = time.monotonic()
    try:
        blocks = read_until(source, lambda _: board.emulator.stats.polls >= 100, timeout_s=10)
    finally:
        FloodedBus.flooding = False
        board.stop()
    assert board.emulator.stats.polls >= 100, board.emulator.stats  # polls went on
    assert time.monotonic() - start < 5  # (at 200 Hz, 100 polls take 0.5 s, 1 s if halved)
    got = np.concatenate([b.wrench for b in blocks])[:, 0]
    ok = ~np.isnan(got).any(axis=1)
    assert ok.sum() >= 50 and source.stats.foreign.get(0x181, 0) > 1000
    diff = np.abs(got[ok][:, None, :] - board.wrench[None, :, 0, :]).max(axis=2)
    assert (diff.min(axis=1) < 0.05).all()  # each sample given out is one the board sent


def test_a_bus_that_does_not_come_back(can_desk, profile_text, tmp_path, virtual_channel):
    text = (
        Path(str(can_desk.path))
        .read_text()
        .replace(
            "  silent_sensor: continue", "  silent_sensor: continue\n  reconnect_timeout_s: 0.3"
        )
    )
    profile = profile_text(text, "desk.yaml")
    opened = []

    def factory(**kwargs):
        if opened:
            raise can.CanInitializationError("adapter unplugged")
        opened.append(1)
        bus = FlakyBus(**kwargs)
        FlakyBus.fail_after = 0
        return bus

    source = open_can_source(f"can:virtual:{virtual_channel}", profile, bus_factory=factory)
    with pytest.raises(
        CanSourceError, match=r"CAN bus lost \(bus-off.*not back within 0.3 s.*adapter unplugged"
    ):
        list(source.blocks())
    source.close()


def test_clear_errors_when_opening(can_desk, bench, virtual_channel):
    with pytest.raises(CanSourceError, match=r"cannot open CAN interface 'nosuch'"):
        open_can_source("can:nosuch:x", can_desk)
    with pytest.raises(CanSourceError, match="no CAN interface"):
        open_can_source("can:", can_desk_without_interface(can_desk))
    with pytest.raises(
        CanSourceError, match=r"ATI sensor `ft` \(base 0x20\) did not answer request 0x202"
    ):
        open_can_source(f"can:virtual:{virtual_channel}", bench, calibration_timeout_s=0.02)


def can_desk_without_interface(profile):
    from dataclasses import replace

    from hapticdesk.files.marked_values import MarkedDict

    section = MarkedDict(profile.can)
    section.position = profile.can.position
    section.key_positions = profile.can.key_positions
    section.value_positions = profile.can.value_positions
    del section["interface"]
    return replace(profile, can=section)


def test_a_silent_sensor_stops_the_live_source(
    can_desk, profile_text, make_samples, virtual_channel
):
    text = (
        Path(str(can_desk.path))
        .read_text()
        .replace("silent_sensor: continue", "silent_sensor: stop")
    )
    profile = profile_text(text, "desk.yaml")
    t, wrench = make_samples(1200, 4)
    wrench[400:, 1] = np.nan  # fr's frames are not sent from sample 400 on
    name = virtual_channel
    source = open_can_source(f"can:virtual:{name}", profile)
    bus = can.Bus(interface="virtual", channel=name, preserve_timestamps=True)
    emulator = CanEmulator(FrameEncoder(can_config(profile), profile), t, wrench, bus, speed=0)
    thread = emulator.start()
    blocks = []
    with pytest.raises(SensorSilentError, match="sensor fr has sent nothing for 0.2 s"):
        for block in source.blocks():
            blocks.append(block)
    source.close()
    thread.join(5)
    bus.shutdown()
    got = np.concatenate([b.wrench for b in blocks])
    # what came before the silence was given out; nothing after the stop
    assert len(got) == 400 + 240 and not np.isnan(got[:400]).any() and np.isnan(got[400:, 1]).all()


def test_close_from_another_thread_ends_blocks(can_desk, virtual_channel):
    source = open_can_source(f"can:virtual:{virtual_channel}", can_desk)
    timer = threading.Timer(0.2, source.close)
    timer.start()
    assert list(source.blocks()) == []  # nothing on the bus; ends when closed
    source.close()  # idempotent
