"""CSV text of many rows built at once from numpy columns: each column's cells as a byte
matrix made by integer arithmetic (no Python step per cell), the rows joined by dropping the
padding. A number's cell is what Python's ``"%.Nf" % value`` writes, to the byte, wherever
that is certain; :attr:`Cells.exact` marks the rows where it is not (for the caller to format
those few with Python), so the text never depends on this module's arithmetic.

Why: ``hapticdesk contacts`` on a minute of data spent more time formatting its 50,000 rows
(one ``%`` format a row) than estimating them (docs/performance.md)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

#: the byte a cell is padded with (no text cell holds it: a label that does is not exact)
PAD = 0
#: a scaled value at or beyond this is left to Python: below it every integer is a float, and
#: the check of :func:`fixed_point` has room
_LARGEST_SCALED = 2.0**52


class Cells(NamedTuple):
    """One column's cells for ``n`` rows."""

    chars: np.ndarray  # (n, width) uint8: a row's cell, then PAD up to the width
    exact: np.ndarray  # (n,) bool: the cell is the text Python writes (else PAD only)


class JoinedRows(NamedTuple):
    """Rows joined into text, with where each row begins in it."""

    text: bytes  # the kept rows, each ended by a line end
    starts: np.ndarray  # (n,) int64: where row i begins in ``text`` (a left-out row: where
    # it would have gone)


def fixed_point(values: np.ndarray, decimals: int) -> Cells:
    """``"%.{decimals}f" % v`` of each value (``decimals`` from 1 to 15).

    The value times 10**decimals is rounded to an integer, whose digits are written with the
    decimal point put back. Python rounds the exact binary value, the product may be half a
    unit in its last place off it, so a value that close to halfway between two outputs, (a
    tie among them), one not finite or one too large is not exact: left for Python."""
    if not 1 <= decimals <= 15:
        raise ValueError(f"decimals from 1 to 15, not {decimals}")
    values = np.asarray(values, dtype=np.float64)
    with np.errstate(invalid="ignore", over="ignore"):
        scaled = values * float(10**decimals)  # (10**15 and below: exact as floats)
        whole = np.rint(scaled)
        # |scaled - whole| is exact (both multiples of scaled's last place); the product's
        # rounding is at most |scaled| * 2**-53: four times that is kept from halfway
        exact = (np.abs(scaled) < _LARGEST_SCALED) & (
            0.5 - np.abs(scaled - whole) > np.abs(scaled) * 2.0**-51
        )
    units = np.where(exact, np.abs(whole), 0.0).astype(np.int64)
    digits = max(decimals + 1, len(str(int(units.max(initial=0)))))
    # [sign][integer digits][.][decimals digits], the digits from the last, one scalar
    # division a column (numpy divides by a scalar without a division instruction)
    cells = np.empty((len(values), digits + 2), np.uint8)
    cells[:, 0] = np.where(np.signbit(values), ord("-"), PAD)  # (-0.0 writes `-0`)
    cells[:, digits - decimals + 1] = ord(".")
    left = units
    for k in range(digits):
        column = digits + 1 - k - (k >= decimals)
        higher = left // 10
        cells[:, column] = left - higher * 10 + ord("0")
        if k > decimals:  # leading zeros dropped down to the units digit (`0.5`, not `00.5`)
            cells[left == 0, column] = PAD
        left = higher
    cells[~exact] = PAD
    return Cells(cells, exact)


def labels(names: Sequence[str], index: np.ndarray) -> Cells:
    """``names[i]`` for each ``i`` of ``index`` (UTF-8; a name holding the PAD character is
    not exact)."""
    encoded = [name.encode("utf-8") for name in names]
    width = max(map(len, encoded), default=0)
    table = np.zeros((len(encoded), max(width, 1)), np.uint8)
    for i, name in enumerate(encoded):
        table[i, : len(name)] = np.frombuffer(name, np.uint8)
    fits = np.array([bytes([PAD]) not in name for name in encoded], dtype=bool)
    index = np.asarray(index, dtype=np.intp)
    chars = np.where(fits[index, None], table[index], PAD).astype(np.uint8, copy=False)
    return Cells(chars, fits[index])


def join_rows(columns: Sequence[np.ndarray], keep: np.ndarray) -> JoinedRows:
    """The rows of ``columns`` (each a Cells.chars), cells separated by commas, each row
    ended by ``\\n``; only the rows ``keep`` marks (where the others begin is kept in
    :attr:`JoinedRows.starts`)."""
    n = len(keep)
    comma = np.full((n, 1), ord(","), np.uint8)
    parts: list[np.ndarray] = []
    for column in columns:
        parts += [column, comma]
    parts[-1] = np.full((n, 1), ord("\n"), np.uint8)
    matrix = np.concatenate(parts, axis=1)
    keep = np.asarray(keep, bool)
    starts = np.zeros(n, np.int64)
    if not keep.all():
        matrix[~keep] = PAD
        lengths = np.count_nonzero(matrix, axis=1)
        starts = np.cumsum(lengths) - lengths
    flat = matrix.ravel()
    return JoinedRows(flat[flat != PAD].tobytes(), starts)
