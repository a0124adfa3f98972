"""Bytes into lines, lines into samples: every line of a read at once, no loop per line.

:class:`LineSplitter` cuts the byte stream at newlines and keeps at most
:data:`MAX_LINE_BYTES` of an unfinished line (a board that never sends a newline costs no
memory: the rest of that line is skipped and counted). :func:`parse_lines` classifies the
lines of one read with array operations over the bytes (checksum by a running XOR, commas
and bad characters by running counts, the fields gathered into a fixed-width table and
converted at once) and gives the samples' stamps, values and offsets; a bad line gets a
reason code (:data:`REASONS`) and is never half-used.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from hapticdesk.boards.hello import MAX_OFFSET_US, MAX_STAMP_DIGITS, BoardHello

#: the longest line read (a sample of 64 channels with offsets fits); longer is garbled
MAX_LINE_BYTES = 2048
#: the longest field (a value or a stamp) in characters
MAX_FIELD_CHARS = 24

# what a line is
EMPTY, SAMPLE, HELLO, COMMENT, BEFORE_HELLO = 0, 1, 2, 3, 4
# why a line is garbled (dropped, counted, named)
OVERLONG = 10
NOT_TEXT = 11
CHECKSUM = 12
CHECKSUM_MISSING = 13
CHECKSUM_FORM = 14
UNKNOWN = 15
FIELDS = 16
CHARACTER = 17
NUMBER = 18
STAMP = 19
OFFSET = 20
REPEAT = 21  # (the clock's) the stamp repeats the previous sample's
OUT_OF_SEQUENCE = 22  # (the clock's) a lone stamp that fits neither neighbour
GARBLED = OVERLONG  # codes from here on are garbled lines

REASONS = {
    OVERLONG: f"longer than {MAX_LINE_BYTES} bytes",
    NOT_TEXT: "bytes that are not text",
    CHECKSUM: "checksum does not match",
    CHECKSUM_MISSING: "no checksum (the hello says checksum=xor)",
    CHECKSUM_FORM: "a `*` not followed by two hex digits at the end",
    UNKNOWN: "neither a sample (a digit first), a hello (@) nor a comment (#)",
    FIELDS: "wrong number of fields",
    CHARACTER: "a character that is not part of a number",
    NUMBER: "a field that is not a number",
    STAMP: f"the stamp is not a whole number of at most {MAX_STAMP_DIGITS} digits below `wrap`",
    OFFSET: f"an offset outside 0 to {MAX_OFFSET_US:g} µs",
    REPEAT: "the stamp repeats the previous sample's",
    OUT_OF_SEQUENCE: "a stamp that fits neither the line before nor the line after",
}

_TEXT = np.zeros(256, bool)  # printable ASCII and tab
_TEXT[32:127] = True
_TEXT[9] = True
_NUMBER_CHARS = np.zeros(256, bool)  # what a sample line's content may hold
_NUMBER_CHARS[[ord(c) for c in "0123456789+-.eE,"]] = True
_DIGIT = np.zeros(256, bool)
_DIGIT[ord("0") : ord("9") + 1] = True
_HEX = np.full(256, -1, np.int16)
for _i, _c in enumerate("0123456789ABCDEF"):
    _HEX[ord(_c)] = _i
    _HEX[ord(_c.lower())] = _i


@dataclass
class LineBatch:
    """Complete lines of one read: line ``i`` is ``buf[starts[i]:ends[i]]`` (without its
    ``\\r\\n``), numbered ``numbers[i]`` from the port's opening, arrived at host time
    ``host_t[i]`` (the read that brought its newline)."""

    buf: np.ndarray  # uint8
    starts: np.ndarray  # int64
    ends: np.ndarray  # int64
    numbers: np.ndarray  # int64
    host_t: np.ndarray
    #: (line number, its first bytes) of lines cut off for being too long
    overlong: list[tuple[int, bytes]] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.starts)

    def text(self, i: int) -> bytes:
        return self.buf[self.starts[i] : self.ends[i]].tobytes()

    def first_bytes(self) -> np.ndarray:
        """Each line's first byte (0 for an empty line)."""
        if not len(self.starts):
            return np.zeros(0, np.uint8)
        first = self.buf[np.minimum(self.starts, len(self.buf) - 1)]
        return np.where(self.ends > self.starts, first, 0)

    def take(self, index: slice) -> LineBatch:
        return LineBatch(
            self.buf, self.starts[index], self.ends[index], self.numbers[index], self.host_t[index]
        )


