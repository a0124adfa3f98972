"""Fuzzing the recording readers (issue 11 item 21): any file ends in a recording or a
ConfigError that names the file (and the line where there is one), never a traceback."""

from __future__ import annotations

import io
import re
import zipfile

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hapticdesk.errors import ConfigError
from hapticdesk.files.recording_io import read_recording

NAMES = ["fl", "fr", "bl", "br"]
COLUMNS = ["t"] + [f"{s}_{a}" for s in NAMES for a in ("fx", "fy", "fz", "mx", "my", "mz")]
FUZZ = settings(
    max_examples=80,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)

cells = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.integers(-(10**30), 10**30).map(str),
    st.sampled_from(["", " ", "nan", "inf", "-", "1e999", '"1"', '"', "x", "1,2", "\t"]),
    st.text(max_size=6),
)


@st.composite
def csv_texts(draw: st.DrawFn) -> str:
    """A header (the needed columns, shuffled, some dropped or doubled, extras) and rows of
    cells of any kind and count, with blank lines and stray line ends."""
    header = draw(st.permutations(COLUMNS))
    if draw(st.booleans()):
        header = header[: draw(st.integers(0, len(header)))]
    header = header + draw(
        st.lists(st.sampled_from(["note", "t", "", "x y", "true_x"]), max_size=3)
    )
    rows = draw(
        st.lists(
            st.lists(cells, min_size=0, max_size=len(header) + 2).map(",".join)
            | st.sampled_from(["", "\r", ",,,", "#"]),
            max_size=12,
        )
    )
    ending = draw(st.sampled_from(["\n", "\r\n", ""]))
    return ",".join(header) + "\n" + "\n".join(rows) + ending


def check_error(err: ConfigError, path: str) -> None:
    text = str(err)
    assert text.startswith(path), text
    assert "Traceback" not in text


def read_or_refuse(path, **kw) -> None:
    try:
        rec = read_recording(path, NAMES, **kw)
    except ConfigError as err:
        check_error(err, str(path))
        return
    assert rec.wrench.shape == (len(rec), 4, 6)
    assert np.isfinite(rec.t).all()  # every sample has a time (NaN channels are flagged later)


@FUZZ
@given(text=csv_texts(), block_rows=st.sampled_from([1, 3, 16_384]))
def test_any_csv_is_a_recording_or_a_clear_error(tmp_path, text, block_rows):
    path = tmp_path / "fuzz.csv"
    path.write_text(text, encoding="utf-8")
    read_or_refuse(path, block_rows=block_rows)


@FUZZ
@given(data=st.binary(max_size=400))
def test_any_bytes_as_csv_are_a_clear_error_or_read(tmp_path, data):
    path = tmp_path / "fuzz.csv"
    path.write_bytes(data)
    read_or_refuse(path)


@FUZZ
@given(text=csv_texts())
def test_a_bad_csv_value_is_named_by_its_line(tmp_path, text):
    """Where the error names a line, that line of the file is a real one."""
    path = tmp_path / "fuzz.csv"
    path.write_text(text, encoding="utf-8")
    try:
        read_recording(path, NAMES, block_rows=2)
    except ConfigError as err:
        found = re.match(re.escape(str(path)) + r":(\d+)", str(err))
        if found:
            assert 1 <= int(found.group(1)) <= len(text.splitlines()) + 1, str(err)


arrays = st.one_of(
    st.integers(0, 6).map(lambda n: np.arange(n, dtype=float) / 1200),
    st.integers(0, 6).map(lambda n: np.ones(n, dtype=np.int16)),
    st.integers(0, 6).map(lambda n: np.full(n, np.nan)),
    st.sampled_from(
        [
            np.array(["a", "b"]),
            np.ones((2, 2)),
            np.array(1.0),
            np.array([1 + 2j, 3j]),
            np.zeros(2, dtype=[("a", "f8")]),
            np.array([True, False]),
            np.zeros(0),
        ]
    ),
)


@FUZZ
@given(columns=st.dictionaries(st.sampled_from(COLUMNS + ["note", "extra"]), arrays, max_size=27))
def test_any_npz_is_a_recording_or_a_clear_error(tmp_path, columns):
    path = tmp_path / "fuzz.npz"
    np.savez(path, **columns)
    read_or_refuse(path)


@FUZZ
@given(cut=st.integers(0, 4000), flip=st.integers(0, 4000))
def test_a_damaged_npz_is_a_clear_error(tmp_path, cut, flip):
    good = io.BytesIO()
    np.savez_compressed(good, **{c: np.arange(20) / 1200 for c in COLUMNS})
    data = bytearray(good.getvalue())
    if flip < len(data):
        data[flip] ^= 0xFF
    path = tmp_path / "fuzz.npz"
    path.write_bytes(bytes(data[: max(cut, 1)]) if cut < len(data) else bytes(data))
    read_or_refuse(path)


def test_a_zip_bomb_member_is_read_in_bounded_blocks(tmp_path):
    """A column that claims 10⁹ rows is refused or read block by block, never allocated whole."""
    path = tmp_path / "claims.npz"
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        header, {"descr": "<f8", "fortran_order": False, "shape": (10**9,)}
    )
    with zipfile.ZipFile(path, "w") as zf:
        for c in COLUMNS:
            zf.writestr(c + ".npy", header.getvalue() + np.zeros(8).tobytes())
    read_or_refuse(path)


@pytest.mark.parametrize(
    "flag_bit, method, message",
    [(0x1, None, "encrypted"), (0x0, 99, "compression method")],
    ids=["encrypted", "unknown-compression"],
)
def test_an_encrypted_or_oddly_compressed_npz_is_a_clear_error(tmp_path, flag_bit, method, message):
    """zipfile raises RuntimeError (NotImplementedError) for these, not OSError: it reached
    the user as "an unexpected RuntimeError"."""
    good = io.BytesIO()
    np.savez(good, **{c: np.arange(20) / 1200 for c in COLUMNS})
    data = bytearray(good.getvalue())
    for signature, flags_at, method_at in ((b"PK\x03\x04", 6, 8), (b"PK\x01\x02", 8, 10)):
        at = data.find(signature)
        while at >= 0:
            data[at + flags_at] |= flag_bit
            if method is not None:
                data[at + method_at : at + method_at + 2] = method.to_bytes(2, "little")
            at = data.find(signature, at + 4)
    path = tmp_path / "odd.npz"
    path.write_bytes(bytes(data))
    with pytest.raises(ConfigError, match=rf"odd\.npz: not a readable NPZ recording: .*{message}"):
        read_recording(path, NAMES)
