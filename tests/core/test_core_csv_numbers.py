"""The compiled parser of plain CSV numbers (:mod:`hapticdesk.files.csv_numbers`) reads to the
bit what numpy's ``loadtxt`` reads, leaves it every block holding anything else, and the CSV
reader with it reads and refuses exactly as without it (file:line:column)."""

from __future__ import annotations

import sys
from pathlib import Path

import numba  # noqa: F401  (loaded, as a command that estimates has it: the parser is used)
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hapticdesk.files import recording_csv
from hapticdesk.files.csv_numbers import plain_numbers
from hapticdesk.files.recording import Recording
from hapticdesk.files.recording_io import write_recording

from .test_core_recording_fuzz import NAMES, csv_texts
from .test_core_recording_plain import _read, assert_read_as_the_careful_path_reads

EXAMPLES = settings(
    max_examples=300,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)

digits = st.text("0123456789", min_size=0, max_size=20)
# numbers of every form (and near-numbers): signs, points, exponents, long mantissas
numbers = st.builds(
    lambda sign, whole, point, fraction, e, esign, power: (
        sign + whole + point + fraction + (e + esign + power if e else "")
    ),
    st.sampled_from(["", "-", "+"]),
    digits,
    st.sampled_from(["", ".", ".."]),
    digits,
    st.sampled_from(["", "e", "E"]),
    st.sampled_from(["", "-", "+"]),
    st.text("0123456789", min_size=0, max_size=6),
)
cells = numbers | st.sampled_from(["nan", "-nan", "NaN", "inf", "", " 1", "1 ", '"2"', "n", "x"])


def loadtxt(lines: list[str]) -> np.ndarray | None:
    try:
        return np.loadtxt(lines, delimiter=",", ndmin=2, dtype=float, comments=None)
    except ValueError:
        return None


@EXAMPLES
@given(rows=st.lists(st.lists(cells, min_size=3, max_size=3).map(",".join), min_size=1))
def test_what_it_reads_is_what_numpy_reads_to_the_bit(rows: list[str]) -> None:
    ours = plain_numbers(rows, 3)
    if ours is not None:
        theirs = loadtxt(rows)
        assert theirs is not None and theirs.shape == ours.shape
        assert (theirs.view(np.int64) == ours.view(np.int64)).all()


@EXAMPLES
@given(
    values=st.lists(
        st.floats(allow_nan=True, allow_infinity=False, width=64), min_size=1, max_size=60
    ),
    form=st.sampled_from(["%.10g", "%r", "%.6f", "%.3e"]),
)
def test_numbers_as_recordings_write_them_are_read_here(values: list[float], form: str) -> None:
    """Not left to numpy: ``%.10g`` (how recordings are written), short reprs, fixed and
    exponent forms; only a mantissa beyond 2**53 or a power beyond 10**22 is left."""
    texts = [(repr(v) if form == "%r" else form % v) for v in values]
    rows = [",".join(texts[i : i + 3]) for i in range(0, len(texts) - len(texts) % 3, 3)]
    if not rows:
        return
    ours = plain_numbers(rows, 3)
    theirs = loadtxt(rows)
    assert theirs is not None
    exact = all(
        "e" not in t or abs(int(t.split("e")[1])) <= 22 - len(t.split("e")[0]) for t in texts
    )
    short = all(len(t.replace("-", "").replace(".", "").split("e")[0]) <= 15 for t in texts)
    if form in ("%.10g", "%.6f", "%.3e") and exact and short and max(map(abs, values)) < 1e15:
        assert ours is not None, rows
    if ours is not None:
        assert (theirs.view(np.int64) == ours.view(np.int64)).all()


def test_anything_else_is_left_to_numpy() -> None:
    for row in ["1,,2", "1, 2,3", "inf,1,2", "-nan,1,2", "1,2", "1,2,3,4", "1e,2,3", "1.2.3,1,2",
                "9007199254740993,1,2", "1e23,1,2", "1e-23,1,2", '"1",2,3', "1,2,3\r", ".,1,2",
                "-,1,2", "1e12345,1,2", "na,1,2", "", "1,2,3 ", "é,1,2"]:  # fmt: skip
        assert plain_numbers([row, "1,2,3"], 3) is None, row
    assert plain_numbers([], 3) is None
    edge = plain_numbers(["9007199254740992,1e+22,-0", "0e99,.5,5."], 3)
    assert edge is not None and np.signbit(edge[0, 2]) and edge[1].tolist() == [0.0, 0.5, 5.0]


