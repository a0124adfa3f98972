"""The live ATI poller and late replies (issue 29: 1.2 kHz on a loaded host).

The poller never polls a board that still owes a reply; the assembler keys each reply by its
own board's poll. So a reply that comes after other boards' next polls lands in the sample
it was asked for (or is dropped as late), never in a later one, and a board that stopped
answering costs its own samples only.
"""

from __future__ import annotations

import time
from pathlib import Path

import can
import numpy as np
import pytest

from hapticdesk.canbus.config_reader import can_config
from hapticdesk.canbus.emulator import CanEmulator
from hapticdesk.canbus.frame_encoder import FrameEncoder
from hapticdesk.canbus.frames import FrameArray
from hapticdesk.canbus.source import open_can_source

PER_SAMPLE = 12  # four polls, then each board's two reply frames (FrameEncoder's order)
BR = 3  # the last board: its poll is frame 3 of a sample, its replies frames 10 and 11


def late_reply(frames: FrameArray, board: int, asked: int, skipped: int) -> FrameArray:
    """``frames`` with ``board``'s reply to sample ``asked`` coming after the other boards'
    polls of sample ``asked + skipped``, and that board left out of the rounds between (as
    the poller leaves out a board that owes a reply)."""
    order = []
    late = [asked * PER_SAMPLE + 4 + 2 * board + j for j in (0, 1)]
    for i in range(len(frames) // PER_SAMPLE):
        base = i * PER_SAMPLE
        polls = [base + b for b in range(4)]
        replies = [base + 4 + j for j in range(8)]
        if asked < i <= asked + skipped:  # not polled, so no reply
            polls.remove(base + board)
            replies = [r for r in replies if r not in (base + 4 + 2 * board, base + 5 + 2 * board)]
        if i == asked:
            replies = [r for r in replies if r not in late]
        order += polls + (late if i == asked + skipped else []) + replies
    return frames.take(np.array(order))


@pytest.fixture
def polled(ati_desk, make_samples):
    profile, config = ati_desk
    t, wrench = make_samples(40, 4, seed=3)
    encoder = FrameEncoder(config, profile)
    return profile, config, encoder, wrench, encoder.encode(t, wrench, polls=True)


@pytest.mark.parametrize("chunks", [1, 7, 40])
def test_a_late_reply_lands_in_the_sample_it_was_asked_for(polled, run_assembler, chunks):
    profile, config, encoder, wrench, frames = polled
    stream = late_reply(frames, BR, asked=5, skipped=1)
    _, got, asm = run_assembler(profile, config, stream, encoder.calibrations, chunks=chunks)
    assert len(got) == 40
    # sample 5 is whole, board br's reply in it; br was not polled for sample 6: NaN there
    np.testing.assert_allclose(got[5], wrench[5], atol=0.05)
    assert np.isnan(got[6, BR]).all() and not np.isnan(got[6, :BR]).any()
    whole = ~np.isnan(got).any(axis=(1, 2))
    assert whole.sum() == 39 and asm.stats.duplicates == 0 and asm.stats.late == 0


@pytest.mark.parametrize("chunks", [1, 9])
def test_a_reply_later_than_its_sample_is_dropped_never_moved(polled, run_assembler, chunks):
    """Three rounds later its sample was given out: the reply is dropped as late, not put
    in the sample of the round it came in (before, it was: sample 8 got sample 5's br)."""
    profile, config, encoder, wrench, frames = polled
    stream = late_reply(frames, BR, asked=5, skipped=3)
    _, got, asm = run_assembler(profile, config, stream, encoder.calibrations, chunks=chunks)
    assert len(got) == 40 and asm.stats.late == 2 and asm.stats.duplicates == 0
    assert np.isnan(got[5:9, BR]).all()
    near = np.abs(got[:, BR] - wrench[5, BR]).max(axis=1) < 0.05
    assert not near.any()  # sample 5's reading of br is in no sample


def test_a_round_without_the_first_polled_board_is_still_a_sample(polled, run_assembler):
    profile, config, encoder, wrench, frames = polled
    stream = late_reply(frames, 0, asked=10, skipped=1)  # fl, polled first, owes a reply
    _, got, asm = run_assembler(profile, config, stream, encoder.calibrations)
    assert len(got) == 40 and asm.stats.duplicates == 0 and asm.stats.late == 0
    np.testing.assert_allclose(got[10], wrench[10], atol=0.05)
    assert np.isnan(got[11, 0]).all()
    np.testing.assert_allclose(got[11, 1:], wrench[11, 1:], atol=0.05)


def test_a_board_that_stopped_answering_does_not_slow_the_others(
    ati_desk, profile_text, make_samples, virtual_channel
):
    """Board br answers its calibration but no poll (its recording is NaN: no reply). The
    poller waits for it once, then polls the others at the desk's rate."""
    profile, _ = ati_desk
    profile = profile_text(
        Path(str(profile.path)).read_text().replace("sample_rate_hz: 1200", "sample_rate_hz: 200"),
        "ati-200.yaml",
    )
    t, wrench = make_samples(2000, 4, seed=4, rate=200.0)
    wrench[:, BR] = np.nan
    board_bus = can.Bus(interface="virtual", channel=virtual_channel)
    emulator = CanEmulator(FrameEncoder(can_config(profile), profile), t, wrench, board_bus)
    thread = emulator.start()
    source = open_can_source(f"virtual:{virtual_channel}", profile)
    got = []
    start = time.monotonic()
    try:
        for block in source.blocks():
            got.append(block.wrench)
            if time.monotonic() - start > 1.5:
                break
    finally:
        wall = time.monotonic() - start
        source.close()
        emulator.stop()
        thread.join(2)
        board_bus.shutdown()
    w = np.concatenate(got)
    assert np.isnan(w[:, BR]).all()
    others_whole = ~np.isnan(w[:, :BR]).any(axis=(1, 2))
    assert others_whole.mean() >= 0.99 and source.stats.duplicates == 0
    # waiting for br every round (0.1 s) would give under 15 samples/s
    assert len(w) / wall >= 60, len(w) / wall


def run_poller(rate: float, stalls: dict[int, float], seconds: float) -> tuple[list[float], int]:
    """A poller of one board that answers every poll at once, its host stalled for
    ``stalls[i]`` seconds as it sends round ``i``: the rounds' times and the rounds it skipped."""
    import threading
    from types import SimpleNamespace

    from hapticdesk.canbus import ati_netcanoem as ati
    from hapticdesk.canbus.ati_bus import AtiBoards
    from hapticdesk.canbus.config import AtiSensor

    closing = threading.Event()
    sent: list[float] = []
    reply = SimpleNamespace(arbitration_id=ati.frame_id(0x20, ati.OP_GAUGES_B), data=b"\0" * 6)

    def send_poll(ident: int) -> None:
        time.sleep(stalls.get(len(sent), 0.0))
        sent.append(time.monotonic())

    def receive(timeout_s: float) -> None:
        while boards._heard[0] < len(sent):  # the board's reply, come at once
            boards.saw(reply)

    boards = AtiBoards(
        {"fl": AtiSensor(0x20)}, rate, spec="test", send_poll=send_poll, receive=receive,
        closing=closing,
    )  # fmt: skip
    boards.start_polling()
    time.sleep(seconds)
    closing.set()  # as the source does when it closes: the poller ends, joined below
    boards.stop_polling()
    assert not boards._poller.is_alive()
    return sent, boards.skipped_rounds


def test_a_poller_woken_late_polls_the_rounds_it_missed():
    """A host that stalls the poller 3 ms (three rounds at 1 kHz) costs no sample: the
    rounds missed are polled back to back after it (each sample at its real time); a
    30 ms stall's rounds are skipped and counted, and the clock keeps its phase."""
    rate = 1000.0
    sent, skipped = run_poller(rate, {200: 0.003, 500: 0.03}, seconds=0.9)
    t = np.array(sent)
    due = (t[-1] - t[0]) * rate + 1  # the rounds due while it ran
    # every round due was polled or counted skipped (a loaded host may stall it more)
    assert abs(len(t) + skipped - due) <= 3, (len(t), skipped, due)
    assert skipped >= 28, skipped  # the 30 ms stall's rounds (a loaded host's own add more)
    gaps = np.diff(t) * rate
    # after the 3 ms stall, its three rounds came back to back
    assert (gaps[200:204] < 0.5).sum() >= 2, gaps[198:206]
