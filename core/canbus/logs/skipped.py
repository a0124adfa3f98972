"""What a CAN log reader skips, and says so: a tally per reason with the first few lines
(:class:`Skipped`), and the checks every reader makes of a frame (its identifier and time in
range)."""

from __future__ import annotations

import logging
from pathlib import Path

from hapticdesk.files.recording import MAX_TIME_S

log = logging.getLogger(__name__)

#: the widest identifiers CAN has (python-can's own ``Message`` check): 29 bits for an extended
#: frame, 11 for a standard one; the readers take any number (an ``.asc`` line of 12 hex digits
#: reached numpy's uint32 and ended the read with an OverflowError)
MAX_EXTENDED_ID = 0x1FFF_FFFF
MAX_STANDARD_ID = 0x7FF
#: the latest time a CAN log holds, in seconds since 1970: any recording's (year 9999).
#: python-can's .asc, .blf and .trc writers date a log by its first frame, so a later one
#: cannot be written; read, a time beyond it (either way) is no clock's, and its gaps
#: overflowed the assembler's integer sample counts
MAX_LOG_TIME_S = MAX_TIME_S

BAD_ID = (
    f"frame(s) whose identifier is out of range (up to 0x{MAX_EXTENDED_ID:X} extended, "
    f"0x{MAX_STANDARD_ID:X} standard) were"
)
BAD_TIME = (
    f"frame(s) whose time cannot be read or is out of range (expected seconds within "
    f"±{MAX_LOG_TIME_S:.0f} of 1970, up to year 9999) were"
)
NOT_FRAMES = "line(s) are not CAN frames and were"


def ident_fits(ident: int, extended: bool) -> bool:
    """True for an identifier CAN can carry (29 bits extended, 11 standard)."""
    return 0 <= ident <= (MAX_EXTENDED_ID if extended else MAX_STANDARD_ID)


class Skipped:
    """Frames or lines skipped for one reason: how many, the first few lines (for the
    warning), the first reason given."""

    def __init__(self, what: str) -> None:
        self.what = what  # "<what> skipped (file:line, …)"
        self.lines: list[int] = []
        self.n = 0
        self.why: str | None = None

    def add(self, number: int | None, why: str | None = None) -> None:
        self.n += 1
        if number is not None and len(self.lines) < 3:
            self.lines.append(number)
        if self.why is None:
            self.why = why

    def warn(self, path: Path, tally: dict[str, int] | None = None) -> None:
        if not self.n:
            return
        if tally is not None:
            tally[self.what] = tally.get(self.what, 0) + self.n
        shown = ", ".join(f"{path}:{number}" for number in self.lines) or str(path)
        more = " …" if self.lines and self.n > len(self.lines) else ""
        why = f": {self.why}" if self.why else ""
        log.warning("%d %s skipped (%s%s)%s", self.n, self.what, shown, more, why)
