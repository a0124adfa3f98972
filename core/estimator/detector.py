"""Stage 4, the fast touch detector: contact from the fast (30 Hz) force, with hysteresis.

Touch-down at ``contact_force_n``, release below it less ``release_hysteresis_n``, and only
for a force that presses into a surface (a lifted object pulls); it does not wait for the
position filters. A force falling fast is released earlier, where it is *predicted* to cross
``contact_force_n``: the fast low-pass runs ``det_delay_s`` (≈ 7.5 ms at 30 Hz) behind the
true force, so the true force is about ``|F| + slope · det_delay_s``; without that a slow
release (20 N/s) took 25 ms to fall through the hysteresis. Only a steep fall
is extrapolated (``release_slope_n_s``, 10 N/s by default: the slope over 20 ms of a held press
— tremor 1.5 %, wander 3 %, noise — stays under 3 N/s; the slowest releases of the human model
fall at about 20 N/s), so a steady hold is never released. A contact that ends while the fast
force is still above the release level (a predicted release, or a force turning away from the
surface) re-arms only once the force has fallen below that level: until then a new touch-down
needs ``contact_force_n`` plus the hysteresis (a light tap whose force flattened at 2.0 N
right after its predicted release touched down again for 10 ms and its button fired twice).
The phase of a contact (touch, hold, release) follows the fast force's slope.

Upright surfaces (a front panel) are pressed along the axes the desk sways on (5.9 Hz on the
paper's desk, rung for seconds by a push), and the ring is a force along the panel's normal
like a finger's: after a 30 N push on the desk's side it made ten touch-downs of 2–9 N. A
finger cannot pull, and each swing of the ring towards the panel follows one away from it at
least as large, so the force along an upright surface's normal counts less the largest pull
along it lately (the ring guard, g[k] = max(pull[k], decay · g[k−1]), forgotten over
``RING_MEMORY_S``) when a touch-down is judged (a ring under a finger already in contact does
not end its press); a horizontal board is not guarded (its vertical modes are far above the
sample rate).

The per-sample work is ``detect`` in :mod:`hapticdesk.estimator.kernel_detector`; its state (in
contact, re-armed, the ring guard of each upright surface) lives in the kernel's state arrays.
"""

from __future__ import annotations

import numpy as np

#: the time constant (s) over which a pull along an upright surface's normal is forgotten.
#: A ring decays by e^(−ζ·π) a half period (≈ 9 % at the paper desk's ζ ≈ 0.03), and a swing
#: towards the panel is rejected while the guard holds more than 1 − min_normal_cos (80 %) of
#: it: a guard decaying by e^(−0.085 s / 1 s) ≈ 8 % over a 5.9 Hz half period keeps a margin
#: for lighter damping and slower sways; a real press right after a push waits for the ring
#: to fall below it (≈ 2.7 s after a 30 N push on the paper desk)
RING_MEMORY_S = 1.0
UPRIGHT_MAX_NZ = 0.5  # a surface whose normal's |z| is below this is upright (sways)


def upright_surfaces(normals: np.ndarray) -> list[int]:
    """The indices of the upright surfaces among ``normals`` (n, 3): those the ring guard
    watches."""
    return [int(i) for i in np.flatnonzero(np.abs(normals[:, 2]) < UPRIGHT_MAX_NZ)]
