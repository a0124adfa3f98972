"""Hostile bytes on the line: whatever comes, the decoder never crashes, never gives a time
that does not increase, keeps its memory bounded, and every sample it gives is one a good
line carried."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hapticdesk.boards.decoder import BoardDecoder
from hapticdesk.boards.hello import BoardHello
from hapticdesk.boards.lines import MAX_LINE_BYTES
from hapticdesk.boards.settings import serial_settings
from hapticdesk.errors import ConfigError

from .board_stream import cells_desk, counts, hello_line, sample_lines

HELLO = BoardHello(1000, ("fl_fz", "fr_fz", "bl_fz", "br_fz"), offsets_us=(0, 250, 500, 750),
                   checksum_required=True)  # fmt: skip
N = 300
VALUES = counts(np.random.default_rng(0).normal(50, 2, (N, 4)))
GOOD = [(x + "\n").encode() for x in sample_lines(np.arange(N), VALUES)]


@pytest.fixture(scope="module")
def desk(tmp_path_factory):
    return cells_desk(tmp_path_factory.mktemp("fuzz"), extra="serial: {scale: 5.0e-5}\n")


pieces = st.one_of(
    st.sampled_from(range(N)),  # a good line, by its number
    st.binary(max_size=80),  # noise
    st.sampled_from([b"\n", b"\r\n", b"*", b",", b"@hapticdesk/1", b"#", b"\x00" * 30]),
)


@settings(
    max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(stream=st.lists(pieces, max_size=60), cuts=st.lists(st.integers(0, 4000), max_size=8))
def test_any_bytes_any_split(desk, stream, cuts):
    data = (hello_line(HELLO) + "\n").encode()
    for piece in stream:
        data += GOOD[piece] if isinstance(piece, int) else piece
    decoder = BoardDecoder(desk, serial_settings(desk, "/dev/null"))
    edges = sorted({0, len(data), *[c % (len(data) + 1) for c in cuts]})
    blocks = []
    try:
        for a, b in zip(edges[:-1], edges[1:], strict=True):
            blocks.append(decoder.push([(0.0, data[a:b])]))
            assert len(decoder._splitter._partial) <= MAX_LINE_BYTES
        blocks.append(decoder.push([], final=True))
    except ConfigError as err:  # a garbled line that reads as another board's hello
        assert "hello" in str(err) or "the board changed" in str(err)
        return
    t = np.concatenate([b.t for b in blocks])
    channels = np.concatenate([b.channels for b in blocks])
    assert (np.diff(t) > 0).all()
    assert np.isfinite(t).all()
    # every sample is a good line's (its first channel is read at the stamp: never moved)
    sent = (VALUES[:, 0] * 5e-5)[None, :]
    assert (np.abs(channels[:, :1] - sent).min(axis=1) < 1e-9).all()
    stats = decoder.stats
    assert stats.samples == len(t)