class LineSplitter:
    """Cuts a byte stream into lines; memory stays below :data:`MAX_LINE_BYTES` whatever
    comes (see the module docstring). The same lines come out whatever the reads' split."""

    def __init__(self) -> None:
        self._partial = b""
        self._skipping = False  # inside a line that was too long: drop up to its newline
        self.lines = 0  # lines ended so far

    def feed(self, chunks: list[tuple[float, bytes]]) -> LineBatch:
        """The lines completed by ``chunks`` ((host time, bytes) in arrival order)."""
        overlong: list[tuple[int, bytes]] = []
        data = self._partial + b"".join(c for _, c in chunks)
        buf = np.frombuffer(data, np.uint8)
        newlines = np.flatnonzero(buf == 10)
        start = 0
        if self._skipping and len(newlines):
            start = int(newlines[0]) + 1  # the end of the overlong line
            newlines = newlines[1:]
            self._skipping = False
            self.lines += 1
        elif self._skipping:
            self._partial = b""
            return self._empty(buf)
        tail = data[int(newlines[-1]) + 1 if len(newlines) else start :]
        if len(tail) > MAX_LINE_BYTES:
            overlong.append((self.lines + len(newlines) + 1, tail[:60]))
            self._skipping, tail = True, b""
        self._partial = tail
        starts = np.concatenate([[start], newlines[:-1] + 1]).astype(np.int64)
        ends = newlines.astype(np.int64)
        if not len(newlines):
            batch = self._empty(buf)
            batch.overlong = overlong
            return batch
        ends = ends - ((ends > starts) & (buf[np.maximum(ends - 1, 0)] == 13))  # \r\n
        # each line's arrival: the read that brought its newline
        sizes = np.array([len(c) for _, c in chunks], np.int64)
        bounds = len(data) - sizes.sum() + np.cumsum(sizes)  # end of each read in ``data``
        times = np.array([t for t, _ in chunks])
        host_t = times[np.minimum(np.searchsorted(bounds, newlines, "right"), len(times) - 1)]
        numbers = self.lines + 1 + np.arange(len(newlines), dtype=np.int64)
        self.lines += len(newlines)
        return LineBatch(buf, starts, ends, numbers, host_t, overlong)

    @staticmethod
    def _empty(buf: np.ndarray) -> LineBatch:
        none = np.zeros(0, np.int64)
        return LineBatch(buf, none, none, none, np.zeros(0))


@dataclass
class ParsedLines:
    """What each line of a batch is (:data:`SAMPLE`, :data:`HELLO`, a garbled reason, …),
    and the samples' ``stamps`` (m,), ``values`` (m, C) (NaN for an empty field) and
    per-line ``offsets`` (m, C) µs where the hello says ``offsets=line``. ``rows`` are the
    samples' line indices in the batch."""

    kind: np.ndarray  # (n,) int8
    rows: np.ndarray  # (m,) int64
    stamps: np.ndarray  # (m,) int64
    values: np.ndarray  # (m, C)
    offsets: np.ndarray | None  # (m, C)


def line_kinds(batch: LineBatch, checksum_required: bool) -> tuple[np.ndarray, np.ndarray]:
    """Each line's kind before its fields are read (EMPTY, SAMPLE for a digit first, HELLO,
    COMMENT, or a garbled reason) and where its content ends (before ``*HH``)."""
    buf, starts, ends = batch.buf, batch.starts, batch.ends
    n = len(starts)
    kind = np.full(n, SAMPLE, np.int8)
    if n == 0:
        return kind, ends
    length = ends - starts
    safe = np.minimum(starts, max(len(buf) - 1, 0))
    first = np.where(length > 0, buf[safe], 0)
    # a checksum: the last `*` of the line
    stars = np.flatnonzero(buf == 42)
    last_star = np.searchsorted(stars, ends) - 1
    star = np.where(last_star >= 0, stars[np.maximum(last_star, 0)] if len(stars) else 0, -1)
    has_star = (star >= starts) & (last_star >= 0)
    content_end = np.where(has_star, star, ends)
    xor = np.concatenate([[0], np.bitwise_xor.accumulate(buf)]) if len(buf) else np.zeros(1)
    computed = xor[content_end] ^ xor[starts]
    hi = _HEX[buf[np.minimum(star + 1, len(buf) - 1)]]
    lo = _HEX[buf[np.minimum(star + 2, len(buf) - 1)]]
    well_formed = has_star & (ends - star == 3) & (hi >= 0) & (lo >= 0)
    not_text = np.concatenate([[0], np.cumsum(~_TEXT[buf])]) if len(buf) else np.zeros(1)
    kind[first == ord("@")] = HELLO
    kind[first == ord("#")] = COMMENT
    kind[~_DIGIT[first] & (first != ord("@")) & (first != ord("#"))] = UNKNOWN
    if checksum_required:
        kind[~has_star & (kind != COMMENT)] = CHECKSUM_MISSING
    kind[well_formed & (computed != hi * 16 + lo)] = CHECKSUM
    kind[has_star & ~well_formed & (kind != COMMENT)] = CHECKSUM_FORM
    kind[(not_text[ends] - not_text[starts]) > 0] = NOT_TEXT
    kind[length > MAX_LINE_BYTES] = OVERLONG
    kind[length == 0] = EMPTY
    return kind, content_end


