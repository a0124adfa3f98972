"""``run --events FILE``: one JSON line per gesture event, for scripts and tests.

The file is optional: when it cannot be written (a full disk, a quota) it is said once, cut back
to its last whole line and dropped, and the events not written are counted; sensing and the
actions go on (a full disk had stopped the desk).
"""

from __future__ import annotations

import logging
import os
from pathlib import Path
from typing import IO

from hapticdesk.errors import ConfigError
from hapticdesk.gestures.event import GestureEvent

log = logging.getLogger("hapticdesk.runtime.service")


class EventsFile:
    """The events of a run as JSON lines in ``path`` (None: no file, nothing is written)."""

    def __init__(self, path: str | Path | None) -> None:
        self.path = Path(path) if path is not None else None
        self._out: IO[str] | None = None
        #: why the file could not be written (None: it could, so far)
        self.failure: str | None = None
        self._written = self._unwritten = self._bytes = 0

    def open(self) -> None:
        """Create the file; a ConfigError naming ``--events`` when it cannot be."""
        if self.path is not None:
            self._out = self._open_file()

    def _open_file(self) -> IO[str]:
        assert self.path is not None
        try:
            return self.path.open("w", encoding="utf-8")
        except OSError as err:
            raise ConfigError("--events", f"cannot write {self.path}: {err.strerror}") from None

    def write(self, event: GestureEvent) -> None:
        """One line, flushed (a reader sees each event as it happens)."""
        if self._out is None:
            if self.failure is not None:
                self._unwritten += 1
            return
        line = event.to_json() + "\n"
        try:
            self._out.write(line)
            self._out.flush()
        except OSError as err:  # (a full disk: /dev/full, a quota)
            self._lost(err)
            self._unwritten += 1
            return
        self._written += 1
        self._bytes += len(line.encode("utf-8"))

    def close(self) -> None:
        """Close the file (what its buffer could not write counts as a failure)."""
        out, self._out = self._out, None
        if out is not None:
            try:
                out.close()
            except OSError as err:  # (what was left in its buffer: the disk is full)
                self._lost(err)

    def summary(self) -> str:
        """A line for the run's report when the file failed."""
        return (
            f"{self.path}: cannot write the events ({self.failure}): "
            f"{self._written} written (whole lines), {self._unwritten} not"
        )

    def _lost(self, err: OSError) -> None:
        """The file failed: said once, its last half line cut off, the file dropped."""
        if self.failure is None:
            self.failure = err.strerror or str(err)
            log.error(
                "%s: cannot write the events (%s); sensing and the actions go on, the "
                "events from now on are not written",
                self.path,
                self.failure,
            )
        out, self._out = self._out, None
        if out is not None:
            try:
                out.close()
            except OSError:
                pass  # (its buffer could not be written either)
        try:  # a reader finds whole events only
            if self.path is not None and self.path.is_file():
                os.truncate(self.path, self._bytes)
        except OSError:
            pass
