"""candump's printed text read as frames, through cantools' log parser: ``candump can0``
without times, ``-tz``/``-td`` relative (``-td`` the time since the previous frame, told by
times that go back), ``-ta``/``-tA`` absolute. The format of any log whose suffix is not
python-can's (``.txt``, ``.candump``, ``.dump`` …). Lines that are no frame are skipped and
counted; a line is never longer than the bound of :mod:`.log_files`."""

from __future__ import annotations

import datetime
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from hapticdesk.canbus.frames import FrameArray
from hapticdesk.canbus.logs.log_files import BoundedLines, open_text
from hapticdesk.canbus.logs.skipped import (
    BAD_ID,
    BAD_TIME,
    MAX_LOG_TIME_S,
    NOT_FRAMES,
    Skipped,
    ident_fits,
)
from hapticdesk.errors import ConfigError

CANDUMP_TEXT_SUFFIXES = (".txt", ".candump", ".dump")


class _Batch:
    """Frames gathered until a chunk is handed out; the clock of ``-td`` deltas carried
    from chunk to chunk."""

    def __init__(self) -> None:
        self.deltas: bool | None = None  # candump -td prints the time since the previous frame
        self.clock = 0.0
        self.relative = False  # a time seen that is relative (-tz, -td)
        self.t: list[float] = []
        self.idents: list[int] = []
        self.exts: list[bool] = []
        self.datas: list[bytes] = []
        self.remote: list[bool] = []

    def __len__(self) -> int:
        return len(self.datas)

    def add(self, seconds: float, frame: Any) -> None:
        self.t.append(seconds)
        self.idents.append(frame.frame_id)
        self.exts.append(frame.is_extended_frame)
        self.datas.append(frame.data)
        self.remote.append(frame.is_remote_frame)

    def chunk(self) -> FrameArray:
        """The frames gathered, as one array; the batch is empty after."""
        times = np.array(self.t, dtype=float)
        if self.deltas is None and np.isfinite(times).all() and self.relative:
            self.deltas = bool(np.any(np.diff(times) < 0))
        if self.deltas:
            times = self.clock + np.cumsum(times)
            self.clock = float(times[-1]) if len(times) else self.clock
        out = FrameArray.build(times, self.idents, self.datas, extended=np.array(self.exts, bool))
        out.flags[np.array(self.remote, dtype=bool)] |= 1
        for gathered in (self.t, self.idents, self.exts, self.datas, self.remote):
            gathered.clear()
        return out


def read_candump_frames(
    path: Path, chunk_frames: int, tally: dict[str, int] | None = None
) -> Iterator[FrameArray]:
    """The log's frames in chunks of ``chunk_frames``, in file order; the lines skipped are
    warned of (and added to ``tally``, by reason)."""
    from cantools.logreader import Parser

    unknown = Skipped(NOT_FRAMES)
    unreadable = Skipped("frame line(s) that cannot be read were")
    bad_ids = Skipped(BAD_ID)
    bad_times = Skipped(BAD_TIME)
    batch = _Batch()
    try:
        with open_text(path) as fh:
            lines = BoundedLines(fh, path)
            parser = Parser()
            # line by line, not cantools' iterlines: a line whose time it cannot make a date of
            # ("(2020-13-45 …)", "(99999999999999999999.0)") raises out of that loop, and ended
            # the whole read with no line named
            for line in lines:
                number = lines.number
                try:
                    frame, seconds = _parse(parser, line)
                except (ValueError, OverflowError) as err:
                    unreadable.add(number, str(err))
                    continue
                if frame is None:
                    if line.strip() and not line.lstrip().startswith(("#", ";")):
                        unknown.add(number)
                    continue
                lines.framed = True
                if not ident_fits(frame.frame_id, frame.is_extended_frame):
                    bad_ids.add(number)
                    continue
                if abs(seconds) > MAX_LOG_TIME_S:  # (NaN, no time, is kept)
                    bad_times.add(number)
                    continue
                batch.relative = batch.relative or isinstance(frame.timestamp, datetime.timedelta)
                batch.add(seconds, frame)
                if len(batch) >= chunk_frames:
                    yield batch.chunk()
    except (OSError, EOFError, UnicodeDecodeError) as err:
        raise ConfigError(str(path), f"cannot read: {err}") from None
    if len(batch):
        yield batch.chunk()
    for skipped in (unknown, unreadable, bad_ids, bad_times):
        skipped.warn(path, tally)


def _parse(parser: Any, line: str) -> tuple[Any, float]:
    """cantools' frame of ``line`` (None: no frame) and its time in seconds (NaN: none)."""
    frame = parser.parse(line.strip("\r\n"))
    stamp = frame.timestamp if frame is not None else None
    if isinstance(stamp, datetime.timedelta):
        return frame, stamp.total_seconds()
    if isinstance(stamp, datetime.datetime):
        return frame, stamp.timestamp()
    return frame, np.nan
