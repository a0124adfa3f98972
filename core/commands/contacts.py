"""``hapticdesk contacts REC --desk DESK [-o OUT.csv] [--method M] [--json]`` (docs: CLI), and
``hapticdesk contacts FILE.c3d [--plate N] -o OUT.csv``: a C3D file's force plate is its own
desk, and the contacts' x, y, z are metres in the file's lab frame (docs/forceplates.md)."""

from __future__ import annotations

import argparse
import csv
import io
import json
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, TextIO

import numpy as np

from hapticdesk.commands.output_path import cannot_write, check_output_path
from hapticdesk.commands.recording_input import add_recording_arguments, load_input
from hapticdesk.estimator import ContactEstimator
from hapticdesk.estimator.contacts import FLAG_NAMES, PHASE_NAMES, SOURCE_NAMES, ContactBlock
from hapticdesk.estimator.inertia import accelerometer_readings
from hapticdesk.files.csv_cells import PAD, fixed_point, join_rows, labels
from hapticdesk.files.profile import METHODS, DeskProfile

if TYPE_CHECKING:
    from hapticdesk.files.forceplate import PlateDesk

HEADER = ["t", "x", "y", "z", "surface", "force_n", "source", "phase"]
WRITE_ROWS = 65_536  # rows built at a time (~8 MB of text): memory flat for long recordings


def configure(parser: argparse.ArgumentParser) -> None:
    add_recording_arguments(parser)
    parser.add_argument("-o", "--output", help="contacts CSV to write ('-' for standard output)")
    parser.add_argument("--method", choices=METHODS, help="override the profile's method")
    parser.add_argument("--json", action="store_true", help="print a JSON summary")


def write_contacts_csv(out: TextIO, block: ContactBlock, profile: DeskProfile) -> int:
    """One row per sample in contact; position columns empty where not located.

    The text is built a block of rows at a time from the columns
    (:mod:`hapticdesk.files.csv_cells`), the same bytes a format per row writes; the few rows
    the columns cannot be sure of (a value at a rounding tie, too large, not finite) are
    formatted by Python in their places. A minute of the paper's experiment, 49,875 rows:
    0.026 s of CPU, 0.080 s a format per row, 0.145 s a format per cell."""
    rows = np.flatnonzero(block.in_contact)
    # a surface's name quoted as the csv module quotes it (a comma in a name stays one cell)
    names = [_csv_cell(s.name) for s in profile.surfaces]
    out.write(",".join(HEADER) + "\n")
    for first in range(0, len(rows), WRITE_ROWS):
        out.write(_contact_rows(block, rows[first : first + WRITE_ROWS], names))
    return len(rows)


def _contact_rows(block: ContactBlock, rows: np.ndarray, names: list[str]) -> str:
    """The CSV lines of the samples ``rows`` (HEADER's columns)."""
    located = block.located[rows]
    t, force = fixed_point(block.t[rows], 6), fixed_point(block.force_n[rows], 4)
    x, y, z = (fixed_point(c[rows], 6) for c in (block.x, block.y, block.z))
    surface = labels([*names, ""], np.where(located, block.surface[rows], len(names)))
    source = labels(SOURCE_NAMES, block.source[rows])
    phase = labels(PHASE_NAMES, block.phase[rows])
    where = (x, y, z, surface)
    for cells in where:
        cells.chars[~located] = PAD  # (not located: empty cells)
    exact = t.exact & force.exact & source.exact & phase.exact
    exact &= ~located | (x.exact & y.exact & z.exact & surface.exact)
    columns = [c.chars for c in (t, *where, force, source, phase)]
    joined = join_rows(columns, exact)
    # the rows the columns were not sure of, by a % format each, in their places
    pieces, done = [], 0
    for i in np.flatnonzero(~exact).tolist():
        start = int(joined.starts[i])
        pieces += [joined.text[done:start], _row_text(block, int(rows[i]), names).encode()]
        done = start
    pieces.append(joined.text[done:])
    return b"".join(pieces).decode("utf-8")


def _row_text(block: ContactBlock, row: int, names: list[str]) -> str:
    """One sample's CSV line, formatted by Python."""
    t, force = block.t[row], block.force_n[row]
    source, phase = SOURCE_NAMES[block.source[row]], PHASE_NAMES[block.phase[row]]
    if not block.located[row]:
        return f"{t:.6f},,,,,{force:.4f},{source},{phase}\n"
    x, y, z, surface = block.x[row], block.y[row], block.z[row], names[block.surface[row]]
    return f"{t:.6f},{x:.6f},{y:.6f},{z:.6f},{surface},{force:.4f},{source},{phase}\n"


