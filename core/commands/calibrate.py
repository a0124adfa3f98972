"""``hapticdesk calibrate REC --desk D --mass-kg M --spot X,Y ... [-o OUT.yaml] [--json]``: fit a
load-cell desk's gains and cell positions to a known weight put on marked spots one after the
other (hapticdesk.analysis.known_weight), check the fit on the spot it left out, and write the
calibrated profile.

``hapticdesk calibrate --desk D --suggest N`` prints N spots (3 to 5) to mark.

Exit status: 0 when the check spot was placed within 5 mm (or there was none to check), 1
when it was not (the profile is written all the same, and the report says so), 2 for a wrong
file, desk or argument.
"""

from __future__ import annotations

import argparse
import json
import math
import re
from datetime import date
from itertools import combinations
from pathlib import Path

from hapticdesk.analysis.calibrated_profile import write_calibrated_profile
from hapticdesk.analysis.known_weight import (
    CHECK_TOLERANCE_M,
    Calibration,
    calibrate,
    load_cell_channels,
    suggested_spots,
)
from hapticdesk.analysis.weight_rests import spots_from_recording
from hapticdesk.commands.output_path import cannot_write, check_output_path
from hapticdesk.errors import ConfigError
from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.profile_reader import load_profile, resolve_profile_path
from hapticdesk.recordings import read_any_recording

MIN_SPOTS, MAX_SPOTS = 3, 5
#: how far beyond the top's outline a spot may be (a mark on its edge, measured roughly)
SPOT_MARGIN_M = 0.02
#: the least distance between two spots
MIN_SPOT_DISTANCE_M = 0.02
#: what argparse takes for a value, not an option, though it starts with "-": a negative
#: number, and a spot that starts with one (``--spot -0.33,-0.18``, as the guide and
#: ``--suggest`` write it; before Python 3.13 argparse saw an option there and said
#: "argument --spot: expected one argument"). This command has no option that looks so.
NEGATIVE_VALUE = re.compile(r"^-\.?\d")


