"""``hapticdesk plot REC --desk D -o FILE.png [--method M] [--start S --end E]`` (or
``plot FILE.c3d [--plate N] -o FILE.png``: the plate is the desk, drawn in its own frame): a PNG
of a recording — force over time, the paper's D_er and D_ed, and the contact trace on the desk
outline (estimate coloured by candidate, truth as a line where the recording has it), like
the paper's Fig. 7 and Fig. 13. Needs matplotlib (``pip install 'hapticdesk[plot]'``)."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

from hapticdesk.commands.recording_input import add_recording_arguments, load_input
from hapticdesk.errors import ConfigError
from hapticdesk.files.profile import METHODS


def configure(parser: argparse.ArgumentParser) -> None:
    add_recording_arguments(parser)
    parser.add_argument("-o", "--output", required=True, help="PNG file to write")
    parser.add_argument("--method", choices=METHODS, help="override the profile's method")
    parser.add_argument("--start", type=float, metavar="S", help="first second to draw")
    parser.add_argument("--end", type=float, metavar="E", help="last second to draw")
    parser.add_argument("--json", action="store_true", help="print a JSON summary")


def run(args: argparse.Namespace) -> int:
    output = Path(args.output)
    if output.suffix.lower() != ".png":
        raise ConfigError(
            str(output), f"the plot is a PNG: expected a .png file, found {output.suffix!r}"
        )
    for flag, value in (("--start", args.start), ("--end", args.end)):
        if value is not None and not math.isfinite(value):
            raise ConfigError(flag, f"must be a finite number of seconds, found {value}")
    if args.start is not None and args.end is not None and not args.end > args.start:
        raise ConfigError(
            "--end", f"must be after --start ({args.start:g} s), found {args.end:g} s"
        )
    given = load_input(args)
    profile, recording = given.profile, given.recording
    if len(recording.t) == 0:  # (a header alone; the plot would not know the file's name)
        raise ConfigError(str(args.recording), "the recording holds no samples")
    from hapticdesk.analysis.plotting import plot_recording  # matplotlib only when plotting

    summary = plot_recording(
        profile,
        recording,
        output,
        method=args.method,
        start_s=args.start,
        end_s=args.end,
        title=f"{Path(args.recording).name} on desk {profile.name}"
        + (" (the plate's frame, seen from above)" if given.plate is not None else ""),
    )
    size_kb = output.stat().st_size / 1024
    if args.json:
        info = dict(summary.__dict__)
        info["bytes"] = output.stat().st_size
        print(json.dumps(info))
    else:
        by_source = ", ".join(f"{n} {c}" for n, c in summary.located.items() if c)
        print(
            f"wrote {output} ({size_kb:.0f} kB): {summary.start_s:.2f}–{summary.end_s:.2f} s, "
            f"{summary.samples} samples, {summary.contact_samples} in contact, "
            f"{summary.located_samples} located{f' ({by_source})' if by_source else ''}"
            f"{', with truth' if summary.truth else ''} ({summary.method})"
        )
    return 0
