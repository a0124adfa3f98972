"""The ATI boards' readings computed side by side (AtiReadings, the live path's) give each
board exactly what its own AtiReading gives: channels bit for bit, invalid samples, status."""

from __future__ import annotations

import numpy as np

from hapticdesk.canbus import ati_netcanoem as ati
from hapticdesk.canbus.decoding import AtiReading, AtiReadings, DeskDecoding, SignalReading


def test_side_by_side_equals_board_by_board():
    rng = np.random.default_rng(29)
    # boards in a desk's order, their columns not in board order (as with other readings between)
    readings = [(s, AtiReading(f"b{s}", first, ati.example_calibration(s))) for s, first in
                [(0, 14), (1, 0), (3, 7)]]  # fmt: skip
    batch = AtiReadings(readings)
    statuses = [0, 0, 0, 1, 2, 1 << 6, 1 << 15, (1 << 14) | (1 << 0)]
    flagged = 0
    for n in [0, 1, 5, 12, 40]:
        table = rng.integers(-32768, 32768, (n, 21)).astype(float)
        for _, reading in readings:
            table[:, reading.columns[0]] = rng.choice(statuses, n)
        table[rng.random(table.shape) < 0.05] = np.nan  # lost frames
        wrench = np.full((n, 4, 6), -1.0)
        invalid = np.zeros((n, 4), dtype=bool)
        counts: list[dict[str, int]] = [{} for _ in range(4)]
        batch.channels(table, wrench, invalid, counts)
        for s, reading in readings:
            w, bad, status = reading.channels(table)
            np.testing.assert_array_equal(wrench[:, s], w)  # (NaN where NaN)
            np.testing.assert_array_equal(invalid[:, s], bad)
            assert list(counts[s].items()) == list(status.items())
            flagged += int(bad.sum())
        assert (wrench[:, 2] == -1.0).all() and not invalid[:, 2].any() and counts[2] == {}
    assert flagged > 0  # critical bits were seen, and voided those samples


def test_no_boards_leaves_everything():
    wrench = np.zeros((3, 1, 6))
    AtiReadings([]).channels(np.zeros((3, 2)), wrench, np.zeros((3, 1), bool), [{}])
    assert not wrench.any()


def test_a_desk_of_boards_and_signal_sensors_reads_each_its_own_way():
    """A desk whose sensors mix ATI boards and database signals (the accelerometer's, or a
    sensor with a DBC): DeskDecoding.channels gives every reading what it gives alone."""
    ati_a = AtiReading("a", 0, ati.example_calibration(1))
    signals = SignalReading("s", {0: 7, 2: 8, 5: 9}, [("s.status", 10)])
    ati_b = AtiReading("b", 11, ati.example_calibration(2))
    decoding = DeskDecoding([], [ati_a, signals, ati_b], 18, {}, frozenset(), None)
    rng = np.random.default_rng(7)
    table = rng.integers(-2000, 2000, (30, 18)).astype(float)
    table[:, [0, 11]] = rng.choice([0, 0, 1 << 3, 1 << 8], (30, 2))
    table[:, 10] = rng.choice([0, 0, 0, 1], 30)
    table[rng.random(table.shape) < 0.05] = np.nan
    wrench, invalid, counts = decoding.channels(table)
    for s, reading in enumerate(decoding.readings):
        w, bad, status = reading.channels(table)
        np.testing.assert_array_equal(wrench[:, s], w)
        np.testing.assert_array_equal(invalid[:, s], bad)
        assert counts[s] == status
    assert invalid[:, 1].any() and invalid[:, [0, 2]].any()  # each kind's status was seen
