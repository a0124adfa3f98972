"""A board for the tests: a load-cell desk, its samples from the simulator, the lines a board
prints for them, and a pseudo-terminal fed by a writer thread (a board on a serial line).

The load-cell simulator is not there yet: each cell's reading is the F_z of a six-axis leg
of the same desk simulated at ``oversample`` times the rate, so that channel ``j`` read
``j / (rate · oversample)`` after the sample's stamp is exactly the simulated value at that
moment (an ADS1256 reading four bridges one after the other).
"""

from __future__ import annotations

import os
import threading
import time
import tty
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hapticdesk.boards.emulator import read_asks
from hapticdesk.boards.hello import BoardHello, with_checksum
from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.profile_reader import builtin_profile_path, load_profile
from hapticdesk.sim import SimEffects, load_scene, simulate

CELLS = """\
name: cells-1k
sample_rate_hz: {rate}
desk: {{mass_kg: 13.7, natural_frequency_hz: 5.9}}
sensors:
  - {{name: fl, kind: load_cell, position: [-0.34, -0.22, 0.0], range: {{force_n: 400}}}}
  - {{name: fr, kind: load_cell, position: [0.34, -0.22, 0.0], range: {{force_n: 400}}}}
  - {{name: bl, kind: load_cell, position: [-0.34, 0.22, 0.0], range: {{force_n: 400}}}}
  - {{name: br, kind: load_cell, position: [0.34, 0.22, 0.0], range: {{force_n: 400}}}}
surfaces:
  - name: top
    origin: [0.0, 0.0, 0.733]
    normal: [0, 0, 1]
    polygon: [[-0.375, -0.25], [0.375, -0.25], [0.375, 0.25], [-0.375, 0.25]]
{extra}"""

SCALE = 5e-5  # N per count, as the profile's `serial: scale` says
ZERO = 1000.0  # counts at no load


def cells_desk(folder: Path, rate: float = 1000, extra: str = "") -> DeskProfile:
    """Four load cells under the paper's desk (its legs' places), at ``rate``."""
    path = folder / "cells-1k.yaml"
    path.write_text(CELLS.format(rate=f"{rate:g}", extra=extra))
    return load_profile(path)


@dataclass
class CellSamples:
    """``t`` (n,) stamps' times; ``fz`` (n, 4, oversample): cell ``j``'s reading
    ``o / (rate · oversample)`` after ``t``; ``truth`` the simulator's columns at ``t``."""

    t: np.ndarray
    fz: np.ndarray
    truth: dict[str, np.ndarray]


def simulated_cells(
    folder: Path,
    scene_text: str,
    rate: float = 1000,
    oversample: int = 4,
    seed: int = 3,
    effects: SimEffects | None = None,
) -> CellSamples:
    """The cells' readings of a simulated scene on the paper's desk (module docstring)."""
    six = builtin_profile_path("kitamura2017")
    assert six is not None
    fine = folder / "six-axis-fine.yaml"
    fine.write_text(
        six.read_text().replace("sample_rate_hz: 1200", f"sample_rate_hz: {rate * oversample:g}")
    )
    scene = folder / "scene.yaml"
    scene.write_text(scene_text)
    rec = simulate(load_profile(fine), load_scene(scene), seed=seed, effects=effects)
    n = len(rec) // oversample
    fz = rec.wrench[: n * oversample, :, 2].reshape(n, oversample, 4).transpose(0, 2, 1)
    truth = {k: v[: n * oversample : oversample] for k, v in rec.extra.items()}
    return CellSamples(rec.t[: n * oversample : oversample], fz, truth)


def counts(newtons: np.ndarray) -> np.ndarray:
    """What a 24-bit converter prints for ``newtons`` with the test's scale and zero."""
    return np.rint(newtons / SCALE + ZERO).astype(np.int64)


def sample_lines(
    stamps: np.ndarray,
    values: np.ndarray,
    offsets: np.ndarray | None = None,
    *,
    checksum: bool = True,
) -> list[str]:
    """The lines a board prints: ``stamp,v1,…,vC[,o1,…,oC][*HH]``."""
    lines = []
    for i, stamp in enumerate(stamps):
        fields = [str(int(stamp)), *(str(int(v)) for v in values[i])]
        if offsets is not None:
            fields += [f"{o:g}" for o in offsets[i]]
        line = ",".join(fields)
        lines.append(with_checksum(line) if checksum else line)
    return lines


def hello_line(hello: BoardHello, checksum: bool = True) -> str:
    return with_checksum(hello.text()) if checksum else hello.text()


class PtyBoard:
    """A board on a pseudo-terminal: ``path`` is the port to open; a writer thread prints
    ``lines`` at ``rate`` lines a second (0: at once), says ``hello`` when the host sends
    ``?``, and keeps the terminal open after the last line until :meth:`close`.
    ``pauses`` maps a line index to seconds of silence before it (a board that stalls or
    reboots). ``wait_for_ask``: the first line only after the host's first ``?`` (a board
    that starts when the port opens, as an Arduino's reset on DTR does)."""

    def __init__(
        self,
        lines: list[str | bytes],
        hello: str,
        rate: float = 0.0,
        pauses: dict[int, float] | None = None,
        answer_hello: bool = True,
        wait_for_ask: bool = True,
    ) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)  # no echo, no newline translation: a serial line's bytes
        self.path = os.ttyname(self.slave)
        self.lines = [x if isinstance(x, bytes) else (x + "\n").encode() for x in lines]
        self.hello = (hello + "\n").encode()
        self.rate = rate
        self.pauses = pauses or {}
        self.answer_hello = answer_hello
        self.wait_for_ask = wait_for_ask  # a board that starts when the port is opened
        self.asked = 0  # `?` requests seen
        self.written = 0  # lines written
        self.done = threading.Event()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._write, daemon=True)

    def start(self) -> PtyBoard:
        self._thread.start()
        return self

    def _answer(self) -> None:
        for _ in range(read_asks(self.master)):
            self.asked += 1
            if self.answer_hello:
                os.write(self.master, self.hello)

    def _write(self) -> None:
        while self.wait_for_ask and not self.asked and not self._stop.is_set():
            self._answer()
            self._stop.wait(0.002)
        start = time.monotonic()
        shift = 0.0
        i = 0
        while i < len(self.lines) and not self._stop.is_set():
            self._answer()
            if i in self.pauses:
                shift += self.pauses.pop(i)
                if not self.rate:
                    self._stop.wait(shift)
            elapsed = time.monotonic() - start - shift
            due = int(elapsed * self.rate) + 1 if self.rate else len(self.lines)
            limit = min([k for k in self.pauses if k > i], default=len(self.lines))
            due = min(max(due, i), limit)
            if due > i:
                os.write(self.master, b"".join(self.lines[i:due]))
                self.written = due
                i = due
            else:
                self._stop.wait(0.002)
        self.done.set()
        while not self._stop.is_set():  # the board stays on the line
            self._answer()
            self._stop.wait(0.02)

    def close(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(5)
        for fd in (self.master, self.slave):
            try:
                os.close(fd)
            except OSError:
                pass
