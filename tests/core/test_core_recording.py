"""Recordings: CSV and NPZ round trips, missing columns named, extra columns kept apart."""

import numpy as np
import pytest

from hapticdesk.errors import ConfigError
from hapticdesk.files.recording import Recording
from hapticdesk.files.recording_io import read_recording, write_recording

NAMES = ["fl", "fr", "bl", "br"]


def sample_recording(k: int = 50) -> Recording:
    rng = np.random.default_rng(3)
    return Recording(
        t=np.arange(k) / 1200.0,
        wrench=rng.normal(size=(k, 4, 6)),
        sensor_names=NAMES,
        extra={"true_x": rng.normal(size=k)},
    )


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_round_trip(tmp_path, suffix):
    rec = sample_recording()
    path = tmp_path / f"rec{suffix}"
    write_recording(path, rec)
    back = read_recording(path, NAMES)
    assert np.allclose(back.t, rec.t, rtol=1e-9, atol=1e-12)
    assert np.allclose(back.wrench, rec.wrench, rtol=1e-9)
    assert np.allclose(back.extra["true_x"], rec.extra["true_x"], rtol=1e-9)


def test_missing_column_is_named(tmp_path):
    path = tmp_path / "rec.csv"
    write_recording(path, sample_recording())
    text = path.read_text().replace("br_mz", "br_mzz")
    path.write_text(text)
    with pytest.raises(ConfigError, match="missing column.*br_mz"):
        read_recording(path, NAMES)


def test_extra_columns_are_ignored_and_column_order_is_free(tmp_path):
    rec = sample_recording(5)
    cols = rec.columns()[::-1] + ["comment"]
    table = np.hstack([rec.table()[:, ::-1], np.ones((5, 1))])
    path = tmp_path / "rec.csv"
    path.write_text(
        ",".join(cols) + "\n" + "\n".join(",".join(str(float(v)) for v in r) for r in table)
    )
    back = read_recording(path, NAMES)
    assert np.allclose(back.wrench, rec.wrench)
    assert "comment" in back.extra


def test_empty_cells_become_nan_for_the_estimator_to_flag(tmp_path):
    path = tmp_path / "rec.csv"
    write_recording(path, sample_recording(3))
    lines = path.read_text().splitlines()
    cells = lines[2].split(",")
    cells[3] = ""
    lines[2] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")
    back = read_recording(path, NAMES)
    assert np.isnan(back.wrench[1]).sum() == 1


@pytest.mark.parametrize("where", ["blank", "last", "last blank", "tab"])
def test_every_kind_of_empty_cell_is_nan(tmp_path, where):
    """The reader looks for empty cells only where a plain numeric file cannot have them:
    each kind must still be found (a blank one, one at the line's end, a tab)."""
    path = tmp_path / "rec.csv"
    write_recording(path, sample_recording(3))
    lines = path.read_text().splitlines()
    cells = lines[2].split(",")
    column = len(cells) - 1 if where.startswith("last") else 3
    cells[column] = {"blank": "  ", "last": "", "last blank": " ", "tab": "\t"}[where]
    lines[2] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")
    back = read_recording(path, NAMES)
    assert np.isnan(back.table()[1]).sum() == 1
    assert np.isfinite(np.delete(back.table(), 1, axis=0)).all()


def test_not_a_number_is_an_error(tmp_path):
    path = tmp_path / "rec.csv"
    write_recording(path, sample_recording(3))
    path.write_text(path.read_text().replace("\n0", "\nabc", 1))
    with pytest.raises(ConfigError, match="not a number"):
        read_recording(path, NAMES)


# --- hardening (issue 11 items 4, 5, 17; issue 15 item 7) -------------------------------------

HEADER = "t," + ",".join(f"{s}_{a}" for s in NAMES for a in ("fx", "fy", "fz", "mx", "my", "mz"))


def _csv(path, rows: list[str], header: str = HEADER) -> None:
    path.write_text(header + "\n" + "".join(r + "\n" for r in rows))


