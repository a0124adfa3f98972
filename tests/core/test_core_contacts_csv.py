"""`hapticdesk contacts -o`: the CSV of DESIGN.md, written a column at a time, is the text a
``csv.writer`` row by row makes (the way it was written before)."""

from __future__ import annotations

import csv
import dataclasses
import io

import numpy as np

from hapticdesk.commands.contacts import HEADER, write_contacts_csv
from hapticdesk.estimator.contacts import PHASE_NAMES, SOURCE_NAMES, ContactBlock
from hapticdesk.files.profile_reader import load_profile


def row_by_row(block: ContactBlock, names: list[str]) -> str:
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(HEADER)
    for r in np.flatnonzero(block.in_contact).tolist():
        pos = ["", "", "", ""]
        if block.located[r]:
            pos = [f"{block.x[r]:.6f}", f"{block.y[r]:.6f}", f"{block.z[r]:.6f}"]
            pos.append(names[block.surface[r]])
        writer.writerow(
            [
                f"{block.t[r]:.6f}",
                *pos,
                f"{block.force_n[r]:.4f}",
                SOURCE_NAMES[block.source[r]],
                PHASE_NAMES[block.phase[r]],
            ]
        )
    return out.getvalue()


def test_the_columns_are_the_rows_a_csv_writer_writes() -> None:
    desk = load_profile("kitamura2017-shelf")
    # a name with a comma, a quote or a line end stays one cell, quoted as csv quotes it
    named = ('top, "front"', "shelf\nboard")
    surfaces = tuple(
        dataclasses.replace(s, name=n) for s, n in zip(desk.surfaces, named, strict=True)
    )
    desk = dataclasses.replace(desk, surfaces=surfaces)
    rng = np.random.default_rng(3)
    k = 500
    block = ContactBlock.blank(np.arange(k) / 1200.0)
    block.in_contact[:] = rng.random(k) < 0.7
    block.located[:] = block.in_contact & (rng.random(k) < 0.6)
    block.surface[:] = np.where(block.located, rng.integers(0, len(surfaces), k), -1)
    for name in ("x", "y", "z", "force_n"):
        getattr(block, name)[:] = rng.normal(size=k) * 0.3
    block.source[:] = np.where(block.located, rng.integers(1, 4, k), 0)
    block.phase[:] = np.where(block.in_contact, rng.integers(1, 4, k), 0)
    out = io.StringIO()
    assert write_contacts_csv(out, block, desk) == int(block.in_contact.sum())
    assert out.getvalue() == row_by_row(block, [s.name for s in surfaces])
    rows = list(csv.reader(io.StringIO(out.getvalue())))
    assert rows[0] == HEADER and all(len(r) == len(HEADER) for r in rows)
    assert {r[4] for r in rows[1:]} == {'top, "front"', "shelf\nboard", ""}


def test_rows_the_columns_are_not_sure_of_are_written_by_python_in_their_places() -> None:
    desk = load_profile("kitamura2017")
    k = 300
    block = ContactBlock.blank(np.arange(k) / 128.0)  # a tie at 6 decimals every other row
    block.in_contact[:] = True
    block.located[::3] = True
    block.surface[block.located] = 0
    block.x[:] = np.where(np.arange(k) % 7 == 0, 1e300, 0.25)  # too large for the columns
    block.force_n[:] = np.linspace(-3.0, 3.0, k)
    block.force_n[5] = np.nan
    block.source[block.located] = 1
    block.phase[:] = 2
    out = io.StringIO()
    write_contacts_csv(out, block, desk)
    assert out.getvalue() == row_by_row(block, [s.name for s in desk.surfaces])
