"""The CSV reader's plain path (one ``np.loadtxt`` of a plainly numeric block) reads exactly
what the careful path reads, and refuses exactly what it refuses with the same
file:line:column; a recording as the simulator writes it never needs the careful path."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hapticdesk.errors import ConfigError
from hapticdesk.files import recording_csv
from hapticdesk.files.recording import Recording
from hapticdesk.files.recording_io import read_recording, write_recording

from .test_core_recording_fuzz import NAMES, csv_texts

SAME = settings(
    max_examples=150,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)


def _read(path: Path, block_rows: int) -> Recording | str:
    try:
        return read_recording(path, NAMES, block_rows=block_rows)
    except ConfigError as err:
        return f"ConfigError: {err}"


def _careful_only(monkeypatch: pytest.MonkeyPatch) -> None:
    reader = recording_csv.CsvRecordingReader
    monkeypatch.setattr(reader, "_plain_ahead", lambda self, rows: None)  # (from the bytes)
    monkeypatch.setattr(reader, "_parse_plain", lambda self, lines: None)


def _assert_same(a: Recording | str, b: Recording | str) -> None:
    if isinstance(a, str) or isinstance(b, str):
        assert a == b
        return
    np.testing.assert_array_equal(a.t, b.t)
    np.testing.assert_array_equal(a.wrench, b.wrench)
    assert list(a.extra) == list(b.extra)
    for name in a.extra:
        np.testing.assert_array_equal(a.extra[name], b.extra[name])


@SAME
@given(
    text=st.one_of(csv_texts(), st.just("")),
    block_rows=st.sampled_from([1, 3, 16_384]),
)
def test_the_plain_path_reads_and_refuses_as_the_careful_path(
    tmp_path: Path, text: str, block_rows: int
) -> None:
    assert_read_as_the_careful_path_reads(tmp_path / "any.csv", text, block_rows)


def assert_read_as_the_careful_path_reads(path: Path, text: str, block_rows: int) -> None:
    """``text`` as a recording reads (or is refused) alike with and without the plain path."""
    path.write_text(text, encoding="utf-8")
    both = _read(path, block_rows)
    with pytest.MonkeyPatch.context() as patch:
        _careful_only(patch)
        careful = _read(path, block_rows)
    _assert_same(both, careful)


@pytest.mark.parametrize(
    "change",
    [
        lambda cells: cells.__setitem__(5, ""),  # an empty cell: NaN
        lambda cells: cells.__setitem__(5, " "),  # a blank one: NaN
        lambda cells: cells.__setitem__(5, "x"),  # a word: file:line:column
        lambda cells: cells.__setitem__(0, "nan"),  # no time
        lambda cells: cells.append("1"),  # a value too many
        lambda cells: cells.pop(),  # one too few
        lambda cells: cells.append(""),  # a logger's trailing comma: still read
        lambda cells: cells.__setitem__(3, '"1.5"'),  # a quoted number
    ],
    ids=["empty", "blank", "word", "no time", "too many", "too few", "trailing comma", "quoted"],
)
def test_one_odd_line_among_plain_ones_reads_as_the_careful_path_reads_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, change
) -> None:
    rng = np.random.default_rng(0)
    rec = Recording(np.arange(40) / 1200, rng.normal(size=(40, 4, 6)), NAMES)
    path = tmp_path / "odd.csv"
    write_recording(path, rec)
    lines = path.read_text().splitlines()
    cells = lines[30].split(",")
    change(cells)
    lines[30] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")
    both = _read(path, 16)
    _careful_only(monkeypatch)
    _assert_same(both, _read(path, 16))


def test_a_written_recording_never_takes_the_careful_path(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The simulator's files (NaN truth columns, -0, exponents, CR LF) are plainly numeric:
    the careful path, which scans every block for empty cells, is not run on them."""
    rng = np.random.default_rng(1)
    k = 3000
    truth = np.where(rng.random(k) < 0.5, np.nan, rng.normal(size=k))
    rec = Recording(
        np.arange(k) / 1200,
        rng.normal(scale=1e-6, size=(k, 4, 6)) * 10.0 ** rng.integers(-3, 9, size=(k, 4, 6)),
        NAMES,
        {"true_x": truth, "true_surface": -np.ones(k)},
    )
    rec.wrench[5, 0, 0] = -0.0
    path = tmp_path / "sim.csv"
    write_recording(path, rec)
    crlf = tmp_path / "crlf.csv"
    crlf.write_bytes(path.read_bytes().replace(b"\n", b"\r\n"))

    def refuse(self, lines, first_line):
        raise AssertionError(f"the careful path ran on line {first_line}")

    monkeypatch.setattr(recording_csv.CsvRecordingReader, "_parse_careful", refuse)
    for file in (path, crlf):
        back = read_recording(file, NAMES, block_rows=1000)
        np.testing.assert_allclose(back.wrench, rec.wrench, rtol=1e-9)
        np.testing.assert_array_equal(np.isnan(back.extra["true_x"]), np.isnan(truth))
