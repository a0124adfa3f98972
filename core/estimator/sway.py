"""Stage 2b, sway compensation without an accelerometer: the legs are the accelerometer.

A desk sways because its legs bend, and the sensors under the legs read what bends them. For
the rigid top on elastic legs (:mod:`hapticdesk.sim.desk`), the horizontal force the sensors
read is the legs' spring force, ``F_h = -k x`` (damping aside), with k the desk's sway
stiffness, ``k = m ω_n²`` for its lowest (sway) mode at ω_n. So the top's acceleration is
the measured force's second derivative,

    a = ẍ = -F̈_h / (m ω_n²),

whatever the finger does (the identity holds for a dragged finger's friction as well as for
the free ring after a swipe). The inertial wrench of :mod:`.inertia` follows without an
accelerometer (``[m a; m c × a]`` with c the centre of mass):

    [F_o; M_o] ← [F_o; M_o] + [F̈_h; c × F̈_h] / ω_n²

The mass cancels: only the sway frequency (``desk.natural_frequency_hz``, which
``hapticdesk characterize`` measures) and the centre of mass are needed. Vertical motion is
left out (the vertical mode is far above the band of a touch).

Differentiating twice amplifies noise, so F̈ is taken of the *low-passed* wrench (the force
low-pass, paper's conventional filter) and the correction is applied to it: the correction
is linear, so correcting then low-passing equals low-passing then correcting, and the
low-pass bounds the noise (its second derivative, scaled by 1/ω_n², passes white noise with
gain (f_c/f_n)² at most). The second difference spans ``SPAN_S`` each way, which keeps the
delay small (``SPAN_S``, a few degrees at the sway frequency) and averages what the low-pass
lets through. The differentiated candidate (paper eq. 8) is a difference of the
same low-passed wrench and so is corrected with it.

Stateful: the last ``2·SPAN_S`` of the low-passed horizontal force (a ring in the kernel's
state, ``_sway`` in :mod:`hapticdesk.estimator.kernel_filters`); a gap restarts it like the filters
(as if the desk had been still).

Measured on the simulated desks (README "Sway compensation"): the translating model
recovers the accelerometer's reading with the gain the model predicts.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hapticdesk.files.profile import DeskProfile, EstimationSettings

SPAN_S = 0.003  # the second difference's half-width: its delay costs 6° of phase at 6 Hz


def compensates(profile: DeskProfile, settings: EstimationSettings | None = None) -> bool:
    """Whether the compensation runs on ``profile`` with ``settings`` (its own estimation
    settings by default). It needs the desk's sway frequency and sensors that measure a
    horizontal force: never on a desk of upright load cells, whatever the settings say (the
    profile reader refuses ``true`` there). Else ``sway_compensation: true`` or ``false``
    decides; unset (auto), it runs for ``fused`` on a desk without an accelerometer
    (one measures the sway itself): dragged fingers make the desk ring, and without it a
    swipe at 0.5 m/s was missed one time in two and swipes in a row after the tenth nearly
    always (README "Sway compensation"). The paper's own methods stay as the paper has
    them."""
    settings = settings or profile.estimation
    if not profile.natural_frequency_hz or not profile.measures_horizontal_force:
        return False  # (the stage reads the legs' horizontal force: load cells measure none)
    if settings.sway_compensation is not None:
        return settings.sway_compensation
    return settings.method == "fused" and not profile.accelerometers


@dataclass(frozen=True, eq=False)
class SwaySettings:
    """One desk's fixed quantities for the compensation (see the module docstring)."""

    moment_lever: np.ndarray  # (3, 2): M += lever · F̈_h / ω² (the rows of [c]× for F̈_z = 0)
    scale: float  # 1 / (ω_n² · (span·T_s)²): a second difference over ``span`` to F̈ / ω_n²
    span: int  # samples

    @classmethod
    def of(cls, profile: DeskProfile, settings: EstimationSettings) -> SwaySettings | None:
        """The settings for ``profile``, or None when the compensation does not run with the
        estimation ``settings`` (see :func:`compensates`)."""
        if not compensates(profile, settings):
            return None
        assert profile.natural_frequency_hz is not None
        cx, cy, cz = (float(v) for v in profile.center_of_mass())
        # c × (a, b, 0) = (-c_z b, c_z a, c_x b - c_y a)
        lever = np.array([[0.0, -cz], [cz, 0.0], [-cy, cx]])
        fs = profile.sample_rate_hz
        span = max(1, round(SPAN_S * fs))
        omega = 2.0 * math.pi * profile.natural_frequency_hz
        return cls(moment_lever=lever, scale=(fs / span) ** 2 / omega**2, span=span)
