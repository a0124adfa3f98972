"""CSV cells built a block at a time (:mod:`hapticdesk.files.csv_cells`): every cell it is
sure of is Python's own ``%.Nf`` text, and it is sure of nearly all; the values near a tie,
not finite or too large are left for Python."""

from __future__ import annotations

import numpy as np
import pytest

from hapticdesk.files.csv_cells import PAD, fixed_point, join_rows, labels


def texts(chars: np.ndarray) -> list[str]:
    return [row[row != PAD].tobytes().decode() for row in chars]


def hard_values(decimals: int) -> np.ndarray:
    """Ties and their neighbours, zeros of both signs, the limits, and values that are not
    numbers."""
    ties = np.arange(-40, 41) / 128.0  # exact binary ties at 6 decimals (1/128 = 0.0078125)
    halfway = (np.arange(-20, 21) + 0.5) / 10.0**decimals  # near ties: off by the product
    near = np.concatenate([np.nextafter(halfway, np.inf), np.nextafter(halfway, -np.inf)])
    big = 2.0**52 / 10.0**decimals
    limits = [0.0, -0.0, -1e-12, 1e-12, big, -big, np.nextafter(big, 0), 1e300]
    other = [np.nan, -np.nan, np.inf, -np.inf]
    return np.concatenate([ties, halfway, near, limits, other])


@pytest.mark.parametrize("decimals", [1, 4, 6, 10])
def test_a_cell_is_pythons_text_or_left_to_python(decimals: int) -> None:
    rng = np.random.default_rng(decimals)
    scale = 10.0 ** rng.integers(-9, 14 - decimals, 200_000)  # (within 2**52 scaled)
    ordinary = rng.normal(size=200_000) * scale
    values = np.concatenate([ordinary, hard_values(decimals)])
    cells = fixed_point(values, decimals)
    python = [f"{v:.{decimals}f}" for v in values.tolist()]
    written = texts(cells.chars)
    for v, exact, ours, theirs in zip(values, cells.exact, written, python, strict=True):
        assert ours == (theirs if exact else ""), v
    # and it is sure of nearly every ordinary value (else it would leave all to Python)
    assert cells.exact[: len(ordinary)].mean() > 0.999
    assert not cells.exact[np.isin(values, [np.inf, -np.inf]) | np.isnan(values)].any()


def test_zero_and_negative_zero_keep_their_sign() -> None:
    assert texts(fixed_point(np.array([0.0, -0.0, -1e-9, 5e-7 - 1e-12]), 6).chars) == [
        "0.000000",
        "-0.000000",
        "-0.000000",
        "0.000000",
    ]


def test_labels_and_rows_joined_with_the_rows_left_out_placed() -> None:
    names = ["", "touch", 'a "b", c', "é", "nul\0"]
    index = np.array([1, 0, 2, 3, 4, 1])
    cells = labels(names, index)
    assert texts(cells.chars) == ["touch", "", 'a "b", c', "é", "", "touch"]
    assert cells.exact.tolist() == [True, True, True, True, False, True]
    numbers = fixed_point(np.arange(6) * 1.5, 2)
    joined = join_rows([numbers.chars, cells.chars], cells.exact)
    text = joined.text.decode()
    assert text == '0.00,touch\n1.50,\n3.00,a "b", c\n4.50,é\n7.50,touch\n'
    # row 4 was left out: where it begins is where row 5 begins
    assert joined.starts[4] == joined.starts[5] == len(text.encode()) - len(b"7.50,touch\n")
    assert join_rows([numbers.chars[:0]], np.zeros(0, bool)).text == b""
