"""The estimator's output columns: the kernel writes each sample's contact into them.

:class:`OutputColumns` holds float, int8 and surface rows for up to ``capacity`` samples
(``kernel_slots.OUT_*``) and the :class:`~hapticdesk.estimator.contacts.ContactBlock` that
views them, so a push returns without building per-sample arrays (issue 29).
"""

from __future__ import annotations

import numpy as np

from hapticdesk.estimator import kernel_slots as slots
from hapticdesk.estimator.contacts import ContactBlock


class OutputColumns:
    """Output columns for up to ``capacity`` samples, and the blocks that view them."""

    def __init__(self, capacity: int, rows: int) -> None:
        self.capacity = capacity
        # (not zeroed: the kernel writes every row of a sample's column, the trace rows of
        # the traced ones, and nothing reads a column before the kernel wrote it)
        self.f = np.empty((rows, capacity))
        self.b = np.empty((slots.N_OUT_B, capacity), np.int8)
        self.s = np.full(capacity, -1, np.int16)
        self._block: ContactBlock | None = None  # the view of the last length asked

    def block(self, n: int) -> ContactBlock:
        """The first ``n`` columns as a contact block (views: the same object for the same n)."""
        cached = self._block
        if cached is not None and len(cached.t) == n:
            return cached
        f, b = self.f, self.b
        block = ContactBlock(
            t=f[slots.OUT_T, :n],
            in_contact=b[slots.OUT_B_IN_CONTACT, :n].view(bool),
            located=b[slots.OUT_B_LOCATED, :n].view(bool),
            surface=self.s[:n],
            x=f[slots.OUT_X, :n],
            y=f[slots.OUT_Y, :n],
            z=f[slots.OUT_Z, :n],
            force_n=f[slots.OUT_FORCE, :n],
            source=b[slots.OUT_B_SOURCE, :n],
            phase=b[slots.OUT_B_PHASE, :n],
            sigma_m=f[slots.OUT_SIGMA, :n],
            flags=b[slots.OUT_B_FLAGS, :n].view(np.uint8),
            located2=b[slots.OUT_B_LOCATED2, :n].view(bool),
            x2=f[slots.OUT_X2, :n],
            y2=f[slots.OUT_Y2, :n],
            z2=f[slots.OUT_Z2, :n],
            resting=b[slots.OUT_B_RESTING, :n].view(bool),
            shear=f[slots.OUT_SHEAR, :n],
            drag_x=f[slots.OUT_DRAG_X, :n],
            drag_y=f[slots.OUT_DRAG_Y, :n],
        )
        self._block = block
        return block