def _row(t: float, value: str = "1") -> str:
    return f"{t}," + ",".join([value] * 24)


def test_a_text_column_is_ignored_as_the_contract_says(tmp_path):
    path = tmp_path / "rec.csv"
    _csv(path, [_row(0.0) + ",left hand", _row(0.001) + ",right hand"], HEADER + ",note")
    back = read_recording(path, NAMES)
    assert np.allclose(back.t, [0.0, 0.001])
    assert "note" not in back.extra


@pytest.mark.parametrize("block_rows", [2, 65536])
def test_a_bad_value_names_its_file_line_and_column(tmp_path, block_rows):
    path = tmp_path / "rec.csv"
    rows = [_row(i / 1200) for i in range(6)]
    rows.insert(2, "")  # a blank line still counts as a line of the file
    cells = rows[5].split(",")
    cells[3] = "oops"
    rows[5] = ",".join(cells)  # file line 7 (header is line 1), column 4 = fl_fz
    _csv(path, rows)
    with pytest.raises(ConfigError, match=r"rec\.csv:7:4: column `fl_fz`: 'oops' is not a number"):
        read_recording(path, NAMES, block_rows=block_rows)


def test_a_short_row_names_its_line(tmp_path):
    path = tmp_path / "rec.csv"
    _csv(path, [_row(0.0), "", _row(0.001), "0.002,1,2"])
    with pytest.raises(ConfigError, match=r"rec\.csv:5: this row has 3 value"):
        read_recording(path, NAMES)


@pytest.mark.parametrize("t", ["", "nan"])
def test_a_row_without_a_time_is_an_error(tmp_path, t):
    path = tmp_path / "rec.csv"
    _csv(path, [_row(0.0), _row(0.001).replace("0.001", t, 1)])
    with pytest.raises(ConfigError, match=r"rec\.csv:3:1: `t` is .*finite time"):
        read_recording(path, NAMES)


@pytest.mark.parametrize("t", ["1e300", "-3e11"])
def test_a_time_no_clock_gives_is_an_error_at_its_cell(tmp_path, t):
    """A time of 1e300 in one row was read: every sample after it went back in time, each
    skipped (one bad cell lost the rest, said only as "time went back" at t=1000…0.000 s)."""
    path = tmp_path / "rec.csv"
    _csv(path, [_row(0.0), _row(0.001).replace("0.001", t, 1), _row(0.002)])
    with pytest.raises(ConfigError, match=rf"rec\.csv:3:1: `t` is '{t}'; .*within ±253402214400"):
        read_recording(path, NAMES)
    cols = _npz_columns(3)
    cols["t"][1] = float(t)
    _npz(tmp_path / "rec.npz", **cols)
    with pytest.raises(ConfigError, match=r"rec\.npz: `t` is .* in row 2; .*year 9999"):
        read_recording(tmp_path / "rec.npz", NAMES)


def test_all_nan_times_are_refused_by_replay(tmp_path, paper_desk):
    from hapticdesk.plugins.replay import open_replay

    path = tmp_path / "rec.csv"
    _csv(path, [_row(float("nan")) for _ in range(5)])
    with pytest.raises(ConfigError, match="`t` is 'nan'"):
        open_replay(str(path), paper_desk, speed=0)


def _npz(path, **columns):
    np.savez(path, **columns)


def _npz_columns(k: int) -> dict:
    cols = {"t": np.arange(k) / 1200.0}
    for s in NAMES:
        for a in ("fx", "fy", "fz", "mx", "my", "mz"):
            cols[f"{s}_{a}"] = np.ones(k)
    return cols


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"fr_fz": np.ones(7)}, r"different lengths: `t` has 8 rows, `fr_fz` 7"),
        ({"fr_fz": np.array(["a"] * 8)}, r"column `fr_fz` holds <U1 values; expected numbers"),
        ({"fr_fz": np.ones((8, 2))}, r"column `fr_fz` has shape \(8, 2\); expected one value"),
        ({"t": np.full(8, np.nan)}, r"`t` is nan in row 1"),
    ],
)
def test_a_bad_npz_column_is_a_clear_error(tmp_path, change, message):
    path = tmp_path / "rec.npz"
    _npz(path, **{**_npz_columns(8), **change})
    with pytest.raises(ConfigError, match=message):
        read_recording(path, NAMES)


