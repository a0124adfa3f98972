"""``hapticdesk record --source SPEC --desk D -o FILE [--seconds S]``: record a desk.

SPEC: ``can:INTERFACE:CHANNEL`` (a live bus; ``can`` alone takes the profile's), ``replay:FILE``
(a recording or CAN log, converted) or ``sim:SCENE.yaml`` (a simulated desk). FILE's suffix
chooses what is written: ``.csv``/``.npz`` the decoded samples (the recording format), or
``.asc``/``.blf``/``.log``/``.trc`` the raw CAN frames through python-can's loggers (with the
ATI calibration exchange and polls, so the log decodes on its own). Ctrl-C ends a live
recording and keeps everything recorded so far; a replayed recording with a bad line keeps
the samples before it and exits 1.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

from hapticdesk.commands import bit_rate, seed_number
from hapticdesk.commands.output_path import cannot_write
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
        help="can:INTERFACE:CHANNEL (or `can` for the profile's bus), replay:FILE, sim:SCENE.yaml",
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
    else:
        raise ConfigError(
            "--source",
            "record reads can:INTERFACE:CHANNEL, replay:FILE or sim:SCENE.yaml, "
            f"found {args.source!r}",
        )
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


# --- a live bus -------------------------------------------------------------------------------


def _record_bus(args: argparse.Namespace, profile: DeskProfile, output: Path) -> dict[str, Any]:
    import can

    from hapticdesk.canbus.source import open_can_source

    raw = output.suffix.lower() in LOG_SUFFIXES
    writer: Any = None
    lock = threading.Lock()
    frames = 0
    lost_frames = 0
    write_failed: OSError | None = None

    def sink(messages: list[Any]) -> None:
        # on the bus reader's thread: a log that cannot be written (a full disk) is said
        # once and dropped, and the frames from then on counted, but the reader goes on
        nonlocal frames, lost_frames, write_failed, writer
        with lock:
            if writer is None:
                lost_frames += len(messages) if write_failed is not None else 0
                return
            try:
                for msg in messages:
                    writer.on_message_received(msg)
            except OSError as err:
                write_failed = err
                lost_frames += len(messages)
                print(f"hapticdesk record: {cannot_write(output, err)}", file=sys.stderr)
                with contextlib.suppress(OSError):
                    writer.stop()
                writer = None
                return
            frames += len(messages)

    if raw:
        try:
            writer = can.Logger(str(output))
        except (OSError, ValueError) as err:
            raise ConfigError(str(output), f"cannot write: {err}") from None
    options: dict[str, Any] = {"frame_sink": sink if raw else None}
    if args.bitrate:
        options["bitrate"] = args.bitrate
    ts: list[np.ndarray] = []
    ws: list[np.ndarray] = []
    stopped_by: BaseException | None = None
    try:
        source = open_can_source(args.source, profile, **options)
    except BaseException:
        if writer is not None:
            writer.stop()
        raise
    timer = None
    if args.seconds is not None:
        timer = threading.Timer(args.seconds, source.close)
        timer.daemon = True
        timer.start()
    try:
        for block in source.blocks():
            ts.append(block.t)
            ws.append(block.wrench)
    except KeyboardInterrupt:
        pass  # Ctrl-C is how a live recording ends
    except ConfigError as err:  # a silent sensor with `stop`, a lost bus: keep what we have
        stopped_by = err
    finally:
        if timer is not None:
            timer.cancel()
        source.close()
        with lock:
            if writer is not None:
                try:
                    writer.stop()
                except OSError as err:  # (its last buffer: the disk is full)
                    write_failed = err
                writer = None
    if write_failed is not None:
        _remove_partial(output)
        raise ConfigError(
            str(output),
            f"cannot write: {write_failed.strerror or write_failed} ({frames} frames written, "
            f"{lost_frames} more not; the partial log was removed)",
        )
    t = np.concatenate(ts) if ts else np.zeros(0)
    wrench = np.concatenate(ws) if ws else np.zeros((0, len(profile.sensors), 6))
    if not raw:
        _write(output, Recording(t, wrench, profile.sensor_names))
    summary = _summary(t, source.stats.summary())
    if raw:
        summary["frames"] = frames
    if stopped_by is not None:
        print(f"hapticdesk record: stopped: {stopped_by}", file=sys.stderr)
        summary["stopped"] = str(stopped_by)
    return summary


# --- files and simulations ----------------------------------------------------------------


def _record_file(
    kind: str, argument: str, args: argparse.Namespace, profile: DeskProfile, output: Path
) -> dict[str, Any]:
    stopped_by: ConfigError | None = None
    if not argument:
        raise ConfigError("--source", f"{kind} needs a file: {kind}:FILE")
    path = Path(argument).expanduser()
    if not path.is_file():
        raise ConfigError("--source", f"{kind}: no such file {argument}")
    raw = output.suffix.lower() in LOG_SUFFIXES
    if kind == "replay" and path.suffix.lower() not in RECORDING_SUFFIXES:
        from hapticdesk.canbus.logs.desk_samples import decode_can_log
        from hapticdesk.canbus.logs.formats import read_frames
        from hapticdesk.canbus.logs.writer import write_frames

        if raw:  # a CAN log into another format: frames as they are
            limit = args.seconds
            first: list[float] = []

            def frames() -> Any:
                for chunk in read_frames(path):
                    if limit is not None and len(chunk):
                        if not first:
                            first.append(
                                float(np.nanmin(chunk.t)) if np.isfinite(chunk.t).any() else 0.0
                            )
                        chunk = chunk.take(~(chunk.t - first[0] >= limit))
                    yield chunk

            n = _write_frames(output, frames(), write_frames)
            decoded = decode_can_log(output, profile)
            summary = _summary(decoded.recording.t, decoded.stats.summary())
            summary["frames"] = n
            return summary
        decoded = decode_can_log(path, profile)
        rec, problems = decoded.recording, decoded.stats.summary()
    elif kind == "replay":
        rec, stopped_by = _read_until_error(path, profile)
        problems = []
    else:
        from hapticdesk.sim import load_scene, simulate

        rec, problems = simulate(profile, load_scene(path), args.seed), []
    if args.seconds is not None:
        keep = rec.t - rec.t[0] < args.seconds if len(rec) else np.zeros(0, bool)
        rec = Recording(
            rec.t[keep],
            rec.wrench[keep],
            rec.sensor_names,
            {k: v[keep] for k, v in rec.extra.items()},
        )
    if not raw:
        _write(output, rec)
        return _stopped(_summary(rec.t, problems), stopped_by, len(rec))
    from hapticdesk.canbus.config_reader import can_config
    from hapticdesk.canbus.frame_encoder import FrameEncoder
    from hapticdesk.canbus.logs.writer import write_frames
    from hapticdesk.estimator.inertia import accelerometer_readings

    encoder = FrameEncoder(can_config(profile), profile)
    t0 = time.time()
    start = encoder.calibration_frames(t0 - 0.01)
    accel = accelerometer_readings(profile, rec.extra)
    body = encoder.encode(rec.t + t0, rec.wrench, polls=True, accel=accel)
    n = _write_frames(output, [start, body], write_frames)
    summary = _summary(rec.t, problems)
    summary["frames"] = n
    return _stopped(summary, stopped_by, len(rec))


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
        _remove_partial(output)
        raise _partial_removed(output, err) from None


def _write(output: Path, rec: Recording) -> None:
    try:
        write_recording(output, rec)
    except OSError as err:
        _remove_partial(output)
        raise _partial_removed(output, err) from None


def _remove_partial(output: Path) -> None:
    """A recording cut short by a full disk is removed: a reader would take the part for
    the whole (b5a43bd left truncated recordings behind)."""
    with contextlib.suppress(OSError):
        output.unlink(missing_ok=True)


def _partial_removed(output: Path, err: OSError) -> ConfigError:
    return ConfigError(
        str(output), f"cannot write: {err.strerror or err} (the partial file was removed)"
    )


def _summary(t: np.ndarray, problems: list[str]) -> dict[str, Any]:
    return {
        "samples": len(t),
        "duration_s": round(float(t[-1] - t[0]), 6) if len(t) else 0.0,
        "problems": problems[1:],  # the first line is the totals
    }