def in_lab_frame(block: ContactBlock, plate: PlateDesk) -> ContactBlock:
    """The block with its located points taken from the plate's desk frame to the C3D
    file's lab frame (metres; PlateDesk.to_lab, with a Kistler plate's FPCOPPOLY)."""
    lab = plate.to_lab(np.stack([block.x, block.y, block.z], axis=1)[block.located])
    x, y, z = block.x.copy(), block.y.copy(), block.z.copy()
    x[block.located], y[block.located], z[block.located] = lab[:, 0], lab[:, 1], lab[:, 2]
    return replace(block, x=x, y=y, z=z)


def _csv_cell(text: str) -> str:
    # (with the writer's own line end: the csv module quotes the line ends it knows of)
    buffer = io.StringIO()
    csv.writer(buffer, lineterminator="\n").writerow([text])
    return buffer.getvalue()[:-1]


def summary(block: ContactBlock, seconds: float, method: str) -> dict[str, object]:
    """The ``--json`` summary (docs/reference/files.md: at least samples, contact_samples, touches,
    estimate_seconds, samples_per_s)."""
    k = len(block)
    starts = np.count_nonzero(block.in_contact[1:] & ~block.in_contact[:-1]) if k else 0
    touches = int(starts + (1 if k and block.in_contact[0] else 0))
    flags = {name: int(np.count_nonzero(block.flags & bit)) for bit, name in FLAG_NAMES.items()}
    return {
        "method": method,
        "samples": k,
        "contact_samples": int(np.count_nonzero(block.in_contact)),
        "located_samples": int(np.count_nonzero(block.located)),
        "touches": touches,
        "estimate_seconds": round(seconds, 6),
        "samples_per_s": round(k / seconds, 1) if seconds > 0 else None,
        "flagged": flags,
    }


#: what a flag that keeps a sample from any contact says of it (docs/reference/files.md)
FLAGS_SAID = {
    "nan": "held NaN or an infinite value",
    "saturated": "were at or beyond a sensor's range",
    "time_back": "were not after the sample before",
    "stuck": "repeated one reading",
    "not_tared": "came before the desk was tared, which it never was (the tare needs a still "
    "desk and whole samples)",
}


def why_nothing(info: dict[str, object]) -> str | None:
    """Why a recording gave no contact, when most of its samples were flagged (a warning
    for the user; ``None`` when it has samples in contact, none, or few flagged)."""
    samples, flagged = info["samples"], info["flagged"]
    assert isinstance(samples, int) and isinstance(flagged, dict)
    if not samples or info["contact_samples"]:
        return None
    said = [
        f"{flagged[name]:,} {text}"
        for name, text in FLAGS_SAID.items()
        # (the tare's own second is never tared: only a desk never tared is said)
        if flagged.get(name, 0) == samples or name != "not_tared" and flagged[name] * 2 > samples
    ]
    if not said:
        return None
    return f"no contact found: of its {samples:,} samples, " + "; ".join(said)


def run(args: argparse.Namespace) -> int:
    output = Path(args.output) if args.output and args.output != "-" else None
    if output is not None:  # before the work: a wrong name is not found after it
        check_output_path(
            output, str(output), what="the contacts file", reads={"the recording": args.recording}
        )
    given = load_input(args)
    profile, recording = given.profile, given.recording
    estimator = ContactEstimator(profile, method=args.method)
    start = time.perf_counter()
    accel = accelerometer_readings(profile, recording.extra)  # (None: no accelerometer)
    block = estimator.push(recording.t, recording.wrench, accel)  # estimation alone is timed
    seconds = time.perf_counter() - start
    if given.plate is not None:
        block = in_lab_frame(block, given.plate)
    if args.output == "-":
        write_contacts_csv(sys.stdout, block, profile)
    elif output is not None:
        try:
            with output.open("w", encoding="utf-8", newline="") as fh:
                write_contacts_csv(fh, block, profile)
        except OSError as err:
            raise cannot_write(output, err) from None
    info = summary(block, seconds, estimator.method)
    if given.plate is not None:
        info["plate"] = given.plate.plate.number
    info["notices"] = [
        {"t": n.t, "kind": n.kind, "message": n.message}
        for n in estimator.notices
        if n.kind != "drift"
    ]
    if args.json:
        print(json.dumps(info))
    elif args.output != "-":
        print(
            f"{info['samples']} samples, {info['contact_samples']} in contact, "
            f"{info['touches']} touches; {info['samples_per_s']:.0f} samples/s "
            f"({estimator.method})",
            file=sys.stderr,
        )
    # (a refused tare is said as the estimator logs it, once: it was printed twice)
    nothing = why_nothing(info)
    if nothing is not None:  # (a plate whose samples were all flagged said nothing at all)
        print(f"hapticdesk contacts: warning: {args.recording}: {nothing}", file=sys.stderr)
    return 0
