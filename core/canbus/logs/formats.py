"""Which reader a CAN log takes, chosen by its suffix from one table (STYLE 22), and the
frames read through it: python-can's formats (:mod:`.python_can_logs`: ``.asc``, ``.blf``,
``.trc``, and ``.log`` when it holds candump ``-l`` lines) and candump's printed text
(:mod:`.candump_text`: ``.txt``, ``.candump``, ``.dump``, and any other suffix). A log
without times gets them from the profile's sample rate (the assembler's)."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path

from hapticdesk.canbus.frames import FrameArray
from hapticdesk.canbus.logs.candump_text import CANDUMP_TEXT_SUFFIXES, read_candump_frames
from hapticdesk.canbus.logs.log_files import log_suffix
from hapticdesk.canbus.logs.python_can_logs import (
    PYTHON_CAN_SUFFIXES,
    looks_canutils,
    read_python_can_frames,
)
from hapticdesk.errors import ConfigError

CHUNK_FRAMES = 50_000
#: a format's frame reader: ``(path, chunk_frames, skipped tally)`` -> chunks of frames
FrameReader = Callable[[Path, int, "dict[str, int] | None"], Iterator[FrameArray]]
#: suffix -> its reader; a suffix not here is read as candump text
FRAME_READERS: dict[str, FrameReader] = {
    **dict.fromkeys(PYTHON_CAN_SUFFIXES, read_python_can_frames),
    **dict.fromkeys(CANDUMP_TEXT_SUFFIXES, read_candump_frames),
}


def is_can_log(path: str | Path) -> bool:
    """True when ``path``'s suffix is a CAN log format read here."""
    return log_suffix(path) in FRAME_READERS


def read_frames(
    path: str | Path, chunk_frames: int = CHUNK_FRAMES, skipped: dict[str, int] | None = None
) -> Iterator[FrameArray]:
    """The log's frames in chunks, in file order. ConfigError when it cannot be read.
    ``skipped``: filled with what was skipped, by reason, as the log is read (a run's
    summary says it: a log of 5 % junk lines had been "silently nothing")."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError(str(path), "no such CAN log")
    suffix = log_suffix(path)
    reader = FRAME_READERS.get(suffix, read_candump_frames)
    if suffix == ".log" and not looks_canutils(path):  # candump's printed text, saved as .log
        reader = read_candump_frames
    any_frame = False
    for chunk in reader(path, chunk_frames, skipped):
        any_frame = any_frame or len(chunk) > 0
        yield chunk
    if not any_frame:
        raise ConfigError(
            str(path),
            "no CAN frames found; expected a python-can log (.asc, .blf, .log, .trc) or "
            "candump output (`candump can0`, `-tz`, `-ta`, `-l`)",
        )