def configure(parser: argparse.ArgumentParser) -> None:
    parser._negative_number_matcher = NEGATIVE_VALUE  # (argparse's own, for this parser)
    parser.add_argument(
        "recording",
        nargs="?",
        help="recording of the weight put on each spot in turn and lifted off between them",
    )
    parser.add_argument("--desk", required=True, help="desk profile name or path (load cells)")
    parser.add_argument("--mass-kg", type=float, help="the known weight's mass, kg")
    parser.add_argument(
        "--spot",
        action="append",
        default=[],
        metavar="X,Y",
        help="a marked spot, desk x,y in metres, in the order the weight went there (3 to 5)",
    )
    parser.add_argument(
        "--check",
        default="last",
        metavar="N",
        help="the spot (from 1) the fit leaves out and is checked on: last (default), a "
        "number, or none (fit on all); with 3 spots there is none",
    )
    parser.add_argument("-o", "--output", help="write the calibrated profile here (.yaml)")
    parser.add_argument(
        "--suggest", type=int, metavar="N", help="print N spots (3 to 5) to mark, and stop"
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def _spot(text: str) -> tuple[float, float]:
    parts = text.replace(" ", "").split(",")
    try:
        x, y = (float(p) for p in parts)
    except ValueError:
        raise ConfigError(
            "--spot", f"expected X,Y in metres (for example 0.2,-0.1), found {text!r}"
        ) from None
    if not (abs(x) < 10 and abs(y) < 10):
        raise ConfigError("--spot", f"expected a spot on the desk, in metres, found {text!r}")
    return x, y


def run(args: argparse.Namespace) -> int:
    profile = load_profile(args.desk)
    load_cell_channels(profile)
    if args.suggest is not None:
        if not MIN_SPOTS <= args.suggest <= MAX_SPOTS:
            raise ConfigError("--suggest", f"mark {MIN_SPOTS} to {MAX_SPOTS} spots")
        spots = suggested_spots(profile, args.suggest)
        if args.json:
            print(json.dumps({"spots_m": spots.round(4).tolist()}))
        else:
            for k, (x, y) in enumerate(spots, 1):
                print(f"spot {k}: x {x:+.3f} m, y {y:+.3f} m")
        return 0
    if args.recording is None:
        raise ConfigError("calibrate", "give the recording of the weight (or --suggest N)")
    if args.mass_kg is None:
        raise ConfigError("--mass-kg", "give the known weight's mass in kg")
    points = [_spot(text) for text in args.spot]
    if not MIN_SPOTS <= len(points) <= MAX_SPOTS:
        raise ConfigError(
            "--spot",
            f"give {MIN_SPOTS} to {MAX_SPOTS} spots (--spot X,Y each), found {len(points)}",
        )
    _spots_on_the_top(profile, points)
    check_index = _check_index(args.check, len(points))
    output = Path(args.output) if args.output else None
    if output is not None:
        check_output_path(output, str(output), (".yaml", ".yml"), "the calibrated profile")
    recording = read_any_recording(args.recording, profile)
    spots = spots_from_recording(profile, recording.t, recording.channels, points, args.mass_kg)
    result = calibrate(profile, spots, args.mass_kg, check_index=check_index)
    if output is not None:
        header = profile_header(result, args.mass_kg, len(points))
        source = resolve_profile_path(args.desk)
        try:
            write_calibrated_profile(source, result.fit, output, header)
        except OSError as err:
            raise cannot_write(output, err) from None
    if args.json:
        info = result.to_dict()
        info.update(desk=profile.name, mass_kg=args.mass_kg, output=args.output)
        print(json.dumps(info))
    else:
        print(format_report(result, args.output))
    return 0 if result.passed else 1


def _spots_on_the_top(profile: DeskProfile, points: list[tuple[float, float]]) -> None:
    """Refuse a spot off the desk's top (beyond its outline's extent and
    :data:`SPOT_MARGIN_M`) and two spots at one place: the fit took a spot 5 m off a 0.5 m
    board, or four at one place, and moved the cells by metres (exit 0 without a check)."""
    top = profile.surfaces[0]  # (load_cell_channels: a horizontal top)
    outline = top.to_desk(top.polygon[:, 0], top.polygon[:, 1])[:, :2]
    low, high = outline.min(axis=0) - SPOT_MARGIN_M, outline.max(axis=0) + SPOT_MARGIN_M
    for k, point in enumerate(points, 1):
        if not ((low <= point) & (point <= high)).all():
            raise ConfigError(
                "--spot",
                f"spot {k} ({point[0]:g}, {point[1]:g}) is off the top of desk {profile.name!r} "
                f"(x {low[0] + SPOT_MARGIN_M:.3f} to {high[0] - SPOT_MARGIN_M:.3f} m, y "
                f"{low[1] + SPOT_MARGIN_M:.3f} to {high[1] - SPOT_MARGIN_M:.3f} m): expected "
                "where the weight sat, desk x,y in metres",
            )
    for i, j in combinations(range(len(points)), 2):
        apart = math.dist(points[i], points[j])
        if apart < MIN_SPOT_DISTANCE_M:
            raise ConfigError(
                "--spot",
                f"spots {i + 1} and {j + 1} are {apart * 1000:.0f} mm apart: expected spots "
                f"at least {MIN_SPOT_DISTANCE_M * 100:g} cm apart (the fit tells the cells "
                "apart by how the readings change from spot to spot)",
            )


def _check_index(text: str, count: int) -> int | None:
    if text == "none" or count < 4:
        return None
    if text == "last":
        return count - 1
    try:
        number = int(text)
    except ValueError:
        number = 0
    if not 1 <= number <= count:
        raise ConfigError("--check", f"expected last, none or 1 to {count}, found {text!r}")
    return number - 1


def profile_header(
    result: Calibration, mass_kg: float, spots: int, by: str = "hapticdesk calibrate"
) -> str:
    """The comment put at the top of a calibrated profile: the weight, the spots, the day,
    what made it (``by``) and how far the check spot was placed."""
    check = result.check
    checked = (
        f"; the check spot placed {check.error_m * 1000:.1f} mm from its mark"
        if check is not None
        else ""
    )
    return (
        f"Calibrated with a {mass_kg:g} kg weight on {spots} spots on {date.today()} "
        f"({by}){checked}.\n"
        "Each cell's gain is its calibration's fz (newtons per unit of its reading)."
    )


def format_report(result: Calibration, output: str | None) -> str:
    """The fit per cell and the checks as text."""
    fit = result.fit
    nominal = fit.nominal_positions()
    lines = [f"{'cell':<12} {'gain':>7} {'x (m)':>8} {'y (m)':>8}  moved"]
    for j, name in enumerate(fit.profile.channel_names()):
        x, y = fit.positions[j]
        moved = float(((fit.positions[j] - nominal[j]) ** 2).sum() ** 0.5)
        lines.append(f"{name:<12} {fit.gains[j]:7.4f} {x:8.4f} {y:8.4f}  {moved * 1000:5.1f} mm")
    lines.append(f"fitted on {fit.spots_used} spots")
    if result.check is not None:
        c = result.check
        verdict = "ok" if result.passed else f"more than {CHECK_TOLERANCE_M * 1000:g} mm: redo"
        lines.append(
            f"check spot ({c.point[0]:.3f}, {c.point[1]:.3f}): placed at "
            f"({c.located[0]:.3f}, {c.located[1]:.3f}), {c.error_m * 1000:.1f} mm off, the "
            f"weight {c.mass_error * 100:+.1f} %: {verdict}"
        )
    if result.leave_one_out:
        worst = max(c.error_m for c in result.leave_one_out)
        lines.append(f"each spot left out in turn: placed within {worst * 1000:.1f} mm")
    if output:
        lines.append(f"wrote {output}")
    return "\n".join(lines)
