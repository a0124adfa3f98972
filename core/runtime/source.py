"""Sources of wrench blocks: one shape for the simulator, replayed files, CAN buses and boards.

A source opens, yields blocks, and closes idempotently; it is a context manager
(python-can's ``BusABC`` habit, STYLE.md 6). Everything downstream runs on sample time.
A device read until it is closed builds on :class:`LiveSource`, which owns the loop.
"""

from __future__ import annotations

import threading
import warnings
from collections.abc import Iterator
from dataclasses import dataclass
from types import TracebackType
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # plugin hook modules import this for every command, even `--help`
    import numpy as np

    from hapticdesk.files.profile import DeskProfile


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


class Source:
    """Base class of all sources. Subclasses implement :meth:`blocks` and may override close."""

    #: sensor names in the order of ``wrench``'s second axis
    sensor_names: list[str]
    sample_rate_hz: float

    def blocks(self) -> Iterator[WrenchBlock]:
        """Yield blocks until the source ends (finite sources) or is closed."""
        raise NotImplementedError

    def close(self) -> None:
        """Release what the source holds. Safe to call more than once."""

    def summary(self) -> list[str]:
        """Lines for the run's report about what the source read (a CAN source: frames seen,
        decoded and rejected by reason); none by default."""
        return []

    def __enter__(self) -> Source:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


class LiveSource(Source):
    """A device read until it is closed. The base owns what every such source would repeat
    (python-can's ``BusABC``, STYLE.md 14 and 20): the loop of :meth:`blocks`, each block's
    shape checked against the desk, and a :meth:`close` that is idempotent and safe from any
    thread (a run's stop closes the source from the watching thread). A subclass writes
    :meth:`read_block` and :meth:`release`; ``__del__`` warns when it was never closed.
    """

    def __init__(self, profile: DeskProfile) -> None:
        self.profile = profile
        self.sensor_names = profile.sensor_names
        self.sample_rate_hz = profile.sample_rate_hz
        self._closing = threading.Event()
        self._close_lock = threading.Lock()
        self._released = False

    @property
    def closing(self) -> bool:
        """True once :meth:`close` was called (a reader should stop waiting)."""
        return self._closing.is_set()

    def blocks(self) -> Iterator[WrenchBlock]:
        """Blocks as :meth:`read_block` gives them, until :meth:`close`."""
        while not self._closing.is_set():
            block = self.read_block()
            if block is not None and len(block.t) and not self._closing.is_set():
                self._check(block)
                yield block

    def read_block(self) -> WrenchBlock | None:
        """The samples that came since the last call, waiting a short while (tens of ms) at
        most: None or an empty block when none came. A ConfigError ends the source (the
        samples given out before it stay given)."""
        raise NotImplementedError

    def release(self) -> None:
        """Free the device; called once, by the first :meth:`close`."""

    def close(self) -> None:
        self._closing.set()
        with self._close_lock:
            if self._released:
                return
            self._released = True
        self.release()

    def _check(self, block: WrenchBlock) -> None:
        """A subclass's bug, said plainly: the block's shape is not the desk's."""
        k = len(block.t)
        if block.t.ndim != 1 or len(block.wrench) != k:
            raise ValueError(
                f"{type(self).__name__} gave times {block.t.shape} and readings "
                f"{block.wrench.shape}: expected (k,) and k rows"
            )
        self.profile.flat_channels(block.wrench)  # (a ValueError naming the shapes)

    def __del__(self) -> None:
        if not getattr(self, "_released", True):
            warnings.warn(f"{type(self).__name__} was never closed", ResourceWarning, stacklevel=2)
