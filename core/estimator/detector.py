"""Stage 4, the fast touch detector: contact from the fast (30 Hz) force, with hysteresis.

Touch-down at ``contact_force_n``, release below it less ``release_hysteresis_n``, and only
for a force that presses into a surface (a lifted object pulls); it does not wait for the
position filters. The phase of a contact (touch, hold, release) follows the fast force's
slope. :meth:`TouchDetector.process` is the block path; :meth:`TouchDetector.process_one` the
same for one sample on plain floats, with the decision (:func:`contact_decision`) and the
phase (:func:`phase_of`) written once for both.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from hapticdesk.estimator.contacts import PHASE_HOLD, PHASE_RELEASE, PHASE_TOUCH
from hapticdesk.estimator.settings import EstimatorSettings


def contact_decision(pressing: Any, mag: Any, settings: EstimatorSettings) -> tuple[Any, Any]:
    """(above, below): where contact starts and where it ends, for arrays (bool, float) or
    plain values; ``&``, ``|`` and ``~`` keep to the arrays' elementwise meaning."""
    s = settings.user
    if isinstance(pressing, bool):
        above = pressing and mag >= s.contact_force_n
        below = not pressing or mag < s.contact_force_n - s.release_hysteresis_n
        return above, below
    return (
        pressing & (mag >= s.contact_force_n),
        ~pressing | (mag < s.contact_force_n - s.release_hysteresis_n),
    )


def phase_of(slope: float, settings: EstimatorSettings) -> int:
    """The phase of a contact from the fast force's slope along it (N/s)."""
    rate = settings.user.phase_rate_n_s
    return PHASE_TOUCH if slope > rate else PHASE_RELEASE if slope < -rate else PHASE_HOLD


def phases_of(slope: np.ndarray, settings: EstimatorSettings) -> np.ndarray:
    """:func:`phase_of` for an array of slopes."""
    rate = settings.user.phase_rate_n_s
    phase = np.full(len(slope), PHASE_HOLD, np.int8)
    phase[slope > rate] = PHASE_TOUCH
    phase[slope < -rate] = PHASE_RELEASE
    return phase


def hysteresis(on: np.ndarray, off: np.ndarray, state: bool) -> np.ndarray:
    """Vectorised two-threshold switch: set where ``on``, cleared where ``off``, else held."""
    k = len(on)
    if k == 1:
        return np.array([bool(on[0]) or (state and not off[0])])
    decided = np.flatnonzero(on | off)
    if len(decided) == 0:
        return np.full(k, state)
    value = on[decided]  # what each decided sample sets
    before = np.empty(len(value), bool)
    before[0] = state
    before[1:] = value[:-1]
    flips = np.flatnonzero(value != before)  # the decided samples that change the state
    # runs of a constant state between the flips, written out with one np.repeat
    bounds = np.concatenate(([0], decided[flips], [k]))
    values = np.concatenate(([state], value[flips]))
    return np.repeat(values, np.diff(bounds))


class TouchDetector:
    """In contact or not, per sample, from the tared fast force; its state: in contact."""

    def __init__(self, settings: EstimatorSettings) -> None:
        self.settings = settings
        self.in_contact = False

    def process(
        self, f_det: np.ndarray, f_det_mag: np.ndarray, tared: np.ndarray | None
    ) -> np.ndarray:
        """In contact (k,) for the fast force (3, k) and its magnitude (k,); ``tared`` (k,)
        where the zero is known (None: everywhere)."""
        s = self.settings
        normals = s.normals
        if len(normals) == 1:
            pressing = normals[0] @ f_det >= s.user.min_normal_cos * f_det_mag
        elif len(normals):
            pressing = (normals @ f_det).max(axis=0) >= s.user.min_normal_cos * f_det_mag
        else:
            pressing = np.zeros(len(f_det_mag), bool)
        above, below = contact_decision(pressing, f_det_mag, s)
        if tared is not None:
            above &= tared
            below |= ~tared
        in_contact = hysteresis(above, below, self.in_contact)
        self.in_contact = bool(in_contact[-1])
        return in_contact

    def process_one(self, fast: list[float]) -> tuple[bool, float]:
        """:meth:`process` for one tared sample: in contact, and |F| of the fast force."""
        s = self.settings
        fx, fy, fz = fast[:3]
        mag = math.sqrt(fx * fx + fy * fy + fz * fz)
        normals = s.normals_list
        if normals:
            along = max(n[0] * fx + n[1] * fy + n[2] * fz for n in normals)
            pressing = along >= s.user.min_normal_cos * mag
        else:
            pressing = False
        above, below = contact_decision(pressing, mag, s)
        self.in_contact = above or (self.in_contact and not below)
        return self.in_contact, mag

    def phase_one(self, fast: list[float], det_slope: list[float], inv: float) -> int:
        """The phase of one sample from the fast force and its slope (1/|F| given)."""
        sx, sy, sz = det_slope
        return phase_of((fast[0] * sx + fast[1] * sy + fast[2] * sz) * inv, self.settings)

    def phases(
        self, f_det_at: np.ndarray, det_slope_at: np.ndarray, inv_mag: np.ndarray
    ) -> np.ndarray:
        """:meth:`phase_one` for the samples in contact (3, n)."""
        slope = np.einsum("ik,ik->k", f_det_at, det_slope_at) * inv_mag
        return phases_of(slope, self.settings)