def parse_lines(batch: LineBatch, hello: BoardHello | None) -> ParsedLines:
    """Classify every line of ``batch`` and read its samples' fields (module docstring);
    ``hello`` None: no hello yet, so sample lines are :data:`BEFORE_HELLO`."""
    kind, content_end = line_kinds(batch, bool(hello and hello.checksum_required))
    n_values = len(hello.channels) if hello else 0
    if hello is None:
        kind[kind == SAMPLE] = BEFORE_HELLO
        return ParsedLines(kind, np.zeros(0, np.int64), np.zeros(0), np.zeros((0, 0)), None)
    buf, starts = batch.buf, batch.starts
    n_fields = hello.fields
    commas = np.flatnonzero(buf == 44)
    count = np.concatenate([[0], np.cumsum(buf == 44)])
    odd = np.concatenate([[0], np.cumsum(~_NUMBER_CHARS[buf])])
    sample = kind == SAMPLE
    kind[sample & (odd[content_end] - odd[starts] > 0)] = CHARACTER
    sample = kind == SAMPLE
    kind[sample & (count[content_end] - count[starts] != n_fields - 1)] = FIELDS
    rows = np.flatnonzero(kind == SAMPLE)
    # the fields of every sample line: (m, F) starts and ends
    first_comma = np.searchsorted(commas, starts[rows])
    at = commas[first_comma[:, None] + np.arange(n_fields - 1)] if n_fields > 1 else None
    f_start = np.column_stack([starts[rows]] + ([at + 1] if at is not None else []))
    f_end = np.column_stack(([at] if at is not None else []) + [content_end[rows]])
    width = f_end - f_start
    too_wide = (width > MAX_FIELD_CHARS).any(axis=1)
    digits = np.concatenate([[0], np.cumsum(~_DIGIT[buf])])
    stamp_ok = (width[:, 0] > 0) & (width[:, 0] <= MAX_STAMP_DIGITS)
    stamp_ok &= digits[f_end[:, 0]] - digits[f_start[:, 0]] == 0
    kind[rows[too_wide]] = NUMBER
    kind[rows[~too_wide & ~stamp_ok]] = STAMP
    keep = ~too_wide & stamp_ok
    rows, f_start, width = rows[keep], f_start[keep], width[keep]
    table = _field_table(buf, f_start, width)
    stamps = table[:, 0].astype(np.float64)
    values = np.full((len(rows), n_fields - 1), np.nan)
    filled = width[:, 1:] > 0
    try:
        values[filled] = table[:, 1:][filled].astype(np.float64)
    except ValueError:  # a field that only looks like a number (1-2, e): find it (rare)
        values[filled] = [_number(v) for v in table[:, 1:][filled].tolist()]
    bad = (np.isnan(values) & filled).any(axis=1) | np.isinf(values).any(axis=1)
    bad |= stamps >= hello.wrap
    kind[rows[bad & (stamps >= hello.wrap)]] = STAMP
    kind[rows[bad & (stamps < hello.wrap)]] = NUMBER
    offsets = None
    if hello.offsets_per_line:
        offsets = values[:, n_values:]
        wrong = ~bad & ~((offsets >= 0) & (offsets < MAX_OFFSET_US)).all(axis=1)
        kind[rows[wrong]] = OFFSET
        bad |= wrong
        offsets = offsets[~bad]
    return ParsedLines(
        kind, rows[~bad], stamps[~bad].astype(np.int64), values[~bad, :n_values], offsets
    )


def _field_table(buf: np.ndarray, f_start: np.ndarray, width: np.ndarray) -> np.ndarray:
    """(m, F) fixed-width byte strings of the fields (padding with NUL, which numpy drops)."""
    w = max(int(width.max()) if width.size else 1, 1)
    index = f_start[..., None] + np.arange(w)
    chars = np.where(
        np.arange(w) < width[..., None], buf[np.minimum(index, len(buf) - 1)], 0
    ).astype(np.uint8)
    return np.ascontiguousarray(chars).view(f"S{w}")[..., 0]


def _number(text: bytes) -> float:
    try:
        return float(text)
    except ValueError:
        return float("nan")
