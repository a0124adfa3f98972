"""``hapticdesk record --source SPEC --desk D -o FILE [--seconds S]``: record a desk.

SPEC: ``can:INTERFACE:CHANNEL`` (a live bus; ``can`` alone takes the profile's), ``serial:PORT``
(a board on a serial line) or any live source a plugin registers, ``replay:FILE``
(a recording or CAN log, converted) or ``sim:SCENE.yaml`` (a simulated desk). FILE's suffix
chooses what is written: ``.csv``/``.npz`` the decoded samples (the recording format), or
``.asc``/``.blf``/``.log``/``.trc`` the raw CAN frames through python-can's loggers (with the
ATI calibration exchange and polls, so the log decodes on its own). Ctrl-C ends a live
recording and keeps everything recorded so far; a replayed recording with a bad line keeps
the samples before it and exits 1. A live bus is captured by :mod:`.record_bus`.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hapticdesk.commands import bit_rate, seed_number
from hapticdesk.commands.output_path import partial_removed, remove_partial
from hapticdesk.commands.record_bus import capture_bus, capture_live
from hapticdesk.errors import ConfigError
from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.profile_reader import load_profile
from hapticdesk.files.recording import Recording, concat_recordings
from hapticdesk.files.recording_io import RECORDING_SUFFIXES, write_recording
from hapticdesk.recordings import open_recording_blocks

LOG_SUFFIXES = (".asc", ".blf", ".log", ".trc")


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--source",
        required=True,
        help="can:INTERFACE:CHANNEL (or `can` for the profile's bus), serial:PORT (a board), "
        "replay:FILE, sim:SCENE.yaml, or a plugin's kind",
    )
    parser.add_argument("--desk", required=True, help="desk profile name or path")
    parser.add_argument(
        "-o",
        "--output",
        required=True,
        help="samples (.csv, .npz) or raw CAN frames (.asc, .blf, .log, .trc)",
    )
    parser.add_argument(
        "--seconds", type=float, help="stop after this long (default: a live bus until Ctrl-C)"
    )
    parser.add_argument("--bitrate", type=bit_rate, help="CAN bit rate (overrides the profile's)")
    parser.add_argument("--seed", type=seed_number, help="simulation seed (sim: sources)")
    parser.add_argument("--json", action="store_true", help="print a JSON summary")


def run(args: argparse.Namespace) -> int:
    output = Path(args.output)
    suffix = output.suffix.lower()
    if suffix not in RECORDING_SUFFIXES + LOG_SUFFIXES:
        raise ConfigError(
            str(output),
            f"cannot record to {suffix or 'a file without suffix'}; use .csv or .npz (samples) "
            "or .asc, .blf, .log, .trc (raw CAN frames)",
        )
    if args.seconds is not None and not (args.seconds > 0 and np.isfinite(args.seconds)):
        raise ConfigError("--seconds", f"must be a positive number, found {args.seconds}")
    profile = load_profile(args.desk)
    kind, _, argument = args.source.partition(":")
    start = time.perf_counter()
    if kind == "can":
        summary = _record_bus(args, profile, output)
    elif kind in ("replay", "sim"):
        summary = _record_file(kind, argument, args, profile, output)
    else:  # a board on a serial line, or a source a plugin registers
        summary = _record_live(args, profile, output)
    summary["output"] = str(output)
    summary["record_seconds"] = round(time.perf_counter() - start, 3)
    if args.json:
        print(json.dumps(summary))
    else:
        what = f"{summary['frames']} frames, " if "frames" in summary else ""
        print(
            f"wrote {output}: {what}{summary['samples']} samples "
            f"({summary['duration_s']:.2f} s) of desk {profile.name}"
        )
        for line in summary.get("problems", []):
            print(f"  {line}")
    return 1 if summary.get("failed") else 0


def _record_bus(args: argparse.Namespace, profile: DeskProfile, output: Path) -> dict[str, Any]:
    raw = output.suffix.lower() in LOG_SUFFIXES
    capture = capture_bus(args, profile, output, raw)
    if not raw:
        extra = _accel_columns(profile, capture.accel)
        _write(output, Recording(capture.t, capture.wrench, profile.sensor_names, extra))
    summary = _summary(capture.t, capture.problems)
    if capture.frames is not None:
        summary["frames"] = capture.frames
    if capture.stopped_by is not None:
        print(f"hapticdesk record: stopped: {capture.stopped_by}", file=sys.stderr)
        summary["stopped"] = str(capture.stopped_by)
    return summary


def _record_live(args: argparse.Namespace, profile: DeskProfile, output: Path) -> dict[str, Any]:
    """Any other live source the registry knows (``serial:PORT``, a plugin's), its decoded
    samples (and accelerometer readings, where it carries them) into a recording."""
    from hapticdesk.plugin_loading import load_registry
    from hapticdesk.runtime.source_spec import open_source, parse_source_spec

    kind, _ = parse_source_spec(args.source)
    if output.suffix.lower() in LOG_SUFFIXES:
        raise ConfigError(
            "--output",
            f"raw CAN frames come only from a can: source; record {kind}: to .csv or .npz",
        )
    registry = load_registry()
    source = open_source(args.source, profile, registry)
    live = capture_live(source, args.seconds)
    wrench = live.wrench if len(live.t) else np.zeros((0, len(profile.channel_names())))
    extra = _accel_columns(profile, live.accel)
    rec = Recording(live.t, wrench, profile.sensor_names, extra, profile.channel_names())
    _write(output, rec)
    summary = _summary(live.t, ["", *source.summary()])
    if live.stopped_by is not None:
        print(f"hapticdesk record: stopped: {live.stopped_by}", file=sys.stderr)
        summary["stopped"] = str(live.stopped_by)
    return summary


def _accel_columns(profile: DeskProfile, accel: np.ndarray | None) -> dict[str, np.ndarray]:
    """A live source's accelerometer readings (k, A) as the recording's columns of the
    desk's accelerometers (none when it sent none)."""
    columns = profile.accelerometer_columns()
    if accel is None or not columns or accel.shape[1] != len(columns):
        return {}
    return {name: accel[:, i] for i, name in enumerate(columns)}


# --- files and simulations ----------------------------------------------------------------


@dataclass(frozen=True)
class _Read:
    """A replayed or simulated recording, the reader's problem lines (the totals first) and
    the bad line that stopped a replay early, if one did."""

    recording: Recording
    problems: list[str]
    stopped_by: ConfigError | None = None


def _record_file(
    kind: str, argument: str, args: argparse.Namespace, profile: DeskProfile, output: Path
) -> dict[str, Any]:
    if not argument:
        raise ConfigError("--source", f"{kind} needs a file: {kind}:FILE")
    path = Path(argument).expanduser()
    if not path.is_file():
        raise ConfigError("--source", f"{kind}: no such file {argument}")
    raw = output.suffix.lower() in LOG_SUFFIXES
    is_can_log = kind == "replay" and path.suffix.lower() not in RECORDING_SUFFIXES
    if is_can_log and raw:  # a CAN log into another format: frames as they are
        return _copy_can_log(path, args.seconds, profile, output)
    read = _read_file(kind, path, args.seed, profile, is_can_log)
    rec = _first_seconds(read.recording, args.seconds)
    if not raw:
        _write(output, rec)
        return _stopped(_summary(rec.t, read.problems), read.stopped_by, len(rec))
    summary = _summary(rec.t, read.problems)
    summary["frames"] = _encode_to_log(rec, profile, output)
    return _stopped(summary, read.stopped_by, len(rec))


def _read_file(
    kind: str, path: Path, seed: int | None, profile: DeskProfile, is_can_log: bool
) -> _Read:
    """A CAN log decoded, a recording read (up to a bad line) or a scene simulated."""
    if is_can_log:
        from hapticdesk.canbus.logs.desk_samples import decode_can_log

        decoded = decode_can_log(path, profile)
        return _Read(decoded.recording, decoded.stats.summary())
    if kind == "replay":
        rec, stopped_by = _read_until_error(path, profile)
        return _Read(rec, [], stopped_by)
    from hapticdesk.sim import load_scene, simulate

    return _Read(simulate(profile, load_scene(path), seed), [])


def _first_seconds(rec: Recording, seconds: float | None) -> Recording:
    """The first ``seconds`` of ``rec`` (all of it when None)."""
    if seconds is None:
        return rec
    keep = rec.t - rec.t[0] < seconds if len(rec) else np.zeros(0, bool)
    return Recording(
        rec.t[keep],
        rec.wrench[keep],
        rec.sensor_names,
        {k: v[keep] for k, v in rec.extra.items()},
    )


def _copy_can_log(
    path: Path, seconds: float | None, profile: DeskProfile, output: Path
) -> dict[str, Any]:
    """A CAN log's frames written in ``output``'s format, its first ``seconds`` if given."""
    from hapticdesk.canbus.logs.desk_samples import decode_can_log
    from hapticdesk.canbus.logs.formats import read_frames
    from hapticdesk.canbus.logs.writer import write_frames

    first: list[float] = []

    def frames() -> Any:
        for chunk in read_frames(path):
            if seconds is not None and len(chunk):
                if not first:
                    first.append(float(np.nanmin(chunk.t)) if np.isfinite(chunk.t).any() else 0.0)
                chunk = chunk.take(~(chunk.t - first[0] >= seconds))
            yield chunk

    n = _write_frames(output, frames(), write_frames)
    decoded = decode_can_log(output, profile)
    summary = _summary(decoded.recording.t, decoded.stats.summary())
    summary["frames"] = n
    return summary


def _encode_to_log(rec: Recording, profile: DeskProfile, output: Path) -> int:
    """``rec`` encoded as the desk's CAN frames (its calibration exchange first, with polls)
    into the log ``output``; returns the frames written."""
    from hapticdesk.canbus.config_reader import can_config
    from hapticdesk.canbus.frame_encoder import FrameEncoder
    from hapticdesk.canbus.logs.writer import write_frames
    from hapticdesk.estimator.inertia import accelerometer_readings

    encoder = FrameEncoder(can_config(profile), profile)
    t0 = time.time()
    start = encoder.calibration_frames(t0 - 0.01)
    accel = accelerometer_readings(profile, rec.extra)
    body = encoder.encode(rec.t + t0, rec.wrench, polls=True, accel=accel)
    return _write_frames(output, [start, body], write_frames)


def _stopped(summary: dict[str, Any], err: ConfigError | None, kept: int) -> dict[str, Any]:
    """``summary`` of a replay that a bad line stopped (``err``): said, and a failure."""
    if err is not None:
        print(
            f"hapticdesk record: stopped at a bad line: {err}; wrote the {kept} samples before it",
            file=sys.stderr,
        )
        summary["stopped"] = str(err)
        summary["failed"] = True
    return summary


def _read_until_error(path: Path, profile: DeskProfile) -> tuple[Recording, ConfigError | None]:
    """A recording read whole, or the samples before its first bad line (the reader hands
    them out first) and that line's error. A file bad from its first sample (or its header),
    or at another rate than the profile's, is refused: nothing of it was good."""
    parts: list[Recording] = []
    with open_recording_blocks(path, profile) as reader:
        try:
            for block in reader.blocks():
                parts.append(block)
        except ConfigError as err:
            if not parts:
                raise
            return concat_recordings(parts, profile.sensor_names), err
    return concat_recordings(parts, profile.sensor_names), None


def _write_frames(output: Path, frames: Any, write: Any) -> int:
    try:
        return int(write(output, frames))
    except OSError as err:
        remove_partial(output)
        raise partial_removed(output, err) from None


def _write(output: Path, rec: Recording) -> None:
    try:
        write_recording(output, rec)
    except OSError as err:
        remove_partial(output)
        raise partial_removed(output, err) from None


def _summary(t: np.ndarray, problems: list[str]) -> dict[str, Any]:
    return {
        "samples": len(t),
        "duration_s": round(float(t[-1] - t[0]), 6) if len(t) else 0.0,
        "problems": problems[1:],  # the first line is the totals
    }
