"""The ``replay`` source: a recording (CSV/NPZ) or a CAN log played back on its own clock.

    hapticdesk run --layout L --source replay:session.csv --speed 1    # real time
    hapticdesk run --layout L --source replay:session.npz --speed 0    # as fast as possible
    hapticdesk run --layout L --source replay:session.asc              # a CAN log

Blocks of ~12 samples (10 ms at 1.2 kHz) are handed out when their last sample's time has
come on the wall clock (scaled by ``speed``), as a live source would deliver them. Files are
read in blocks of :data:`~hapticdesk.files.recording.BLOCK_ROWS` samples as they are played,
so memory stays flat whatever the file's size. CAN logs are read by
:mod:`hapticdesk.canbus.logs`, imported only for them.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.recording import RECORDING_SUFFIXES, Recording, RecordingBlocks
from hapticdesk.files.yamlfile import ConfigError
from hapticdesk.hookspecs import hookimpl
from hapticdesk.runtime.source import Source, WrenchBlock

BLOCK_SIZE = 12


class Pacer:
    """Holds blocks back until their sample time has come: wall = start + (t - t0) / speed.

    ``speed`` 0 never waits. :meth:`wall_time` maps a sample time to the wall clock
    (``time.perf_counter``), which is how the latency benchmark knows when a tap really ended.
    """

    def __init__(self, speed: float, stop: threading.Event) -> None:
        if speed < 0:
            raise ConfigError(
                "--speed", f"--speed must be 0 (as fast as possible) or more, found {speed:g}"
            )
        self.speed = speed
        self._stop = stop
        self.t0: float | None = None
        self.started_at: float | None = None

    def wait_for(self, t: float) -> bool:
        """Wait until sample time ``t`` has come; False when stopped meanwhile."""
        if self.t0 is None:
            self.t0, self.started_at = t, time.perf_counter()
        if self.speed == 0:
            return not self._stop.is_set()
        delay = self.wall_time(t) - time.perf_counter()
        if delay > 0:
            return not self._stop.wait(delay)
        return not self._stop.is_set()

    def wall_time(self, t: float) -> float:
        assert self.t0 is not None and self.started_at is not None, "not started"
        return self.started_at + (t - self.t0) / (self.speed or float("inf"))


class RecordingSource(Source):
    """A recording handed out in blocks of ``block_size`` samples, as fast as they are read.

    ``recording``: a whole :class:`Recording`, or a :class:`RecordingBlocks` streamed from its
    file one read block at a time.
    """

    def __init__(
        self,
        recording: Recording | RecordingBlocks,
        sample_rate_hz: float,
        *,
        block_size: int = BLOCK_SIZE,
    ) -> None:
        self.recording = recording
        self.sensor_names = list(recording.sensor_names)
        self.sample_rate_hz = sample_rate_hz
        self.block_size = block_size

    def blocks(self) -> Iterator[WrenchBlock]:
        parts = self.recording.blocks() if isinstance(self.recording, RecordingBlocks) else None
        for rec in parts if parts is not None else [self.recording]:
            assert isinstance(rec, Recording)
            for start in range(0, len(rec), self.block_size):
                end = min(start + self.block_size, len(rec))
                truth = {k: np.asarray(v[start:end]) for k, v in rec.extra.items()} or None
                yield WrenchBlock(rec.t[start:end], rec.wrench[start:end], truth)

    def close(self) -> None:
        if isinstance(self.recording, RecordingBlocks):
            self.recording.close()


class PacedSource(Source):
    """A finite source (recording, simulation, CAN log) with its blocks held back until their
    last sample's time has come, as a live source would deliver them."""

    def __init__(self, inner: Source, speed: float) -> None:
        self.inner = inner
        self.sensor_names = list(inner.sensor_names)
        self.sample_rate_hz = inner.sample_rate_hz
        self._stop = threading.Event()
        self.pacer = Pacer(speed, self._stop)

    def blocks(self) -> Iterator[WrenchBlock]:
        for block in self.inner.blocks():
            if len(block.t) and not self.pacer.wait_for(float(block.t[-1])):
                return
            yield block

    def close(self) -> None:
        self._stop.set()
        self.inner.close()


def open_replay(
    argument: str, profile: DeskProfile, *, speed: float = 1.0, **options: Any
) -> Source:
    """``replay:FILE``: a CSV/NPZ recording, or a CAN log by any other suffix."""
    if not argument:
        raise ConfigError("--source", "replay needs a file: replay:FILE.csv, .npz or a CAN log")
    path = Path(argument).expanduser()
    if not path.is_file():
        raise ConfigError("--source", f"replay: no such file {argument}")
    if path.suffix.lower() in RECORDING_SUFFIXES:
        recording = RecordingBlocks(path, profile.sensor_names)
        if recording.is_empty():
            recording.close()
            raise ConfigError(str(path), "the recording holds no samples")
        return PacedSource(RecordingSource(recording, profile.sample_rate_hz), speed)
    from hapticdesk.canbus import logs

    if not logs.is_can_log(path):
        kinds = ", ".join(logs.PYTHON_CAN_SUFFIXES + logs.CANDUMP_TEXT_SUFFIXES)
        raise ConfigError(
            str(path),
            f"cannot replay a {path.suffix or 'suffix-less'} file; expected a recording "
            f"({', '.join(RECORDING_SUFFIXES)}) or a CAN log ({kinds})",
        )
    return PacedSource(logs.open_can_log(path, profile), speed)


@hookimpl
def register_sources(register: Any) -> None:
    register(
        "replay",
        open_replay,
        "a recording (CSV, NPZ) or CAN log, at --speed (1 = real time, 0 = as fast as possible)",
    )
