"""The ``replay`` source: a recording (CSV/NPZ), a CAN log or a C3D file's force plates played
back on their own clock.

    hapticdesk run --layout L --source replay:session.csv --speed 1    # real time
    hapticdesk run --layout L --source replay:session.npz --speed 0    # as fast as possible
    hapticdesk run --layout L --source replay:session.asc              # a CAN log
    hapticdesk run --layout L --source replay:walk.c3d --plate 2       # a force plate

Blocks of ~12 samples (10 ms at 1.2 kHz) are handed out when their last sample's time has
come on the wall clock (scaled by ``speed``), as a live source would deliver them. Files are
read in blocks of :data:`~hapticdesk.files.recording_io.BLOCK_ROWS` samples as they are played,
so memory stays flat whatever the file's size. CAN logs are read by
:mod:`hapticdesk.canbus.logs`, imported only for them; a C3D file (read whole by ezc3d) by
:mod:`hapticdesk.files.forceplate`, its plates the desk's sensors ``plate<N>`` (without
``--desk``, ``run`` makes the file's plate the desk).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

from hapticdesk.errors import ConfigError
from hapticdesk.hookspecs import hookimpl
from hapticdesk.runtime.source import Source, WrenchBlock

if TYPE_CHECKING:  # the hooks are loaded for every command, even `--help`: no numpy here
    import numpy as np

    from hapticdesk.files.profile import DeskProfile
    from hapticdesk.files.recording import Recording
    from hapticdesk.files.recording_io import RecordingBlocks

__all__ = ["BLOCK_SIZE", "RecordingSource", "open_replay"]

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
        super().__init__(recording.sensor_names, sample_rate_hz)
        self.recording = recording
        self.accel_columns = accel_columns
        self.block_size = block_size
        self._parts: Iterator[Recording] | None = None  # the file's read blocks, once reading
        self._part: Recording | None = None
        self._at = 0  # the next sample of ``_part`` to hand out

    def read_block(self) -> WrenchBlock | None:
        """The next ``block_size`` samples of the recording (fewer at the end of one of the
        file's read blocks); None at its end."""
        import numpy as np

        while self._part is None or self._at >= len(self._part):
            self._part, self._at = next(self._file_parts(), None), 0
            if self._part is None:
                return None
        rec, start = self._part, self._at
        end = min(start + self.block_size, len(rec))
        self._at = end
        truth = {k: np.asarray(v[start:end]) for k, v in rec.extra.items()} or None
        accel = self._readings(truth) if truth else None
        return WrenchBlock(rec.t[start:end], rec.wrench[start:end], truth, accel)

    def _file_parts(self) -> Iterator[Recording]:
        """The recording whole, or its file's read blocks one at a time as they are read."""
        from hapticdesk.files.recording import Recording

        if self._parts is None:
            whole = self.recording
            self._parts = iter([whole]) if isinstance(whole, Recording) else whole.blocks()
        return self._parts

    def _readings(self, columns: dict[str, np.ndarray]) -> np.ndarray | None:
        """The accelerometers' readings (k, A) among a block's extra ``columns``, or None."""
        from hapticdesk.files.recording import accel_table, named_columns

        if self.accel_columns is None:
            return accel_table(columns)
        return named_columns(columns, self.accel_columns)

    def release(self) -> None:
        """Close the file (the base calls this on the reading thread while one reads)."""
        from hapticdesk.files.recording import Recording

        close = getattr(self._parts, "close", None)  # a generator of the file's blocks
        if close is not None:
            close()
        if not isinstance(self.recording, Recording):
            self.recording.close()


def open_replay(
    argument: str, profile: DeskProfile, *, speed: float = 1.0, **options: Any
) -> Source:
    """``replay:FILE``: a CSV/NPZ recording, a C3D file, or a CAN log by any other suffix."""
    from hapticdesk.files.recording_io import RECORDING_SUFFIXES
    from hapticdesk.recordings import open_recording_blocks

    if not argument:
        raise ConfigError(
            "--source", "replay needs a file: replay:FILE.csv, .npz, .c3d or a CAN log"
        )
    path = Path(argument).expanduser()
    if not path.is_file():
        what = "not a regular file" if path.exists() else "no such file"  # (a FIFO, a folder)
        raise ConfigError("--source", f"replay: {what}: {argument}")
    if path.suffix.lower() == ".c3d":
        from hapticdesk.recordings import read_any_recording

        plates = read_any_recording(path, profile)  # (checked to come at the desk's rate)
        if len(plates) == 0:
            raise ConfigError(str(path), "the C3D file holds no analog samples")
        return RecordingSource(plates, profile.sample_rate_hz).paced(speed)
    if path.suffix.lower() in RECORDING_SUFFIXES:
        recording = open_recording_blocks(path, profile)
        if recording.is_empty():
            recording.close()
            raise ConfigError(str(path), "the recording holds no samples")
        source = RecordingSource(
            recording, profile.sample_rate_hz, accel_columns=profile.accelerometer_columns()
        )
        return source.paced(speed)
    from hapticdesk.canbus.logs.desk_samples import open_can_log
    from hapticdesk.canbus.logs.formats import FRAME_READERS, is_can_log

    if not is_can_log(path):
        kinds = ", ".join(FRAME_READERS)
        raise ConfigError(
            str(path),
            f"cannot replay a {path.suffix or 'suffix-less'} file; expected a recording "
            f"({', '.join(RECORDING_SUFFIXES)}) or a CAN log ({kinds})",
        )
    return open_can_log(path, profile).paced(speed)


@hookimpl
def register_sources(register: Any) -> None:
    register(
        "replay",
        open_replay,
        "a recording (CSV, NPZ), CAN log or C3D file, at --speed (1 = real time, 0 = as fast "
        "as possible)",
    )
