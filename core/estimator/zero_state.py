"""The zero's state: the part only Python keeps, and the part the kernel shares.

What the kernel shares — the zero, when it was set, the window counts, the still run and its
means, whether the load is resting, how many objects are absorbed — lives in the kernel's
state arrays (``kernel_slots.S_*``, ``kernel_slots.J_*``: the kernel judges the idle desk's
windows itself); a window Python judges reads their fixed slots once as lists and writes them
back in one go (:meth:`hapticdesk.estimator.zero.ZeroStage.window`). :class:`ZeroState` is
Python's own: the tare's windows, the idle desk's yardsticks, the object rule's run and the
objects absorbed; and the zero, read from the kernel's state for callers.
"""

from __future__ import annotations

import numpy as np

from hapticdesk.estimator import kernel_slots as slots
from hapticdesk.estimator.still_objects import AbsorbedObject, ObjectRun
from hapticdesk.estimator.tare import Tare
from hapticdesk.estimator.yardsticks import Yardsticks


class ZeroState:
    """Python's part of the zero's state, and the kernel's part read on demand (the zero,
    when and how often it was set: for callers and tests, not for a window's end)."""

    def __init__(
        self, sf: np.ndarray, si: np.ndarray, tare: Tare, yardsticks: Yardsticks, run: ObjectRun
    ) -> None:
        self._sf, self._si = sf, si
        self.noise: np.ndarray | None = None  # (6, 6) measured at the tare
        self.tare = tare
        self.yardsticks = yardsticks
        self.object_run = run
        # objects absorbed into the zero, last on top
        self.objects: list[AbsorbedObject] = []

    @property
    def tared(self) -> bool:
        return bool(self._si[slots.J_TARED])

    @property
    def zero(self) -> np.ndarray | None:
        """The zero (6,), None before the tare."""
        return self._sf[slots.S_ZERO : slots.S_ZERO + 6].copy() if self.tared else None

    @property
    def zero_t(self) -> float:
        """When the zero was last set, for the drift since then."""
        return float(self._sf[slots.S_ZERO_T])

    @property
    def zero_version(self) -> int:
        """How many times the zero was set."""
        return int(self._si[slots.J_ZERO_VERSION])
