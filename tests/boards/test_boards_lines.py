"""The line format (docs/serial.md): the hello, the checksum, every kind of garbled line named
and counted, memory bounded by an endless line, and the same samples whatever the split."""

from __future__ import annotations

import re

import numpy as np
import pytest

from hapticdesk.boards.decoder import BoardDecoder
from hapticdesk.boards.hello import BoardHello, checksum, parse_hello, with_checksum
from hapticdesk.boards.lines import MAX_LINE_BYTES, REASONS, LineSplitter
from hapticdesk.boards.settings import serial_settings
from hapticdesk.errors import ConfigError

from .board_stream import SCALE, ZERO, cells_desk, counts, hello_line, sample_lines

CHANNELS = ("fl_fz", "fr_fz", "bl_fz", "br_fz")


@pytest.fixture
def desk(tmp_path):
    return cells_desk(tmp_path, extra=f"serial: {{scale: {SCALE}, zero: {ZERO}}}\n")


def decoder(desk, spec: str = "/dev/null") -> BoardDecoder:
    return BoardDecoder(desk, serial_settings(desk, spec))


def stream(lines: list[str]) -> bytes:
    return ("\n".join(lines) + "\n").encode()


HELLO = BoardHello(1000, CHANNELS, offsets_us=(0, 0, 0, 0), checksum_required=True)


def test_checksum_is_nmea_xor():
    # NMEA's own example sentence: $GPGLL,5300.97914,N,00259.98174,E,125926,A*28
    assert checksum(b"GPGLL,5300.97914,N,00259.98174,E,125926,A") == 0x28
    assert (
        with_checksum("12,1,2")
        == f"12,1,2*{ord('1') ^ ord('2') ^ ord(',') ^ ord('1') ^ ord(',') ^ ord('2'):02X}"
    )


def test_hello_round_trip_and_errors():
    hello = BoardHello(
        80, CHANNELS, stamp="us", offsets_per_line=True, checksum_required=True, board="hx711"
    )
    assert parse_hello(hello.text(), "x") == hello
    assert hello.text() == (
        "@hapticdesk/1 rate=80 channels=fl_fz,fr_fz,bl_fz,br_fz stamp=us offsets=line "
        "checksum=xor board=hx711"
    )
    for text, needle in [
        ("@hapticdesk/1 channels=a", "missing `rate=`"),
        ("@hapticdesk/1 rate=fast channels=a", "`rate` must be a number"),
        ("@hapticdesk/1 rate=80 channels=a,b offsets_us=0", "one offset per channel (2)"),
        ("@hapticdesk/1 rate=80 channels=a offset_us=0", "unknown key `offset_us`"),
        ("@hapticdesk/1 rate=80 channels=a stamp=ms", "`stamp` must be one of seq, us"),
        ("@hapticdesk/2 rate=80 channels=a", "starts with `@hapticdesk/1`"),
    ]:
        with pytest.raises(ConfigError, match=re.escape(needle)):
            parse_hello(text, "port line 1")


def test_samples_in_the_profiles_order_scaled(desk):
    values = counts(np.array([[10.0, 20.0, 30.0, 40.0], [11.0, 21.0, 31.0, 41.0]]))
    block = decoder(desk).push([(0.0, stream([hello_line(HELLO), *sample_lines([5, 6], values)]))])
    np.testing.assert_allclose(block.t, [0.0, 0.001])
    np.testing.assert_allclose(block.channels, [[10, 20, 30, 40], [11, 21, 31, 41]], atol=SCALE)


@pytest.mark.parametrize(
    ("line", "reason"),
    [
        ("7,1,2,3,4*00", "checksum does not match"),
        ("7,1,2,3,4", "no checksum (the hello says checksum=xor)"),
        ("7,1,2,3,4*0", "a `*` not followed by two hex digits at the end"),
        (with_checksum("7,1,2,3"), "wrong number of fields"),
        (with_checksum("7,1,2,3,4,5"), "wrong number of fields"),
        (with_checksum("7,1,2,x,4"), "a character that is not part of a number"),
        (with_checksum("7,1,2,1-2,4"), "a field that is not a number"),
        (with_checksum("7,1,2,1e999,4"), "a field that is not a number"),
        (with_checksum("7.5,1,2,3,4"), "the stamp is not a whole number"),
        (with_checksum("99999999999,1,2,3,4"), "the stamp is not a whole number"),
        (with_checksum("hello world"), "neither a sample"),
        ("7,1,\x012,3,4", "bytes that are not text"),
    ],
)
def test_each_garbled_line_is_named_and_counted(desk, line, reason):
    good = sample_lines(np.arange(6), counts(np.ones((6, 4))))
    lines = [hello_line(HELLO), *good[:3], line, *good[4:]]
    dec = decoder(desk)
    block = dec.push([(0.0, stream(lines))])
    assert len(block.t) == 5
    stats = dec.stats
    assert stats.garbled_lines == 1 and [REASONS[c] for c in stats.garbled] == [
        next(r for r in REASONS.values() if r.startswith(reason))
    ]
    told = [n.message for n in stats.notices if n.kind == "garbled"]
    assert len(told) == 1 and "line 5: garbled" in told[0]
    # the garbled line's sample is counted lost, and its time left empty
    assert stats.lost == 1 and np.diff(block.t).max() == pytest.approx(0.002)
    assert any(f"garbled lines dropped ({reason}" in x for x in stats.summary())


