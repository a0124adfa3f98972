"""The accelerometers, compiled: which readings are usable, the desk's inertial wrench taken off.

Stage 1b of the kernel (:mod:`hapticdesk.estimator.kernel`), the per-sample side of
:mod:`hapticdesk.estimator.inertia`: :func:`_accel_use` says from a sample's readings whether
the inertial wrench comes from all of them, from the usable ones (the gain of that pattern
made by Python) or from none; :func:`_inertial` takes G (a − a_rest) off the sample's wrench.
(The paper's desk had no accelerometer: no equation of it is followed here.)
"""

from __future__ import annotations

import numpy as np

from hapticdesk.estimator.kernel_compile import inlined
from hapticdesk.estimator.kernel_slots import (
    I_A,
    I_MULTI_ACCEL,
    I_PO_ALIMIT,
    I_PO_REST,
    J_PARTIAL,
    J_PARTIAL_PATTERN,
    S_RAW,
)

#: how a sample's inertial wrench is made (:func:`_accel_use`): not at all, from all its
#: readings, from the usable ones (the gain of partial readings), or not yet: Python first
#: makes the gain of its pattern of usable readings (``EV_PARTIAL_ACCEL``)
ACCEL_OFF, ACCEL_ALL, ACCEL_USABLE, ACCEL_ASK = range(4)


@inlined
def _accel_use(
    a: np.ndarray, given: bool, pf: np.ndarray, pi: np.ndarray, si: np.ndarray
) -> tuple[int, bool]:
    """How the sample's inertial wrench is made from its readings ``a`` (if ``given``): an
    ``ACCEL_*`` code; and whether the sample goes uncompensated (FLAG_NO_ACCEL)."""
    n_a = pi[I_A]
    accel = ACCEL_OFF
    no_accel = n_a > 0 and not given
    if n_a > 0 and given:
        pattern = 0  # which readings are usable (finite, inside the range), one bit each
        alimit = pi[I_PO_ALIMIT]
        for j in range(n_a):
            if abs(a[j]) < pf[alimit + j]:
                pattern |= 1 << j
        if pattern == (1 << n_a) - 1:
            accel = ACCEL_ALL
        elif not pi[I_MULTI_ACCEL]:
            no_accel = True  # one accelerometer: uncompensated, flagged
        elif si[J_PARTIAL_PATTERN] != pattern + 1:
            accel = ACCEL_ASK
        elif si[J_PARTIAL] == 1:
            accel = ACCEL_USABLE  # (a board lost for good costs nothing more)
        else:
            no_accel = True
    return accel, no_accel


@inlined
def _inertial(
    a: np.ndarray,
    gain: np.ndarray,
    pf: np.ndarray,
    pi: np.ndarray,
    sf: np.ndarray,
    g: int,
    usable_only: bool,
) -> None:
    """Takes the desk's inertial wrench G (a − a_rest) off the sample in flight (S_RAW), the
    gain G (6, A) at gain[g:] (inertia.py). ``usable_only``: a reading that is not usable
    counts as at rest (the gain of partial readings has no column for it)."""
    n_a = pi[I_A]
    rest, alimit = pi[I_PO_REST], pi[I_PO_ALIMIT]
    for r in range(6):
        acc = 0.0
        for k in range(n_a):
            reading = a[k]
            if usable_only and not abs(reading) < pf[alimit + k]:
                reading = pf[rest + k]
            acc += gain[g + r * n_a + k] * (reading - pf[rest + k])
        sf[S_RAW + r] -= acc
