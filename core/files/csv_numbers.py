"""A CSV block of plain decimal numbers parsed by a compiled loop, for a command that has numba
loaded already (one that estimates: the estimator's kernels need it). The CSV reader
(:mod:`.recording_csv`) imports this only then: it never pays numba's import for itself.

Only the plainest cells are read here: an optional sign, digits with at most one point, an
optional exponent (``1.5e-05``), or ``nan``; at most 18 digits making an integer up to 2**53
and a power of ten within 10**±22, so that the digits and the power are both exact as floats
and one division (or multiplication) rounds their quotient correctly: the same float numpy's
parser makes (it rounds correctly too). Anything else (a blank or quoted cell, a space,
``inf``, a row of another width, 17 significant digits, 1e-23, a CR LF line end) and the
line is left to numpy's ``loadtxt``, which reads it and names any fault, as before: the
reader hands the parser the bytes it read (:func:`plain_rows`: the lines read before that
line are parsed, the block ends there) or a block of lines (:func:`plain_numbers`: all or
none of them).

Why: numpy's ``loadtxt`` took 0.13–0.19 s of ``hapticdesk contacts`` on a minute of the
paper's experiment (72,000 lines of 34 columns), a quarter of the command; this loop takes a
third of that (docs/performance.md)."""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit, types

from hapticdesk.cached_load import cache_loads
from hapticdesk.files.recording import MAX_TIME_S

# (as the estimator's kernels are compiled: a cached load leaves numba's runtime out)
_OPTIONS: dict[str, Any] = {"cache": True, "nogil": True, "error_model": "numpy", "_nrt": False}
_INLINED = {**_OPTIONS, "forceinline": True}  # (into the loop, by LLVM)
_SIGNATURE = (
    types.Array(types.uint8, 1, "C", readonly=True),
    types.int64,
    types.int64,
    types.float64[:, ::1],
)
#: the powers of ten a float holds exactly
_POWERS = np.array([float(10**k) for k in range(23)])
_EXACT_INTEGERS = np.uint64(2**53)  # a mantissa up to this is exact as a float
_ZERO, _NINE, _POINT, _PLUS, _MINUS = (ord(c) for c in "09.+-")
_COMMA, _LINE_END, _N, _A, _E, _E_UPPER = (ord(c) for c in ",\nnaeE")


@njit(**_INLINED)
def _digits(data: np.ndarray, i: int, mantissa: np.uint64) -> tuple[np.uint64, int]:
    """The digits from ``data[i]`` on appended to ``mantissa``, and the index after them (the
    data ends with a line end: every loop here stops there at the latest)."""
    while True:
        digit = np.uint64(data[i]) - np.uint64(_ZERO)  # (below "0" wraps round: not a digit)
        if digit > 9:
            return mantissa, i
        mantissa = mantissa * np.uint64(10) + digit
        i += 1


@njit(**_INLINED)
def _exponent(data: np.ndarray, i: int) -> tuple[int, int]:
    """The exponent from ``data[i]`` on (after its ``e``) and the index after it; -1 for the
    index when it is not a sign and one to four digits."""
    minus = data[i] == _MINUS
    if minus or data[i] == _PLUS:
        i += 1
    digits, end = _digits(data, i, np.uint64(0))
    if not 0 < end - i <= 4:
        return 0, -1
    power = int(np.int64(digits))  # (int64 and uint64 would make a float)
    return (-power if minus else power), end


@njit(**_INLINED)
def _number(data: np.ndarray, i: int) -> tuple[float, int]:
    """The plain decimal at ``data[i]`` on and the index after it; -1 for the index when it is
    not one this reads exactly."""
    negative = data[i] == _MINUS
    if negative or data[i] == _PLUS:
        i += 1
    elif data[i] == _N and data[i + 1] == _A and data[i + 2] == _N:
        return np.nan, i + 3
    mantissa, end = _digits(data, i, np.uint64(0))
    digits, exponent = end - i, 0
    if data[end] == _POINT:
        i = end + 1
        mantissa, end = _digits(data, i, mantissa)
        digits, exponent = digits + end - i, i - end
    # (18 digits cannot overflow; the mantissa must be exact as a float)
    if digits == 0 or digits > 18 or mantissa > _EXACT_INTEGERS:
        return 0.0, -1
    if data[end] == _E or data[end] == _E_UPPER:
        power, end = _exponent(data, end + 1)
        if end < 0:
            return 0.0, -1
        exponent += power
    value = 0.0
    if mantissa and not -22 <= exponent <= 22:
        return 0.0, -1
    if mantissa and exponent < 0:
        value = mantissa / _POWERS[-exponent]  # both exact: one correctly rounded division
    elif mantissa:
        value = mantissa * _POWERS[exponent]
    return (-value if negative else value), end


@njit(**_OPTIONS)
def _parse(data: np.ndarray, width: int, time_column: int, table: np.ndarray) -> tuple[int, int]:
    """Fill rows of ``table`` (× ``width``) from the start of ``data`` until the table is
    full, the data ends or a row is not ``width`` plain decimals separated by commas and
    ended by a line end, or its ``time_column`` (-1: none) is not a time a recording may
    hold (finite, within ``MAX_TIME_S``). Returns the rows filled and the index of ``data``
    after them."""
    i = 0
    for row in range(table.shape[0]):
        start = i
        for column in range(width):
            if i >= len(data):
                return row, start
            value, i = _number(data, i)
            if i < 0 or data[i] != (_COMMA if column < width - 1 else _LINE_END):
                return row, start
            table[row, column] = value
            i += 1
        if time_column >= 0 and not abs(table[row, time_column]) <= MAX_TIME_S:
            return row, start
    return table.shape[0], i


_loaded = False


def plain_rows(
    data: bytes | memoryview, width: int, time_column: int, table: np.ndarray
) -> tuple[int, int]:
    """Rows of ``table`` (C-contiguous, ``width`` columns) read from ``data``, whole lines
    each ended by a line end, as many as fit, up to the first that is not ``width`` plain
    decimals with a time a recording may hold (``time_column``; -1: any): the rows filled
    and the bytes of ``data`` they were. The rows after are left to numpy's ``loadtxt``."""
    global _loaded
    if not _loaded:  # (from numba's cache without readying its compiler: cached_load)
        with cache_loads():
            _parse.compile(_SIGNATURE)
        _loaded = True
    rows, used = _parse(np.frombuffer(data, np.uint8), width, time_column, table)
    return int(rows), int(used)


def plain_numbers(lines: list[str], width: int) -> np.ndarray | None:
    """The table of ``lines`` (each ``width`` plain decimals), or None when a cell or a line
    is anything else (numpy's ``loadtxt`` then reads the block and names any fault)."""
    text = "\n".join([*lines, ""])  # (each line ended: the loops stop at the last end)
    if not lines or not text.isascii():
        return None
    table = np.empty((len(lines), width))
    rows, _ = plain_rows(text.encode("ascii"), width, -1, table)
    return table if rows == len(lines) else None
