"""ATI on a busy bus (issue 11 #18, #19): second reply frames delayed past the next poll.

The board answers a poll (0x200, no data) with 0x200 (8 bytes) then 0x201 (6 bytes), in that
order. On a bus shared with a CANopen drive, SYNC and PDOs of higher priority can hold 0x201
back until after the host's next poll; it still belongs to the reply before it. The capture
is written as candump ``-l`` text, as `candump -l can0` saves it.
"""

from __future__ import annotations

import time
from pathlib import Path

import can
import numpy as np
import pytest
from can.interfaces.virtual import VirtualBus

from hapticdesk.canbus.assembler import FrameAssembler
from hapticdesk.canbus.ati_netcanoem import SAMPLE_BITS, max_poll_rate
from hapticdesk.canbus.config_reader import can_config
from hapticdesk.canbus.decoding import build_decoding
from hapticdesk.canbus.emulator import CanEmulator
from hapticdesk.canbus.frame_encoder import FrameEncoder
from hapticdesk.canbus.frames import FrameArray
from hapticdesk.canbus.logs.desk_samples import decode_can_log
from hapticdesk.canbus.source import open_can_source

T0 = 1_700_000_000.0
N = 600  # samples
LATE = 0.06  # share of replies whose second frame comes after the next poll
BIT_S = 1 / 250_000  # the board's default 250 kbit/s


def candump_l(frames: FrameArray) -> str:
    """``candump -l`` lines: ``(seconds) can0 ID#HEX``."""
    lines = []
    for i in range(len(frames)):
        data = frames.data[i, : frames.dlc[i]].tobytes().hex().upper()
        lines.append(f"({frames.t[i]:.6f}) can0 {int(frames.ident[i]):03X}#{data}")
    return "\n".join(lines) + "\n"


def canopen_drive(t_end: float, rng: np.random.Generator) -> FrameArray:
    """A CANopen drive (node 0x0A) at 1 kHz: SYNC 0x080, TPDO1 0x18A, RPDO1 0x20A, and its
    heartbeat 0x70A every 0.1 s. 0x20A is in the ATI board's identifier range (base 0x20,
    opcode 0xA): protocol traffic to the decoder, never sample data."""
    ticks = np.arange(0.0, t_end, 1e-3)
    parts = []
    for ident, length, offset in ((0x080, 0, 0.0), (0x18A, 8, 90e-6), (0x20A, 4, 300e-6)):
        n = len(ticks)
        data = [bytes(rng.integers(0, 256, length, dtype=np.uint8)) for _ in range(n)]
        parts.append(FrameArray.build(T0 + ticks + offset, [ident] * n, data))
    beats = np.arange(0.0, t_end, 0.1)
    parts.append(FrameArray.build(T0 + beats + 50e-6, [0x70A] * len(beats), [b"\x05"] * len(beats)))
    return FrameArray.concat(parts)


@pytest.fixture
def capture(bench, make_samples):
    """(samples, their wrench, frames of the capture, which replies came late)."""
    config = can_config(bench)
    encoder = FrameEncoder(config, bench)
    rate = bench.sample_rate_hz  # 500 Hz: a poll every 2 ms
    t, wrench = make_samples(N, 1, seed=11, rate=rate)
    wrench[:, :, 3:] *= 0.5
    body = encoder.encode(T0 + 0.01 + t, wrench, polls=True)  # per sample: poll, 0x200, 0x201
    rng = np.random.default_rng(4)
    # on the wire: the poll, then the first frame ~0.2 ms later, the second ~0.45 ms later
    body.t = body.t + np.tile([0.0, 200e-6, 450e-6], N)
    late = np.zeros(N, dtype=bool)
    late[rng.choice(np.arange(N - 1), int(LATE * N), replace=False)] = True
    late[:2] = True  # the capture's first replies too
    second = np.flatnonzero(body.ident == 0x201)
    # held back behind other traffic until just after the next poll (before the next reply)
    body.t[second[late]] = T0 + 0.01 + t[np.flatnonzero(late)] + 1 / rate + 100e-6
    frames = FrameArray.concat(
        [encoder.calibration_frames(T0), body, canopen_drive(0.01 + N / rate, rng)]
    )
    frames = frames.take(np.argsort(frames.t, kind="stable"))
    return t, wrench, frames, late


