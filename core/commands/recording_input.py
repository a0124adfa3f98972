"""The recording a command reads and its desk: ``--desk`` with a recording (.csv, .npz, a CAN
log), or a C3D file whose force plate (``--plate N``, from 1) is the desk when no ``--desk``
is given (:mod:`hapticdesk.files.forceplate`). ``contacts`` and ``plot`` read through here;
``run`` takes :func:`source_desk` for a C3D replay, ``check`` :func:`desk_or_plate`."""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from hapticdesk.errors import ConfigError
from hapticdesk.files.c3d import is_c3d, open_c3d
from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.profile_reader import load_profile
from hapticdesk.files.recording import Recording
from hapticdesk.recordings import read_any_recording

if TYPE_CHECKING:  # (imported where a C3D plate is read: a CSV's contacts need neither)
    from hapticdesk.files.forceplate import PlateDesk


def plate_number(text: str) -> int:
    """An argparse type: a plate's number, from 1 as C3D counts."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected a plate number (1, 2, …), found {text!r}"
        ) from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"plates count from 1, as C3D counts; found {value}")
    return value


def add_recording_arguments(parser: argparse.ArgumentParser) -> None:
    """The recording, ``--desk`` and ``--plate`` arguments of ``contacts`` and ``plot``."""
    parser.add_argument("recording", help="recording (.csv, .npz), CAN log, or C3D file")
    parser.add_argument(
        "--desk", help="desk profile name or path (a .c3d file brings its own: its plate)"
    )
    parser.add_argument(
        "--plate",
        type=plate_number,
        metavar="N",
        help="the C3D file's force plate to read, from 1 as C3D counts (default 1)",
    )


@dataclass(frozen=True)
class RecordingInput:
    """What a command estimates on: the desk, its recording, and for a C3D plate read
    without ``--desk`` the plate's desk (its frame in the lab: ``PlateDesk.to_lab``)."""

    profile: DeskProfile
    recording: Recording
    plate: PlateDesk | None = None


def load_input(args: argparse.Namespace) -> RecordingInput:
    """The desk and recording ``args`` name (ConfigError for a wrong combination)."""
    c3d = is_c3d(args.recording)
    if args.plate is not None and (not c3d or args.desk is not None):
        raise ConfigError(
            "--plate",
            "chooses the force plate of a C3D file read without --desk"
            + (
                "; with --desk the desk's sensors (plate1, plate2, …) name the plates"
                if c3d
                else f", but {args.recording} is not a .c3d file"
            ),
        )
    if args.desk is not None:
        profile = load_profile(args.desk)
        return RecordingInput(profile, read_any_recording(args.recording, profile))
    if not c3d:
        raise ConfigError(
            "--desk",
            f"reading {Path(args.recording).name} needs the desk it was recorded on: give "
            "--desk NAME_OR_PATH (only a .c3d file brings its own, its force plate)",
        )
    from hapticdesk.files.forceplate import plate_desk, read_plate_recording

    file = open_c3d(args.recording)
    desk = plate_desk(file, args.plate or 1)
    recording = read_plate_recording(args.recording, desk.profile, file)
    return RecordingInput(desk.profile, recording, desk)


def source_desk(source: str, plate: int | None, given: str | None = None) -> DeskProfile | None:
    """For ``run``: the desk a C3D replay (``replay:FILE.c3d``) brings, its plate ``plate``
    (default 1), when no desk is ``given`` (--desk); None for any other source (its desk
    comes from --desk or the layout)."""
    # (here, not at the top: it loads the plugin registry, which contacts and plot never use)
    from hapticdesk.runtime.source_spec import parse_source_spec

    kind, argument = parse_source_spec(source)
    c3d = kind == "replay" and is_c3d(argument)
    if plate is not None and (not c3d or given is not None):
        raise ConfigError(
            "--plate",
            "chooses the force plate of a C3D replay (replay:FILE.c3d) without --desk"
            + (f", not of {source}" if not c3d else "; with --desk its sensors name the plates"),
        )
    if not c3d or given is not None:
        return None
    return _plate_profile(argument, plate)


def desk_or_plate(desk: str | None, plate: int | None) -> str | DeskProfile | None:
    """For ``check`` and ``init``: ``--desk`` as given, or for a C3D file its force plate
    ``plate`` (default 1) made a desk, as ``run --source replay:FILE.c3d`` makes it
    (``--plate`` chooses the plate of a C3D ``--desk`` only)."""
    if desk is None or not is_c3d(desk):
        if plate is not None:
            raise ConfigError(
                "--plate", "chooses the force plate of a C3D file given as --desk FILE.c3d"
            )
        return desk
    return _plate_profile(desk, plate)


def _plate_profile(path: str, plate: int | None) -> DeskProfile:
    """The desk a C3D file's force plate ``plate`` (default 1) makes."""
    from hapticdesk.files.forceplate import plate_desk

    return plate_desk(open_c3d(Path(path).expanduser()), plate or 1).profile
