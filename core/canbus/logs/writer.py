"""Frames written to a python-can log, its format chosen by the suffix (python-can's
``Logger``): ``.asc``, ``.blf``, ``.log``, ``.trc``. A frame whose time no such log can hold
is refused before the file is made, or the file is removed, never left cut short."""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from hapticdesk.canbus.frames import FrameArray
from hapticdesk.canbus.logs.log_files import log_suffix
from hapticdesk.canbus.logs.python_can_logs import PYTHON_CAN_SUFFIXES
from hapticdesk.canbus.logs.skipped import MAX_LOG_TIME_S
from hapticdesk.errors import ConfigError

WRITE_SUFFIXES = PYTHON_CAN_SUFFIXES


def write_frames(path: str | Path, frames: Iterable[FrameArray], channel: Any = None) -> int:
    """Write frames to a python-can log chosen by suffix; returns the number written."""
    import can

    path = Path(path)
    if log_suffix(path) not in WRITE_SUFFIXES:
        raise ConfigError(
            str(path), f"cannot write CAN logs as {path.suffix!r}; use {', '.join(WRITE_SUFFIXES)}"
        )
    checked = isinstance(frames, (list, tuple))
    if checked:  # all at hand: refused before the file is made (or an old one overwritten)
        for chunk in frames:
            if (failure := _unwritable(path, chunk)) is not None:
                raise failure
    n = 0
    failure = None
    with can.Logger(str(path)) as logger:
        for chunk in frames:
            if not checked and (failure := _unwritable(path, chunk)) is not None:
                break
            for msg in chunk.to_messages(channel=channel):
                logger.on_message_received(msg)
            n += len(chunk)
    if failure is not None:
        path.unlink(missing_ok=True)  # no log cut short at the bad frame is left behind
        raise failure
    return n


def _unwritable(path: Path, chunk: FrameArray) -> ConfigError | None:
    """Why ``chunk`` cannot go in the log at ``path``: a time out of its range (python-can
    failed on it with an OverflowError or "year 11533 is out of range", or for ``.log`` wrote
    times that read back all equal)."""
    bad = ~np.isnan(chunk.t) & ~((chunk.t >= 0) & (chunk.t <= MAX_LOG_TIME_S))
    if not bad.any():
        return None
    t = float(chunk.t[np.argmax(bad)])
    return ConfigError(
        str(path),
        f"cannot write a frame at {t:.6g} s: a {log_suffix(path)} CAN log's times are seconds "
        f"since 1970 from 0 to {MAX_LOG_TIME_S:.0f} (year 9999); are the source's times in "
        "seconds?",
    )