def ati_lines(text: str) -> list[str]:
    """The board's sample traffic in a candump -l text: poll ``200#``, ``200#…``, ``201#…``."""
    return [x.split()[-1] for x in text.splitlines() if x.split()[-1][:4] in ("200#", "201#")]


def test_the_capture_has_late_second_frames(capture):
    *_, frames, late = capture
    words = ati_lines(candump_l(frames))
    # a second frame straight after a poll: its reply's first frame came before that poll
    after_poll = sum(
        b.startswith("201#") and a == "200#" for a, b in zip(words, words[1:], strict=False)
    )
    assert after_poll == late.sum() == int(LATE * N) + 2


def test_late_second_frames_decode_every_sample(tmp_path, bench, capture):
    _, wrench, frames, _ = capture
    path = tmp_path / "busy-bus.log"
    path.write_text(candump_l(frames))
    result = decode_can_log(path, bench)
    rec, stats = result.recording, result.stats
    assert len(rec) == N and not np.isnan(rec.wrench).any()
    np.testing.assert_allclose(rec.wrench, wrench, atol=0.1)  # gauge counts: ~0.03 N
    assert stats.late == stats.duplicates == stats.lost_samples == 0
    assert stats.incomplete == {"ft": 0}
    assert stats.foreign and stats.protocol  # the drive's traffic was seen and set aside


@pytest.mark.parametrize("per_push", [1, 2, 7, 50])
def test_pairing_does_not_depend_on_how_frames_arrive(tmp_path, bench, capture, per_push):
    """Live, frames come in pushes of any size: a late second frame often in the next one."""
    _, wrench, frames, _ = capture
    config = can_config(bench)
    decoding = build_decoding(config, bench, {"ft": FrameEncoder(config, bench).calibrations["ft"]})
    asm = FrameAssembler(decoding, bench.sample_rate_hz)
    got = [
        asm.push(frames.take(slice(i, i + per_push))).wrench
        for i in range(0, len(frames), per_push)
    ]
    got.append(asm.flush().wrench)
    np.testing.assert_allclose(np.concatenate(got), wrench, atol=0.1)  # gauge counts: ~0.03 N
    assert asm.stats.samples == N and asm.stats.incomplete == {"ft": 0}


def test_truly_lost_frames_are_counted_not_paired_across_samples(tmp_path, bench, capture):
    _, wrench, frames, late = capture
    replies = frames.take(frames.dlc > 0)
    second = np.flatnonzero(replies.ident == 0x201)
    first = np.flatnonzero(replies.ident == 0x200)
    on_time = np.flatnonzero(~late[:-1] & ~late[1:])
    i, j = on_time[on_time > 100][0], on_time[on_time > 300][0]
    # sample i loses its second frame, sample j its first: neither takes a neighbour's
    drop = np.zeros(len(replies), dtype=bool)
    drop[[second[i], first[j]]] = True
    kept = FrameArray.concat([frames.take(frames.dlc == 0), replies.take(~drop)])
    kept = kept.take(np.argsort(kept.t, kind="stable"))
    path = tmp_path / "lossy.log"
    path.write_text(candump_l(kept))
    result = decode_can_log(path, bench)
    bad = np.isnan(result.recording.wrench).any(axis=(1, 2))
    assert np.flatnonzero(bad).tolist() == [i, j]
    np.testing.assert_allclose(result.recording.wrench[~bad], wrench[~bad], atol=0.1)
    assert result.stats.incomplete == {"ft": 2} and result.stats.duplicates == 0


class SlowBoardBus(VirtualBus):
    """The board's side of a virtual bus: it answers each sample poll ``delay_s`` late (a
    board slower than the poll rate, or a host that stalls), one poll after the other."""

    delay_s = 0.0

    def send(self, msg, timeout=None):
        if msg.arbitration_id & 0xF == 0x0 and len(msg.data) == 8:
            time.sleep(self.delay_s)
        super().send(msg, timeout)


