"""Sources of wrench blocks: one base for the simulator, replayed files, CAN buses and boards.

The base owns what every source would otherwise repeat (python-can's ``BusABC``, STYLE.md 6,
14 and 20): the loop of :meth:`Source.blocks`, each block's shape checked against the desk,
the pacing of a finite source on its own sample clock, and a :meth:`Source.close` that is
idempotent and safe from any thread; ``__del__`` warns when it never ran. A source writes one
read method, :meth:`Source.read_block` (and :meth:`Source.release` when it holds a device or
a file). Everything downstream runs on sample time.
"""

from __future__ import annotations

import threading
import warnings
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from types import TracebackType
from typing import TYPE_CHECKING

from hapticdesk.runtime.pacing import Pacer

if TYPE_CHECKING:  # plugin hook modules import this for every command, even `--help`
    import numpy as np


@dataclass
class WrenchBlock:
    """``t`` (k,) sample times in seconds on the sensor clock; ``wrench`` the sensors' raw
    readings: (k, S, 6) for a desk of six-axis sensors, else (k, C), the profile's channels
    in order (:meth:`DeskProfile.channel_names`; the estimator takes either)."""

    t: np.ndarray
    wrench: np.ndarray
    truth: dict[str, np.ndarray] | None = None  # ground truth where the source knows it
    #: (k, A) the desk's accelerometers' readings (``acc_x, acc_y, acc_z``, then ``acc2_*``, …
    #: as the profile lists them) where the desk has some and the source carries them; see
    #: hapticdesk.estimator.inertia
    accel: np.ndarray | None = None

    @classmethod
    def empty(cls) -> WrenchBlock:
        """A block of no samples: what a live source's read gives when none came."""
        import numpy as np  # (here: this module stays light for `hapticdesk --help`)

        return cls(np.zeros(0), np.zeros((0, 0)))


class Source:
    """The base of every source (module docstring). A subclass calls ``__init__`` with its
    sensors' names, its rate and, where it knows it, its channel count C, and writes
    :meth:`read_block`.

    Reading: :meth:`blocks` calls :meth:`read_block` until it returns None (a finite source's
    end) or :meth:`close` is called, then hands on :meth:`read_rest`; it yields only non-empty
    blocks, each checked (its times (k,) and k rows of (k, S, 6) or (k, C) readings; a
    ValueError names the shapes otherwise), held back to its time when the source is
    :meth:`paced`. When :meth:`blocks` ends, for whatever reason, the source is closed.

    Closing: :meth:`close` may come from any thread (a run's stop closes the source from the
    watching thread); :meth:`release` runs once. While :meth:`blocks` reads on another
    thread, that thread releases the source as soon as its read returns (a read waits tens
    of milliseconds at most), so a device or file is never freed under a read in progress.
    """

    #: sensor names in the order of ``wrench``'s second axis
    sensor_names: list[str]
    sample_rate_hz: float

    def __init__(
        self,
        sensor_names: Sequence[str],
        sample_rate_hz: float,
        *,
        channel_count: int | None = None,
    ) -> None:
        self.sensor_names = list(sensor_names)
        self.sample_rate_hz = float(sample_rate_hz)
        #: C, the raw channels a (k, C) block carries (None: not checked)
        self.channel_count = channel_count
        #: set when the source plays on its sample clock (:meth:`paced`)
        self.pacer: Pacer | None = None
        self._closing = threading.Event()
        self._close_lock = threading.Lock()
        self._released = False
        self._reading_thread: int | None = None  # the thread in blocks(), while it reads

    # --- what a source writes ----------------------------------------------------------------

    def read_block(self) -> WrenchBlock | None:
        """The samples that came since the last call, waiting a short while (tens of ms) at
        most for a live source: an empty block when none came, None when the source has
        ended (a finite source; a live one ends when closed). A ConfigError ends the source;
        the blocks given out before it stay given."""
        raise NotImplementedError

    def read_rest(self) -> WrenchBlock | None:
        """What the source still holds when it is closed (a CAN assembler's last samples);
        called once, on the reading thread, after the last :meth:`read_block`. None by
        default."""
        return None

    def release(self) -> None:
        """Free the device or file; called once, by the first :meth:`close` (or, while
        :meth:`blocks` reads, by the reading thread)."""

    def summary(self) -> list[str]:
        """Lines for the run's report about what the source read (a CAN source: frames seen,
        decoded and rejected by reason); none by default."""
        return []

    # --- what the base owns ------------------------------------------------------------------

    def paced(self, speed: float) -> Source:
        """Hand each block out when its last sample's time has come on the wall clock, at
        ``speed`` times real time (0: as fast as possible), as a live source would deliver
        it; for a finite source (a recording, a simulation, a CAN log). Returns the source."""
        self.pacer = Pacer(speed, self._closing)
        return self

    @property
    def closing(self) -> bool:
        """True once :meth:`close` was called (a reader should stop waiting)."""
        return self._closing.is_set()

    def blocks(self) -> Iterator[WrenchBlock]:
        """Blocks as :meth:`read_block` gives them, until the source ends or is closed."""
        self._reading_thread = threading.get_ident()
        try:
            while not self._closing.is_set():
                block = self.read_block()
                if block is None:
                    return
                if not len(block.t):
                    continue
                if not self._hold_back(block):
                    return
                yield block
            rest = self.read_rest()
            if rest is not None and len(rest.t):
                self._check(rest)
                yield rest
        finally:
            self._reading_thread = None
            self.close()

    def close(self) -> None:
        """Stop reading and release what the source holds. Safe to call more than once, from
        any thread."""
        self._closing.set()
        reading = self._reading_thread
        if reading is not None and reading != threading.get_ident():
            return  # the reading thread releases it when its read returns
        with self._close_lock:
            if self._released:
                return
            self._released = True
        self.release()

    def _hold_back(self, block: WrenchBlock) -> bool:
        """Check the block and, when paced, wait for its time; False when closed meanwhile."""
        self._check(block)
        return self.pacer is None or self.pacer.wait_for(float(block.t[-1]))

    def _check(self, block: WrenchBlock) -> None:
        """A source's bug, said plainly: the block's shape is not the desk's."""
        k, shape = len(block.t), block.wrench.shape
        n, c = len(self.sensor_names), self.channel_count
        rows_ok = block.t.ndim == 1 and len(block.wrench) == k
        if block.wrench.ndim == 3:
            ok = shape[1:] == (n, 6) and c in (None, 6 * n)
        else:
            ok = block.wrench.ndim == 2 and c in (None, shape[1])
        accel_ok = block.accel is None or len(block.accel) == k
        if not (rows_ok and ok and accel_ok):
            expected = f"(k, {n}, 6)" + (f" or (k, {c})" if c is not None else " or (k, C)")
            raise ValueError(
                f"{type(self).__name__} gave times {block.t.shape}, readings {shape}"
                + (f" and accelerometers {block.accel.shape}" if block.accel is not None else "")
                + f": expected (k,), {expected} and k rows of each"
            )

    def __enter__(self) -> Source:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def __del__(self) -> None:
        if getattr(self, "_released", True) is False:
            warnings.warn(f"{type(self).__name__} was never closed", ResourceWarning, stacklevel=2)
