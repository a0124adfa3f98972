"""Recordings: CSV and NPZ round trips, missing columns named, extra columns kept apart."""

import numpy as np
import pytest

from hapticdesk.files.recording import Recording, read_recording, write_recording
from hapticdesk.files.yamlfile import ConfigError

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


def test_not_a_number_is_an_error(tmp_path):
    path = tmp_path / "rec.csv"
    write_recording(path, sample_recording(3))
    path.write_text(path.read_text().replace("\n0", "\nabc", 1))
    with pytest.raises(ConfigError, match="not a number"):
        read_recording(path, NAMES)
