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
    I_PO_ALIMIT,
    I_PO_REST,
    S_RAW,
)


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