def test_the_poller_waits_for_a_slow_board_instead_of_voiding_samples(
    bench, profile_text, virtual_channel
):
    """Polls every 20 ms, replies 25 ms after their poll: polls sent on the clock alone would
    land between every poll and its reply, and void nearly every sample."""
    bench = profile_text(
        Path(str(bench.path)).read_text().replace("sample_rate_hz: 500", "sample_rate_hz: 50"),
        "bench.yaml",
    )
    n = 200
    t = np.arange(n) / bench.sample_rate_hz
    wrench = np.random.default_rng(1).normal(0, 20, (n, 1, 6))
    wrench[:, :, 3:] *= 0.02
    board_bus = SlowBoardBus(channel=virtual_channel)
    emulator = CanEmulator(FrameEncoder(can_config(bench), bench), t, wrench, board_bus)
    thread = emulator.start()
    source = open_can_source(f"virtual:{virtual_channel}", bench)
    SlowBoardBus.delay_s = 0.025  # after the calibration exchange
    got = []
    deadline = time.monotonic() + 1.5
    try:
        for block in source.blocks():
            got.append(block.wrench)
            if time.monotonic() > deadline:
                break
    finally:
        source.close()
        emulator.stop()
        thread.join(2)
        board_bus.shutdown()
        SlowBoardBus.delay_s = 0.0
    w = np.concatenate(got)[:, 0]
    whole = ~np.isnan(w).any(axis=1)
    assert len(w) >= 20 and whole.mean() >= 0.9, (len(w), whole.mean())
    assert source.stats.duplicates == 0  # (a board owing a reply is not polled again)


def test_the_bus_capacity_is_stated():
    # a poll (0 bytes) and replies of 8 and 6 bytes, with worst-case bit stuffing
    assert SAMPLE_BITS == 55 + 135 + 115
    assert max_poll_rate(1, 250_000) == pytest.approx(820, abs=1)
    assert max_poll_rate(4, 1_000_000) == pytest.approx(820, abs=1)  # not a 1.2 kHz desk


def test_a_desk_faster_than_its_bus_is_told_at_start(bench, profile_text, virtual_channel, caplog):
    bench = profile_text(
        Path(str(bench.path)).read_text().replace("sample_rate_hz: 500", "sample_rate_hz: 1200"),
        "bench.yaml",
    )
    board_bus = can.Bus(interface="virtual", channel=virtual_channel)
    t = np.arange(10) / 1200
    emulator = CanEmulator(
        FrameEncoder(can_config(bench), bench), t, np.zeros((10, 1, 6)), board_bus
    )
    thread = emulator.start()
    try:
        source = open_can_source(  # a real interface's name: its bit rate is a limit
            "socketcan:can0",
            bench,
            bus_factory=lambda **kw: can.Bus(interface="virtual", channel=virtual_channel),
        )
        source.close()
    finally:
        emulator.stop()
        thread.join(2)
        board_bus.shutdown()
    notice = next(n for n in source.notices if n.kind == "capacity")
    assert "1 ATI board(s) polled at 1200 Hz need 366 kbit/s" in notice.message
    assert "runs at 250 kbit/s and carries at most ~820 samples/s" in notice.message


def test_polls_echoed_back_by_the_bus_are_not_counted_twice(bench_board, virtual_channel):
    """udp_multicast (and a virtual bus told to) hands the host its own polls back: taken
    twice, every poll would start a sample and every other sample be empty."""
    board = bench_board(rate=100, n=300, seed=2)
    source = open_can_source(
        f"virtual:{virtual_channel}", board.profile, bus_options={"receive_own_messages": True}
    )
    got = []
    deadline = time.monotonic() + 1.0
    try:
        for block in source.blocks():
            got.append(block.wrench)
            if time.monotonic() > deadline:
                break
    finally:
        source.close()
        board.stop()
    w = np.concatenate(got)[:, 0]
    whole = ~np.isnan(w).any(axis=1)
    assert len(w) >= 50 and whole.mean() >= 0.9, (len(w), whole.mean())
    assert source.stats.requests <= len(w) + 5  # one poll a sample
