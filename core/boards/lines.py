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

_DIGIT = np.zeros(256, bool)
_DIGIT[ord("0") : ord("9") + 1] = True
#: per byte: not text (printable ASCII and tab are), not a sample's character, a comma,
#: not a digit; summed along a line by running counts (:func:`_prefix_counts`)
_FLAGS = np.ones((256, 4), np.int32)
_FLAGS[32:127, 0] = _FLAGS[9, 0] = 0
_FLAGS[[ord(c) for c in "0123456789+-.eE,"], 1] = 0
_FLAGS[:, 2] = 0
_FLAGS[ord(","), 2] = 1
_FLAGS[_DIGIT, 3] = 0
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


def _prefix_counts(buf: np.ndarray) -> np.ndarray:
    """(len(buf) + 1, 4) running counts of the bytes that are not text, not a sample's
    character, commas, and not digits (:data:`_FLAGS`): a line's counts are two rows apart."""
    counts = np.zeros((len(buf) + 1, _FLAGS.shape[1]), np.int32)
    np.cumsum(_FLAGS[buf], axis=0, out=counts[1:])
    return counts


def line_kinds(
    batch: LineBatch, checksum_required: bool
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each line's kind before its fields are read (EMPTY, SAMPLE for a digit first, HELLO,
    COMMENT, or a garbled reason), where its content ends (before ``*HH``), and the batch's
    running counts (:func:`_prefix_counts`)."""
    buf, starts, ends = batch.buf, batch.starts, batch.ends
    counts = _prefix_counts(buf)
    if len(starts) == 0:
        return np.zeros(0, np.int8), ends, counts
    last = len(buf) - 1
    length = ends - starts
    first = np.where(length > 0, buf[np.minimum(starts, last)], 0)
    # a checksum is the line's last three bytes: `*`, two hex digits
    tail = buf[np.clip(ends[:, None] - np.arange(3, 0, -1), 0, last)]  # (n, 3)
    tail[length < 3] = 0
    well_formed = (tail[:, 0] == 42) & (_HEX[tail[:, 1]] >= 0) & (_HEX[tail[:, 2]] >= 0)
    content_end = np.where(well_formed, ends - 3, ends)
    xor = np.zeros(len(buf) + 1, np.uint8)
    np.bitwise_xor.accumulate(buf, out=xor[1:])
    given = _HEX[tail[:, 1]] * 16 + _HEX[tail[:, 2]]
    not_text = counts[ends, 0] - counts[starts, 0] > 0
    matches = (xor[content_end] ^ xor[starts]) == given
    checked = np.where(well_formed, matches, not checksum_required)
    usual = checked & ~not_text & _DIGIT[first] & (length <= MAX_LINE_BYTES)
    if usual.all():  # the common read: sample lines, checksums right, nothing odd
        return np.full(len(starts), SAMPLE, np.int8), content_end, counts
    comment = first == ord("#")
    near_star = (tail[:, 1] == 42) | (tail[:, 2] == 42)  # `*` and fewer than two digits
    kind = np.select(
        [
            length == 0,
            length > MAX_LINE_BYTES,
            not_text,
            near_star & ~comment,
            well_formed & ~matches,
            ~well_formed & ~comment & checksum_required,
            comment,
            first == ord("@"),
            ~_DIGIT[first],
        ],
        [EMPTY, OVERLONG, NOT_TEXT, CHECKSUM_FORM, CHECKSUM, CHECKSUM_MISSING, COMMENT, HELLO,
         UNKNOWN],
        SAMPLE,
    ).astype(np.int8)  # fmt: skip
    return kind, content_end, counts


def parse_lines(batch: LineBatch, hello: BoardHello | None) -> ParsedLines:
    """Classify every line of ``batch`` and read its samples' fields (module docstring);
    ``hello`` None: no hello yet, so sample lines are :data:`BEFORE_HELLO`."""
    kind, content_end, counts = line_kinds(batch, bool(hello and hello.checksum_required))
    if hello is None:
        kind[kind == SAMPLE] = BEFORE_HELLO
        return ParsedLines(kind, np.zeros(0, np.int64), np.zeros(0), np.zeros((0, 0)), None)
    buf, starts = batch.buf, batch.starts
    n_values, n_fields = len(hello.channels), hello.fields
    rows = np.flatnonzero(kind == SAMPLE)
    within = counts[content_end[rows]] - counts[starts[rows]]  # (m, 4) per line
    odd, fields = within[:, 1] > 0, within[:, 2] != n_fields - 1
    kind[rows[odd]] = CHARACTER
    kind[rows[~odd & fields]] = FIELDS
    rows = rows[~odd & ~fields]
    # the fields of every sample line: (m, F) starts and ends
    commas = np.flatnonzero(buf == 44)
    at = commas[np.searchsorted(commas, starts[rows])[:, None] + np.arange(n_fields - 1)]
    f_start = np.concatenate([starts[rows, None], at + 1], axis=1)
    f_end = np.concatenate([at, content_end[rows, None]], axis=1)
    width = f_end - f_start
    stamp_width = width[:, 0]
    stamp_ok = (stamp_width > 0) & (stamp_width <= MAX_STAMP_DIGITS)
    stamp_ok &= counts[f_end[:, 0], 3] == counts[f_start[:, 0], 3]  # digits only
    too_wide = (width > MAX_FIELD_CHARS).any(axis=1)
    kind[rows[too_wide]] = NUMBER
    kind[rows[~too_wide & ~stamp_ok]] = STAMP
    keep = ~too_wide & stamp_ok
    rows, f_start, width = rows[keep], f_start[keep], width[keep]
    table = _field_table(buf, f_start, width)
    stamps = table[:, 0].astype(np.float64)
    filled = width[:, 1:] > 0
    if filled.all():
        try:
            values = table[:, 1:].astype(np.float64)
        except ValueError:  # a field that only looks like a number (1-2, e): find it (rare)
            values = np.array([_number(v) for v in table[:, 1:].ravel().tolist()])
            values = values.reshape(len(rows), n_fields - 1)
    else:  # an empty field is a channel the board could not read: NaN
        values = np.full((len(rows), n_fields - 1), np.nan)
        values[filled] = [_number(v) for v in table[:, 1:][filled].tolist()]
    bad = (np.isnan(values) & filled).any(axis=1) | np.isinf(values).any(axis=1)
    beyond = stamps >= hello.wrap
    kind[rows[beyond]] = STAMP
    kind[rows[bad & ~beyond]] = NUMBER
    bad |= beyond
    offsets = None
    if hello.offsets_per_line:
        offsets = values[:, n_values:]
        wrong = ~bad & ~((offsets >= 0) & (offsets < MAX_OFFSET_US)).all(axis=1)
        kind[rows[wrong]] = OFFSET
        bad |= wrong
        offsets = offsets[~bad]
    if bad.any():
        rows, stamps, values = rows[~bad], stamps[~bad], values[~bad]
    return ParsedLines(kind, rows, stamps.astype(np.int64), values[:, :n_values], offsets)


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
