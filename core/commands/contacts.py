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
from hapticdesk.files.profile import METHODS, DeskProfile

if TYPE_CHECKING:
    from hapticdesk.files.forceplate import PlateDesk

HEADER = ["t", "x", "y", "z", "surface", "force_n", "source", "phase"]


def configure(parser: argparse.ArgumentParser) -> None:
    add_recording_arguments(parser)
    parser.add_argument("-o", "--output", help="contacts CSV to write ('-' for standard output)")
    parser.add_argument("--method", choices=METHODS, help="override the profile's method")
    parser.add_argument("--json", action="store_true", help="print a JSON summary")


def write_contacts_csv(out: TextIO, block: ContactBlock, profile: DeskProfile) -> int:
    """One row per sample in contact; position columns empty where not located.

    Each row formatted by one ``%`` format of its own (located or not), from columns taken
    out of the block once, not a ``csv.writer`` call per row nor a format per cell: the same
    text in half the time of a format per cell (a minute of the paper's experiment, 49,875
    rows: 0.145 -> 0.078 s of CPU; the writing had taken longer than the estimation)."""
    rows = np.flatnonzero(block.in_contact)
    located = block.located[rows]
    # a surface's name quoted as the csv module quotes it (a comma in a name stays one cell)
    names = [_csv_cell(s.name) for s in profile.surfaces] or [""]
    surfaces = [names[i] for i in np.where(located, block.surface[rows], 0).tolist()]
    t, x, y, z, force = (
        c[rows].tolist() for c in (block.t, block.x, block.y, block.z, block.force_n)
    )
    source = np.asarray(SOURCE_NAMES, dtype=object)[block.source[rows]].tolist()
    phase = np.asarray(PHASE_NAMES, dtype=object)[block.phase[rows]].tolist()
    at = "%.6f,%.6f,%.6f,%.6f,%s,%.4f,%s,%s\n".__mod__  # (HEADER's columns)
    nowhere = "%.6f,,,,,%.4f,%s,%s\n".__mod__
    out.write(",".join(HEADER) + "\n")
    columns = zip(located.tolist(), t, x, y, z, surfaces, force, source, phase, strict=True)
    out.writelines(
        [
            at((ti, xi, yi, zi, si, fi, so, ph)) if ok else nowhere((ti, fi, so, ph))
            for ok, ti, xi, yi, zi, si, fi, so, ph in columns
        ]
    )
    return len(rows)


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


def run(args: argparse.Namespace) -> int:
    output = Path(args.output) if args.output and args.output != "-" else None
    if output is not None:  # before the work: a wrong name is not found after it
        check_output_path(output, str(output), what="the contacts file")
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
    return 0
