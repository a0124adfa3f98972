"""A board on a pseudo-terminal: a desk's samples printed as a microcontroller prints them.

``hapticdesk emulate --serial`` (:mod:`hapticdesk.commands.emulate`) makes a maker's board
without the board: it opens a pseudo-terminal (a serial port another program opens by its
path, ``/dev/pts/N``), says the hello of docs/serial.md, answers every ``?`` with it, and
prints one line a sample — the stamp a sequence number, each channel in the counts the
profile's ``serial: scale`` and ``zero`` turn back into newtons (the values in newtons where
it gives none), every line with its ``*HH`` — paced by the samples' times. Its hello says the
channels are read together (``offsets_us`` 0: the values as simulated, at each sample's
time), or the profile's ``serial: offsets_us``. The lines are made
once before the first is printed; the writer prints those due every few milliseconds, as a
board's USB link delivers them in bursts. POSIX only (``os.openpty``).
"""

from __future__ import annotations

import os
import select
import threading
import time
import tty

import numpy as np

from hapticdesk.boards.hello import BoardHello, with_checksum
from hapticdesk.boards.settings import board_channels, serial_settings
from hapticdesk.errors import ConfigError
from hapticdesk.files.profile import DeskProfile

WRITE_EVERY_S = 0.005  # the due lines are printed this often (a USB link's bursts)
BOARD_NAME = "hapticdesk-emulate"


def board_lines(profile: DeskProfile, values: np.ndarray) -> tuple[str, list[bytes]]:
    """The hello and the sample lines (each with its checksum and newline) a board of
    ``profile`` prints for ``values`` (n, C) in the profile's units, in its channels' order
    (:func:`~hapticdesk.boards.settings.board_channels`)."""
    settings = serial_settings(profile, "emulated")  # (its scale, zero and offsets: any port)
    channels = board_channels(profile)
    if values.shape[1:] != (len(channels),):
        raise ConfigError(
            profile.name, f"expected {len(channels)} channels a sample, found {values.shape[1:]}"
        )
    hello = BoardHello(
        rate_hz=profile.sample_rate_hz,
        channels=tuple(channels),
        # the values as the simulator (or the recording) has them at each sample's time:
        # read together, unless the profile says when its board reads each channel
        offsets_us=settings.offsets_us or tuple(0.0 for _ in channels),
        checksum_required=True,
        board=BOARD_NAME,
    )
    if settings.scale_given:  # what the board's converters print: counts
        raw = np.rint(values / settings.scale + settings.zero).astype(np.int64)
        cells = raw.astype(str)
    else:
        cells = np.char.mod("%.4f", values)
    cells[~np.isfinite(values)] = ""  # (a channel the board could not read: an empty field)
    stamps = np.arange(len(values)).astype(str)
    rows = [",".join((stamp, *row)) for stamp, row in zip(stamps, cells.tolist(), strict=True)]
    return with_checksum(hello.text()), [(with_checksum(r) + "\n").encode() for r in rows]


def read_asks(master: int) -> int:
    """How many ``?`` the host has sent on the terminal ``master`` since the last call (0
    once the terminal is closed)."""
    asks = 0
    while True:
        try:  # (OSError: the terminal was closed meanwhile)
            if not select.select([master], [], [], 0)[0]:
                return asks
            data = os.read(master, 1024)
        except OSError:
            return asks
        if not data:
            return asks
        asks += data.count(b"?")


class PtyBoard:
    """A board on a new pseudo-terminal (``path``): :meth:`run` prints ``lines`` paced by
    ``t`` (seconds; ``speed`` 0: at once), answering ``?`` with ``hello``, and then stays on
    the line until :meth:`stop` (or starts over with ``loop``)."""

    def __init__(
        self, hello: str, lines: list[bytes], t: np.ndarray, speed: float = 1.0, loop: bool = False
    ) -> None:
        if not hasattr(os, "openpty"):
            raise ConfigError("--serial", "needs a POSIX system (a pseudo-terminal)")
        self.master, self._slave = os.openpty()
        tty.setraw(self._slave)  # no echo, no newline translation: a serial line's bytes
        os.set_blocking(self.master, False)  # (a host that stops reading cannot hang stop())
        self.path = os.ttyname(self._slave)
        self.hello = (hello + "\n").encode()
        self.lines, self.speed, self.loop = lines, speed, loop
        self.at = np.asarray(t, dtype=float) - float(t[0]) if len(t) else np.zeros(0)
        self.printed = 0  # sample lines printed
        self.asked = 0  # `?` heard
        self._stop = threading.Event()

    def run(self) -> None:
        """Print the lines (once, or over and over with ``loop``) until :meth:`stop`, from the
        host's first ``?`` on (as a board that restarts when its port is opened: an Arduino's
        reset on DTR), so that a reader started later still gets the scene from its start."""
        while not self.asked and not self._stop.is_set():
            self._answer()
            self._stop.wait(0.01)
        while not self._stop.is_set():
            self._print_once()
            if not self.loop:
                break
        while not self._stop.is_set():  # the board stays on the line
            self._answer()
            self._stop.wait(0.02)

    def _print_once(self) -> None:
        start = time.monotonic()
        i = 0
        while i < len(self.lines) and not self._stop.is_set():
            self._answer()
            elapsed = (time.monotonic() - start) * self.speed
            due = len(self.lines)
            if self.speed:
                due = int(np.searchsorted(self.at, elapsed, "right"))
            if due > i:
                self._write(b"".join(self.lines[i:due]))
                self.printed += due - i
                i = due
            else:
                self._stop.wait(WRITE_EVERY_S)

    def _answer(self) -> None:
        """The hello for every ``?`` the host sent (when it opened the port, and while it
        waits for one)."""
        for _ in range(read_asks(self.master)):
            self.asked += 1
            self._write(self.hello)

    def _write(self, data: bytes) -> None:
        """``data`` onto the line; while a host does not read, the terminal's buffer fills and
        the board waits (until :meth:`stop`)."""
        view = memoryview(data)
        while view and not self._stop.is_set():
            try:
                if not select.select([], [self.master], [], 0.05)[1]:
                    continue
                view = view[os.write(self.master, view) :]
            except BlockingIOError:
                continue
            except OSError:  # (the terminal closed: stop())
                return

    def halt(self) -> None:
        """Have :meth:`run` return soon (from another thread, or a signal handler)."""
        self._stop.set()

    def stop(self) -> None:
        """Stop printing and close the terminal."""
        self._stop.set()
        for fd in (self.master, self._slave):
            try:
                os.close(fd)
            except OSError:
                pass
