"""The board's clock into sample times: wrap-around, losses, resets, garbled stamps, and gaps
kept as gaps for the estimator to flag."""

from __future__ import annotations

import numpy as np
import pytest

from hapticdesk.boards.decoder import BoardDecoder
from hapticdesk.boards.hello import BoardHello
from hapticdesk.boards.lines import OUT_OF_SEQUENCE, REPEAT
from hapticdesk.boards.settings import serial_settings
from hapticdesk.errors import ConfigError
from hapticdesk.estimator import ContactEstimator
from hapticdesk.estimator.contacts import FLAG_GAP

from .board_stream import SCALE, ZERO, cells_desk, counts, hello_line, sample_lines

CHANNELS = ("fl_fz", "fr_fz", "bl_fz", "br_fz")


@pytest.fixture
def desk(tmp_path):
    return cells_desk(
        tmp_path, extra=f"serial: {{scale: {SCALE}, zero: {ZERO}, simultaneous: true}}\n"
    )


def feed(dec: BoardDecoder, lines: list[str], host_t: float = 0.0):
    return dec.push([(host_t, ("\n".join(lines) + "\n").encode())])


def ones(n: int) -> np.ndarray:
    return counts(np.full((n, 4), 100.0))


def test_microsecond_stamps_wrap_without_a_reset(desk):
    hello = BoardHello(1000, CHANNELS, stamp="us", checksum_required=True)
    rng = np.random.default_rng(1)
    n = 3000
    board_us = 2**32 - 1_000_000 + np.arange(n) * 1000 + rng.integers(-30, 30, n)  # wraps at 1 s
    keep = np.ones(n, bool)
    keep[[500, 1700, 1701, 1702]] = False  # four lines never arrive
    dec = BoardDecoder(desk, serial_settings(desk, "/dev/null"))
    lines = sample_lines(np.mod(board_us, 2**32)[keep], ones(n)[keep])
    blocks = [feed(dec, [hello_line(hello)], 0.0)]
    blocks += [feed(dec, lines[i : i + 100], 0.1 * (i // 100)) for i in range(0, len(lines), 100)]
    t = np.concatenate([b.t for b in blocks])
    # the board's clock, unwrapped, and nothing else: no reset at the wrap
    np.testing.assert_allclose(t, (board_us[keep] - board_us[0]) * 1e-6, atol=1e-9)
    assert dec.stats.resets == 0 and dec.stats.lost == 4 and dec.stats.loss_runs == 2


def test_a_reset_is_survived_after_a_real_gap(desk):
    hello = BoardHello(1000, CHANNELS, checksum_required=True)
    dec = BoardDecoder(desk, serial_settings(desk, "/dev/null"))
    before = feed(dec, [hello_line(hello), *sample_lines(np.arange(5000, 5500), ones(500))], 10.0)
    # the board reboots: its sequence starts again from 0, 2.5 s later (no hello seen)
    after = feed(dec, sample_lines(np.arange(0, 500), ones(500)), 12.5)
    assert dec.stats.resets == 1 and dec.stats.samples == 1000 and dec.stats.lost == 0
    step = after.t[0] - before.t[-1]
    assert step == pytest.approx(2.5)  # the host's clock measured the reboot
    np.testing.assert_allclose(np.diff(after.t), 0.001)
    notice = next(n for n in dec.stats.notices if n.kind == "reset")
    assert (
        "the stamp jumped from 5499 to 0" in notice.message
        and "after a gap of 2.500 s" in notice.message
    )
    assert "1 board resets" in " ".join(dec.stats.summary())


def test_a_quick_reset_is_still_a_gap_the_estimator_sees(desk):
    """A board that restarts within a few milliseconds lost samples nobody knows: the new
    epoch starts beyond max_gap_s, so the estimator restarts its filters there."""
    hello = BoardHello(1000, CHANNELS, checksum_required=True)
    dec = BoardDecoder(desk, serial_settings(desk, "/dev/null"))
    lines = [hello_line(hello), *sample_lines(np.arange(1500), ones(1500))]
    lines += [hello_line(hello), *sample_lines(np.arange(1500), ones(1500))]  # said hello again
    block = feed(dec, lines, 0.0)
    assert dec.stats.resets == 1  # once, though both the hello and the stamp said it
    steps = np.diff(block.t)
    assert steps.max() > desk.estimation.max_gap_s
    contacts = ContactEstimator(desk).push(block.t, block.channels)
    gaps = np.flatnonzero(contacts.flags & FLAG_GAP)
    assert gaps.tolist() == [1500]


def test_a_hello_the_host_asked_for_is_no_reset(desk):
    hello = BoardHello(1000, CHANNELS, checksum_required=True)
    dec = BoardDecoder(desk, serial_settings(desk, "/dev/null"))
    feed(dec, [hello_line(hello), *sample_lines(np.arange(100), ones(100))])
    dec.reconnected()  # the port opened again, `?` sent: the board answers
    block = feed(dec, [hello_line(hello), *sample_lines(np.arange(100, 200), ones(100))], 0.5)
    assert dec.stats.resets == 0 and dec.stats.reconnects == 1
    assert block.t[0] - 0.099 == pytest.approx(0.5)  # a new epoch all the same: a gap


def test_a_garbled_stamp_without_checksum_is_dropped_not_a_reset(desk):
    hello = BoardHello(1000, CHANNELS)  # no checksum
    dec = BoardDecoder(desk, serial_settings(desk, "/dev/null"))
    stamps = np.arange(1000, 1100)
    stamps[40] = 9040  # a digit hit: 8 s ahead of what the host saw pass
    stamps[70] = stamps[69]  # printed twice (and 1070 never)
    block = feed(
        dec, [hello_line(hello, checksum=False), *sample_lines(stamps, ones(100), checksum=False)]
    )
    assert dec.stats.resets == 0 and len(block.t) == 98
    assert dec.stats.garbled == {OUT_OF_SEQUENCE: 1, REPEAT: 1}
    assert dec.stats.lost == 2  # the garbled line's sample, and 1070


def test_a_jump_in_the_last_line_waits_for_the_next(desk):
    hello = BoardHello(1000, CHANNELS, checksum_required=True)
    dec = BoardDecoder(desk, serial_settings(desk, "/dev/null"))
    first = feed(dec, [hello_line(hello), *sample_lines([10, 11, 12, 0], ones(4))])
    assert len(first.t) == 3  # stamp 0 after 12: a reset or a garbled line? The next says.
    second = feed(dec, sample_lines([1, 2], ones(2)), 1.0)
    assert len(second.t) == 3 and dec.stats.resets == 1


def test_another_board_after_a_reset_stops_the_source(desk):
    hello = BoardHello(1000, CHANNELS, checksum_required=True)
    dec = BoardDecoder(desk, serial_settings(desk, "/dev/null"))
    feed(dec, [hello_line(hello), *sample_lines(np.arange(10), ones(10))])
    other = BoardHello(500, CHANNELS, checksum_required=True)
    with pytest.raises(
        ConfigError, match="the board changed: it said .* rate=1000 .* now .* rate=500"
    ):
        feed(dec, [hello_line(other)])


def test_a_board_that_pauses_leaves_a_gap_the_estimator_flags(desk):
    hello = BoardHello(1000, CHANNELS, stamp="us", checksum_required=True)
    dec = BoardDecoder(desk, serial_settings(desk, "/dev/null"))
    board_us = np.arange(3000) * 1000
    board_us[2000:] += 200_000  # the board stopped sampling for 0.2 s
    block = feed(dec, [hello_line(hello), *sample_lines(board_us, ones(3000))])
    assert len(block.t) == 3000  # nothing invented for the pause
    assert dec.stats.gaps == 1 and dec.stats.lost == 200
    contacts = ContactEstimator(desk).push(block.t, block.channels)
    assert np.flatnonzero(contacts.flags & FLAG_GAP).tolist() == [2000]
