"""Channels read at their own moments make a false moment while the force changes; aligned to
the sample's time before the map, the centre of pressure is the one read all at once."""

from __future__ import annotations

import numpy as np
import pytest

from hapticdesk.boards.alignment import ChannelAligner
from hapticdesk.boards.decoder import BoardDecoder
from hapticdesk.boards.hello import BoardHello
from hapticdesk.boards.settings import serial_settings
from hapticdesk.sim import SimEffects

from .board_stream import SCALE, ZERO, cells_desk, counts, hello_line, sample_lines, simulated_cells

SCENE = """\
name: rise
desk: kitamura2017
units: cm
quiet_s: 1.5
tail_s: 0.5
human: {tap_peak_n: [5, 5]}
timeline:
  - tap: {point: [-20, 12]}
  - press: {point: [25, -15], peak_n: 12}
"""
#: no noise and no quantisation: what is left is the timing alone
IDEAL_SENSORS = SimEffects(noise=False, drift=False, quantisation=False)


def test_a_ramp_read_apart_is_the_same_on_every_channel_once_aligned():
    t = np.arange(50) * 1e-3
    offsets = np.array([0.0, 229.0, 458.0, 687.0])
    read = 100.0 * (t[:, None] + offsets * 1e-6)  # 100 N/s read at each channel's moment
    aligner = ChannelAligner(4)
    fresh = np.zeros(50, bool)
    fresh[0] = True
    out = np.concatenate(
        [aligner.align(t[s], read[s], np.tile(offsets, (len(t[s]), 1)), fresh[s]) for s in
         (slice(0, 7), slice(7, 8), slice(8, 50))]
    )  # fmt: skip
    np.testing.assert_allclose(out[1:], np.repeat(100.0 * t[1:, None], 4, axis=1), atol=1e-12)
    assert aligner.unaligned == 1  # the first: nothing earlier to interpolate from


def centre_of_pressure(desk, channels: np.ndarray) -> np.ndarray:
    """(k, 2) x, y of the load added since the first half second (the desk's weight off)."""
    w = channels @ desk.wrench_map().T
    w = w - w[:500].mean(axis=0)
    return np.column_stack([-w[:, 4] / w[:, 2], w[:, 3] / w[:, 2]])


def decode(desk, hello: BoardHello, lines: list[str]) -> np.ndarray:
    dec = BoardDecoder(desk, serial_settings(desk, "/dev/null"))
    return dec.push([(0.0, ("\n".join([hello_line(hello), *lines]) + "\n").encode())]).channels


def cop_errors(desk, cells, channels: np.ndarray) -> np.ndarray:
    at_once = (counts(cells.fz[:, :, 0]) - ZERO) * SCALE  # every cell read at the stamp
    pressed = (at_once @ desk.wrench_map().T)[:, 2] - (at_once @ desk.wrench_map().T)[
        :500, 2
    ].mean()
    err = centre_of_pressure(desk, channels) - centre_of_pressure(desk, at_once)
    return np.hypot(*err[pressed > 2.0].T)


def test_an_ads1256_reading_four_bridges_in_turn(tmp_path):
    """1 kHz, the four bridges 250 µs apart: read as if simultaneous, a tap's centre of
    pressure is off by millimetres while the force rises; aligned, by micrometres."""
    cells = simulated_cells(tmp_path, SCENE, rate=1000, oversample=4, effects=IDEAL_SENSORS)
    desk = cells_desk(tmp_path, extra=f"serial: {{scale: {SCALE}, zero: {ZERO}}}\n")
    names = tuple(desk.channel_names())
    lines = sample_lines(np.arange(len(cells.t)), counts(cells.fz[:, np.arange(4), np.arange(4)]))
    aligned = decode(desk, BoardHello(1000, names, offsets_us=(0, 250, 500, 750)), lines)
    as_read = decode(desk, BoardHello(1000, names, offsets_us=(0, 0, 0, 0)), lines)
    err_aligned, err_read = cop_errors(desk, cells, aligned), cop_errors(desk, cells, as_read)
    assert err_read.max() > 2e-3 and np.percentile(err_read, 95) > 0.5e-3
    assert err_aligned.max() < 0.1e-3


@pytest.mark.parametrize("seed", [0, 1])
def test_four_hx711_on_their_own_clocks(tmp_path, seed):
    """80 Hz, each chip converting on its own clock (its reading anywhere in the 12.5 ms
    after the stamp, drifting from line to line): the board prints each line's offsets."""
    oversample = 16
    cells = simulated_cells(tmp_path, SCENE, rate=80, oversample=oversample, effects=IDEAL_SENSORS)
    desk = cells_desk(tmp_path, rate=80, extra=f"serial: {{scale: {SCALE}, zero: {ZERO}}}\n")
    n = len(cells.t)
    rng = np.random.default_rng(seed)
    rates = 1 + rng.uniform(-0.03, 0.03, 4)  # four oscillators a few % apart
    phase = np.mod(np.arange(n)[:, None] * rates * oversample + rng.integers(0, 16, 4), oversample)
    k = np.floor(phase).astype(int)
    readings = counts(np.take_along_axis(cells.fz, k[:, :, None], axis=2)[:, :, 0])
    offsets_us = k * 1e6 / (80 * oversample)
    hello = BoardHello(80, tuple(desk.channel_names()), stamp="us", offsets_per_line=True)
    stamps = np.rint(cells.t * 1e6).astype(np.int64)
    lines = sample_lines(stamps, readings, offsets_us)
    aligned = decode(desk, hello, lines)
    as_read = decode(desk, hello, sample_lines(stamps, readings, np.zeros_like(offsets_us)))
    err_aligned, err_read = cop_errors(desk, cells, aligned), cop_errors(desk, cells, as_read)
    # at 80 Hz a tap is a few samples: interpolation leaves more than at 1 kHz, yet the
    # false moment of reading the legs up to 12 ms apart is mostly gone
    assert np.percentile(err_aligned, 95) < 0.35 * np.percentile(err_read, 95)
    assert np.median(err_aligned) < 0.35 * np.median(err_read)
