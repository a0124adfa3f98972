"""The ``replay`` source: a recording (CSV/NPZ), a CAN log or a C3D file's force plates played
back on their own clock.

    hapticdesk run --layout L --source replay:session.csv --speed 1    # real time
    hapticdesk run --layout L --source replay:session.npz --speed 0    # as fast as possible
    hapticdesk run --layout L --source replay:session.asc              # a CAN log
    hapticdesk run --layout L --source replay:walk.c3d --plate 2       # a force plate

Blocks of ~12 samples (10 ms at 1.2 kHz) are handed out when their last sample's time has
come on the wall clock (scaled by ``speed``), as a live source would deliver them. Files are
read in blocks of :data:`~hapticdesk.files.recording.BLOCK_ROWS` samples as they are played,
so memory stays flat whatever the file's size. CAN logs are read by
:mod:`hapticdesk.canbus.logs`, imported only for them; a C3D file (read whole by ezc3d) by
:mod:`hapticdesk.files.forceplate`, its plates the desk's sensors ``plate<N>`` (without
``--desk``, ``run`` makes the file's plate the desk).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

from hapticdesk.files.yamlfile import ConfigError
from hapticdesk.hookspecs import hookimpl
from hapticdesk.runtime.pacing import PacedSource, Pacer
from hapticdesk.runtime.source import Source, WrenchBlock

if TYPE_CHECKING:  # the hooks are loaded for every command, even `--help`: no numpy here
    import numpy as np

    from hapticdesk.files.profile import DeskProfile
    from hapticdesk.files.recording import Recording, RecordingBlocks

__all__ = ["BLOCK_SIZE", "PacedSource", "Pacer", "RecordingSource", "open_replay"]

BLOCK_SIZE = 12


class RecordingSource(Source):
    """A recording handed out in blocks of ``block_size`` samples, as fast as they are read.

    ``recording``: a whole :class:`Recording`, or a :class:`RecordingBlocks` streamed from its
    file one read block at a time. ``accel_columns``: the desk's accelerometer columns
    (:meth:`DeskProfile.accelerometer_columns`), whose readings go with each block when the
    file has them all (none else: the estimator flags those samples uncompensated); without
    it, every accelerometer column the file has, in order.
    """

    def __init__(
        self,
        recording: Recording | RecordingBlocks,
        sample_rate_hz: float,
        *,
        block_size: int = BLOCK_SIZE,
        accel_columns: list[str] | None = None,
    ) -> None:
        self.recording = recording
        self.accel_columns = accel_columns
        self.sensor_names = list(recording.sensor_names)
        self.sample_rate_hz = sample_rate_hz
        self.block_size = block_size
        self._reading = False
        self._closed = False

    def blocks(self) -> Iterator[WrenchBlock]:
        import numpy as np

        from hapticdesk.files.recording import Recording

        rec_or_blocks = self.recording
        if isinstance(rec_or_blocks, Recording):
            parts: Iterator[Recording] = iter([rec_or_blocks])
        else:
            parts = rec_or_blocks.blocks()  # closes the file when it ends or is closed
        self._reading = True
        try:
            for rec in parts:
                for start in range(0, len(rec), self.block_size):
                    if self._closed:
                        return
                    end = min(start + self.block_size, len(rec))
                    truth = {k: np.asarray(v[start:end]) for k, v in rec.extra.items()} or None
                    accel = self._readings(truth) if truth else None
                    yield WrenchBlock(rec.t[start:end], rec.wrench[start:end], truth, accel)
        finally:
            close = getattr(parts, "close", None)  # a generator of file blocks
            if close is not None:
                close()

    def _readings(self, columns: dict[str, np.ndarray]) -> np.ndarray | None:
        """The accelerometers' readings (k, A) among a block's extra ``columns``, or None."""
        from hapticdesk.files.recording import accel_table, named_columns

        if self.accel_columns is None:
            return accel_table(columns)
        return named_columns(columns, self.accel_columns)

    def close(self) -> None:
        """Safe from another thread: a file being read is closed by the reading thread."""
        from hapticdesk.files.recording import Recording

        self._closed = True
        if not self._reading and not isinstance(self.recording, Recording):
            self.recording.close()


def open_replay(
    argument: str, profile: DeskProfile, *, speed: float = 1.0, **options: Any
) -> Source:
    """``replay:FILE``: a CSV/NPZ recording, a C3D file, or a CAN log by any other suffix."""
    from hapticdesk.files.readers import open_recording_blocks
    from hapticdesk.files.recording import RECORDING_SUFFIXES

    if not argument:
        raise ConfigError(
            "--source", "replay needs a file: replay:FILE.csv, .npz, .c3d or a CAN log"
        )
    path = Path(argument).expanduser()
    if not path.is_file():
        what = "not a regular file" if path.exists() else "no such file"  # (a FIFO, a folder)
        raise ConfigError("--source", f"replay: {what}: {argument}")
    if path.suffix.lower() == ".c3d":
        from hapticdesk.files.readers import read_any_recording

        plates = read_any_recording(path, profile)  # (checked to come at the desk's rate)
        if len(plates) == 0:
            raise ConfigError(str(path), "the C3D file holds no analog samples")
        return PacedSource(RecordingSource(plates, profile.sample_rate_hz), speed)
    if path.suffix.lower() in RECORDING_SUFFIXES:
        recording = open_recording_blocks(path, profile)
        if recording.is_empty():
            recording.close()
            raise ConfigError(str(path), "the recording holds no samples")
        source = RecordingSource(
            recording, profile.sample_rate_hz, accel_columns=profile.accelerometer_columns()
        )
        return PacedSource(source, speed)
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
        "a recording (CSV, NPZ), CAN log or C3D file, at --speed (1 = real time, 0 = as fast "
        "as possible)",
    )
