"""The ATI boards' readings computed side by side (AtiReadings, the live path's) give each
board exactly what its own AtiReading gives: channels bit for bit, invalid samples, status."""

from __future__ import annotations

import numpy as np

from hapticdesk.canbus import ati_netcanoem as ati
from hapticdesk.canbus.decoding import AtiReading, AtiReadings


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