def test_comments_and_lines_before_the_hello_are_not_samples(desk):
    lines = [
        "1,2,3,4,5",
        "# booting",
        hello_line(HELLO),
        *sample_lines([1], counts(np.ones((1, 4)))),
    ]
    dec = decoder(desk)
    assert len(dec.push([(0.0, stream(lines))]).t) == 1
    assert (dec.stats.before_hello, dec.stats.comments, dec.stats.garbled_lines) == (1, 1, 0)


def test_an_empty_field_is_a_missing_reading(desk):
    lines = [hello_line(HELLO), with_checksum("1,1000,,1000,1000")]
    dec = decoder(desk)
    block = dec.push([(0.0, stream(lines))])
    assert np.isnan(block.channels[0, 1]) and np.isfinite(block.channels[0, [0, 2, 3]]).all()
    assert dec.stats.missing_values == 1


def test_an_endless_line_costs_no_memory_and_is_counted(desk):
    dec = decoder(desk)
    dec.push([(0.0, stream([hello_line(HELLO)]))])
    junk = bytes(range(32, 127)) * 700  # 66 kB without a newline, 1 kB at a time
    for i in range(0, len(junk), 1024):
        dec.push([(0.0, junk[i : i + 1024])])
        assert len(dec._splitter._partial) <= MAX_LINE_BYTES
    block = dec.push([(0.0, b"\n" + stream(sample_lines([1, 2], counts(np.ones((2, 4))))))])
    assert len(block.t) == 2
    assert dec.stats.garbled == {min(REASONS): 1}  # one overlong line
    assert "longer than 2048 bytes" in dec.stats.notices[-1].message


def test_the_same_samples_whatever_the_split(desk):
    """Chunk invariance (STYLE.md 8): any split of the bytes gives the same samples, counts
    and times."""
    rng = np.random.default_rng(5)
    n = 400
    values = counts(rng.normal(50, 5, (n, 4)))
    stamps = np.arange(n) + 1000
    lines = sample_lines(stamps, values, checksum=True)
    for i in rng.choice(n, 12, replace=False):  # garbled and dropped lines
        lines[i] = lines[i][:-1] + ("0" if lines[i][-1] != "0" else "1")
    del lines[100:103]
    data = stream([hello_line(HELLO), *lines])
    whole = decoder(desk)
    ref = whole.push([(0.0, data)], final=True)
    for _ in range(5):
        cuts = np.sort(rng.choice(len(data), 40, replace=False))
        parts = np.split(np.frombuffer(data, np.uint8), cuts)
        dec = decoder(desk)
        blocks = [dec.push([(0.0, p.tobytes())]) for p in parts] + [dec.push([], final=True)]
        np.testing.assert_array_equal(np.concatenate([b.t for b in blocks]), ref.t)
        np.testing.assert_array_equal(np.concatenate([b.channels for b in blocks]), ref.channels)
        assert dec.stats.summary() == whole.stats.summary()
    assert whole.stats.garbled_lines == 12 and whole.stats.lost == 15


def test_line_numbers_and_arrival_times_follow_the_reads():
    splitter = LineSplitter()
    batch = splitter.feed([(1.0, b"a\r\nbb"), (2.0, b"b\n"), (3.0, b"\nccc")])
    assert [batch.text(i) for i in range(len(batch))] == [b"a", b"bbb", b""]
    assert batch.numbers.tolist() == [1, 2, 3] and batch.host_t.tolist() == [1.0, 2.0, 3.0]
    batch = splitter.feed([(4.0, b"\n")])
    assert batch.text(0) == b"ccc" and batch.numbers.tolist() == [4]


def test_a_hello_whose_checksum_fails_is_garbled_not_taken(desk):
    text = hello_line(HELLO)
    dec = decoder(desk)
    block = dec.push(
        [(0.0, stream([text[:-2] + "00", *sample_lines([1], counts(np.ones((1, 4))))]))]
    )
    assert dec.hello is None and len(block.t) == 0
    assert dec.stats.garbled_lines == 1 and dec.stats.before_hello == 1
    dec.push([(0.0, stream([text]))])
    assert dec.hello == HELLO