@EXAMPLES
@given(text=st.one_of(csv_texts(), st.just("")), block_rows=st.sampled_from([1, 3, 16_384]))
def test_the_reader_with_it_reads_and_refuses_as_the_careful_path(
    tmp_path: Path, text: str, block_rows: int
) -> None:
    assert "numba" in sys.modules  # (the compiled parser is used)
    assert_read_as_the_careful_path_reads(tmp_path / "any.csv", text, block_rows)


def test_a_written_recording_is_read_by_it_alone(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    rng = np.random.default_rng(2)
    k = 2000
    truth = np.where(rng.random(k) < 0.5, np.nan, rng.normal(size=k))
    rec = Recording(
        np.arange(k) / 1200,
        # (down to 1e-10 or so, as %.10g writes it: 1.234567891e-10, 10**-19 exact)
        rng.normal(size=(k, 4, 6)) * 10.0 ** rng.integers(-4, 6, size=(k, 4, 6)),
        NAMES,
        {"true_x": truth},
    )
    rec.wrench[5, 0, 0] = -0.0
    path = tmp_path / "sim.csv"
    write_recording(path, rec)
    with monkeypatch.context() as patch:  # numba not loaded: numpy reads it
        patch.delitem(sys.modules, "numba")
        by_numpy = _read(path, 500)

    def refuse(self, lines):
        raise AssertionError("numpy's parser ran")

    monkeypatch.setattr(recording_csv.CsvRecordingReader, "_loadtxt", refuse)
    compiled = _read(path, 500)
    assert not isinstance(compiled, str) and not isinstance(by_numpy, str)
    for a, b in [(compiled.t, by_numpy.t), (compiled.wrench, by_numpy.wrench)]:
        assert (a.view(np.int64) == b.view(np.int64)).all()
    assert (
        compiled.extra["true_x"].view(np.int64) == by_numpy.extra["true_x"].view(np.int64)
    ).all()


@pytest.mark.parametrize("end", ["\n", ""], ids=["ended", "last line unended"])
def test_plain_lines_are_parsed_from_the_bytes_as_read(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, end: str
) -> None:
    """A file of plain lines is parsed from its bytes as read, across the reads and the
    blocks (no line decoded, split, joined and encoded again), to the same bits as numpy
    reads it; an odd line among them is read as text, and the plain ones after it from the
    bytes again."""
    rng = np.random.default_rng(5)
    k = 3000
    rec = Recording(np.arange(k) / 1200, rng.normal(size=(k, 4, 6)), NAMES, {})
    path = tmp_path / "plain.csv"
    write_recording(path, rec)
    path.write_text(path.read_text().removesuffix("\n") + end)
    with monkeypatch.context() as patch:  # numba not loaded: numpy reads it
        patch.delitem(sys.modules, "numba")
        by_numpy = _read(path, 700)
    decoded: list[int] = []
    lines = recording_csv.RecordingLines
    decode = lines._decode
    monkeypatch.setattr(lines, "_decode", lambda self, data: decoded.append(len(data)))
    compiled = _read(path, 700)
    assert decoded == [], "lines were decoded"
    assert not isinstance(compiled, str) and not isinstance(by_numpy, str)
    for a, b in [(compiled.t, by_numpy.t), (compiled.wrench, by_numpy.wrench)]:
        assert (a.view(np.int64) == b.view(np.int64)).all()
    # one line with an empty cell (read as NaN by the careful path): the rest still read
    text = path.read_text().split("\n")
    cells = text[1500].split(",")
    cells[3] = ""
    text[1500] = ",".join(cells)
    path.write_text("\n".join(text))
    monkeypatch.setattr(lines, "_decode", decode)
    odd = _read(path, 700)
    assert not isinstance(odd, str)
    assert np.isnan(odd.wrench[1499]).sum() == 1
    assert (odd.t.view(np.int64) == by_numpy.t.view(np.int64)).all()
