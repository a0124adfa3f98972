"""``record`` from a live source: read until Ctrl-C or ``--seconds``, the samples kept in
memory (:func:`capture_live`, any source: a board on a serial line, a plugin's); a CAN bus
(:func:`capture_bus`) also hands every raw frame, for a log output, to python-can's logger on
the bus reader's thread (a log the disk cannot hold is removed, the frames counted)."""

from __future__ import annotations

import argparse
import contextlib
import sys
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hapticdesk.commands.output_path import cannot_write, remove_partial
from hapticdesk.errors import ConfigError
from hapticdesk.files.profile import DeskProfile
from hapticdesk.runtime.source import Source


@dataclass(frozen=True)
class LiveCapture:
    """What a live source gave until it was stopped: samples ``t`` (k,), ``wrench`` (k, S, 6)
    or (k, C), ``accel`` (k, A) where the source carries accelerometers, and the error that
    stopped it early, if one did."""

    t: np.ndarray
    wrench: np.ndarray
    accel: np.ndarray | None
    stopped_by: ConfigError | None


def capture_live(source: Source, seconds: float | None) -> LiveCapture:
    """Read ``source`` until Ctrl-C, ``seconds`` or an error that stops it (kept: what came
    before); the source is closed."""
    ts: list[np.ndarray] = []
    ws: list[np.ndarray] = []
    accs: list[np.ndarray] = []
    stopped_by: ConfigError | None = None
    timer = None
    if seconds is not None:
        timer = threading.Timer(seconds, source.close)
        timer.daemon = True
        timer.start()
    try:
        for block in source.blocks():
            if len(block.t):
                ts.append(block.t)
                ws.append(block.wrench)
                if block.accel is not None:
                    accs.append(block.accel)
    except KeyboardInterrupt:
        pass  # Ctrl-C is how a live recording ends
    except ConfigError as err:  # a silent sensor with `stop`, a lost device: keep what we have
        stopped_by = err
    finally:
        if timer is not None:
            timer.cancel()
        source.close()
    if not ts:
        return LiveCapture(np.zeros(0), np.zeros((0, 0)), None, stopped_by)
    # (accelerometer readings only where every block carried them: all of them or none)
    accel = np.concatenate(accs) if len(accs) == len(ts) else None
    return LiveCapture(np.concatenate(ts), np.concatenate(ws), accel, stopped_by)


@dataclass(frozen=True)
class BusCapture:
    """What a bus gave: samples ``t`` (k,) and ``wrench`` (k, S, 6), the accelerometers'
    readings (k, A) where the desk's boards sent them (else None), the source's problem
    lines (the totals first), the frames logged (None when no log was written) and the error
    that stopped it early, if one did."""

    t: np.ndarray
    wrench: np.ndarray
    accel: np.ndarray | None
    problems: list[str]
    frames: int | None
    stopped_by: ConfigError | None


class _FrameLog:
    """Raw frames into a python-can logger, from the bus reader's thread: a log that cannot
    be written (a full disk) is said once and dropped, and the frames from then on counted,
    but the reader goes on."""

    def __init__(self, output: Path, writer: Any) -> None:
        self.output = output
        self.writer = writer
        self.lock = threading.Lock()
        self.frames = 0
        self.lost_frames = 0
        self.write_failed: OSError | None = None

    def sink(self, messages: list[Any]) -> None:
        with self.lock:
            if self.writer is None:
                self.lost_frames += len(messages) if self.write_failed is not None else 0
                return
            try:
                for msg in messages:
                    self.writer.on_message_received(msg)
            except OSError as err:
                self.write_failed = err
                self.lost_frames += len(messages)
                print(f"hapticdesk record: {cannot_write(self.output, err)}", file=sys.stderr)
                with contextlib.suppress(OSError):
                    self.writer.stop()
                self.writer = None
                return
            self.frames += len(messages)

    def stop(self) -> None:
        with self.lock:
            if self.writer is not None:
                try:
                    self.writer.stop()
                except OSError as err:  # (its last buffer: the disk is full)
                    self.write_failed = err
                self.writer = None

    def check(self) -> None:
        """Raise if the log could not be written (the partial log removed)."""
        if self.write_failed is not None:
            remove_partial(self.output)
            raise ConfigError(
                str(self.output),
                f"cannot write: {self.write_failed.strerror or self.write_failed} "
                f"({self.frames} frames written, {self.lost_frames} more not; the partial log "
                "was removed)",
            )


def capture_bus(
    args: argparse.Namespace, profile: DeskProfile, output: Path, raw: bool
) -> BusCapture:
    """Read the bus ``args.source`` until Ctrl-C, ``args.seconds`` or an error that stops it;
    ``raw``: log every frame to ``output`` as well."""
    import can

    from hapticdesk.canbus.source import open_can_source

    log: _FrameLog | None = None
    if raw:
        try:
            log = _FrameLog(output, can.Logger(str(output)))
        except (OSError, ValueError) as err:
            raise ConfigError(str(output), f"cannot write: {err}") from None
    options: dict[str, Any] = {"frame_sink": log.sink if log is not None else None}
    if args.bitrate:
        options["bitrate"] = args.bitrate
    try:
        source = open_can_source(args.source, profile, **options)
    except BaseException:
        if log is not None:
            log.stop()
        raise
    try:
        live = capture_live(source, args.seconds)
    finally:
        if log is not None:
            log.stop()
    if log is not None:
        log.check()
    wrench = live.wrench if len(live.t) else np.zeros((0, len(profile.sensors), 6))
    frames = log.frames if log is not None else None
    return BusCapture(live.t, wrench, live.accel, source.stats.summary(), frames, live.stopped_by)