def test_npz_extra_columns_of_other_kinds_are_ignored(tmp_path):
    path = tmp_path / "rec.npz"
    _npz(
        path, **_npz_columns(8), note=np.array(["x"] * 8), image=np.ones((3, 3)), true_x=np.ones(8)
    )
    back = read_recording(path, NAMES)
    assert len(back) == 8 and list(back.extra) == ["true_x"]


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_blocks_join_to_the_whole_file(tmp_path, suffix):
    from hapticdesk.files.recording_io import RecordingBlocks

    rec = sample_recording(50)
    path = tmp_path / f"rec{suffix}"
    write_recording(path, rec)
    with RecordingBlocks(path, NAMES, block_rows=7) as reader:
        parts = list(reader.blocks())
    assert [len(p) for p in parts] == [7] * 7 + [1]
    assert np.allclose(np.concatenate([p.wrench for p in parts]), rec.wrench, rtol=1e-9)
    assert np.allclose(np.concatenate([p.extra["true_x"] for p in parts]), rec.extra["true_x"])


def test_a_replay_closed_from_another_thread_ends_cleanly(tmp_path, paper_desk):
    """Ctrl-C closes the source from the main thread while the sensing thread reads the file:
    the reader ends, no 'I/O operation on closed file' from the reading thread."""
    import threading

    from hapticdesk.plugins.replay import open_replay

    path = tmp_path / "rec.csv"
    _csv(path, [_row(i / 1200) for i in range(40_000)])
    source = open_replay(str(path), paper_desk, speed=1.0)
    errors: list[BaseException] = []
    got = []

    def read() -> None:
        try:
            for block in source.blocks():
                got.append(len(block.t))
        except BaseException as err:  # what the sensing thread would report
            errors.append(err)

    thread = threading.Thread(target=read)
    thread.start()
    while not got:
        thread.join(0.01)
    source.close()
    thread.join(5)
    assert not thread.is_alive() and errors == []
    assert 0 < sum(got) < 40_000
    assert source.recording._reader._fh is None  # the file was closed


def test_an_npz_column_cut_short_is_said_once(tmp_path):
    """A member whose header promises more values than it holds: the error named the file
    twice ("rec.npz: not a readable NPZ recording: rec.npz: column `t` ends after …")."""
    import io
    import zipfile

    path = tmp_path / "rec.npz"
    with zipfile.ZipFile(path, "w") as archive:
        for name, column in _npz_columns(8).items():
            member = io.BytesIO()
            np.lib.format.write_array_header_1_0(
                member, {"descr": "<f8", "fortran_order": False, "shape": (12,)}
            )
            member.write(column.astype("<f8").tobytes())
            archive.writestr(f"{name}.npy", member.getvalue())
    with pytest.raises(ConfigError) as caught:
        read_recording(path, NAMES)
    said = str(caught.value)
    assert said.startswith(f"{path}: column `t` ends after 8 of its 12 rows"), said
    assert said.count(str(path)) == 1


@pytest.mark.parametrize(("separator", "name"), [("\t", "tabs"), (";", "semicolons")])
def test_a_recording_not_separated_by_commas_is_told_so(tmp_path, separator, name):
    """It was told only the columns it lacked: all of them, `t` first."""
    path = tmp_path / "rec.csv"
    path.write_text(
        HEADER.replace(",", separator) + "\n" + _row(0.0).replace(",", separator) + "\n"
    )
    with pytest.raises(
        ConfigError,
        match=rf"rec\.csv:1: missing column\(s\) t, .*separated by {name}\? expected commas\)$",
    ):
        read_recording(path, NAMES)
