"""The zero's state: the part only Python keeps, and the part the kernel shares.

What the kernel shares — the zero, when it was set, the window counts, the still run and its
means, the idle desk's yardsticks, the object rule's run, whether the load is resting, the
last absorbed object — lives in the kernel's state arrays (``kernel_slots.S_*``,
``kernel_slots.J_*``: the kernel judges every window after the tare itself).
:class:`ZeroState` is Python's own: the tare's windows, the noise measured at the tare and
the objects absorbed (the kernel keeps the last one's zero and weight, for its lift); and
the zero, read from the kernel's state for callers.
"""

from __future__ import annotations

import numpy as np

from hapticdesk.estimator import kernel_slots as slots
from hapticdesk.estimator.still_objects import AbsorbedObject
from hapticdesk.estimator.tare import Tare


class ZeroState:
    """Python's part of the zero's state, and the kernel's part read on demand (the zero,
    when and how often it was set: for callers and tests)."""

    def __init__(self, sf: np.ndarray, si: np.ndarray, tare: Tare) -> None:
        self._sf, self._si = sf, si
        self.noise: np.ndarray | None = None  # (6, 6) measured at the tare
        self.tare = tare
        # objects absorbed into the zero, last on top
        self.objects: list[AbsorbedObject] = []

    @property
    def tared(self) -> bool:
        return bool(self._si[slots.J_TARED])

    @property
    def zero(self) -> np.ndarray | None:
        """The zero (6,), None before the tare (the one the kernel applies from the next
        sample on, where a window's end just decided one: kernel_zero.still_window)."""
        if not self.tared:
            return None
        at = slots.S_ZERO_NEXT if self._si[slots.J_ZERO_NEXT] else slots.S_ZERO
        return self._sf[at : at + 6].copy()

    @property
    def zero_t(self) -> float:
        """When the zero was last set, for the drift since then."""
        at = slots.S_ZERO_T_NEXT if self._si[slots.J_ZERO_NEXT] else slots.S_ZERO_T
        return float(self._sf[at])

    @property
    def zero_version(self) -> int:
        """How many times the zero was set."""
        return int(self._si[slots.J_ZERO_VERSION])
