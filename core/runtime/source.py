"""Sources of wrench blocks: one shape for the simulator, replayed files and CAN buses.

A source opens, yields blocks, and closes idempotently; it is a context manager
(python-can's ``BusABC`` habit, STYLE.md 6). Everything downstream runs on sample time.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from types import TracebackType
from typing import TYPE_CHECKING

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
