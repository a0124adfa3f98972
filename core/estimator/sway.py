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

Stateful: the last ``2·SPAN_S`` of the low-passed horizontal force, so the output is the
same for any split of the input; a gap restarts it like the filters (as if the desk had been
still).

Measured on the simulated desks (README "Sway compensation"): the translating model
recovers the accelerometer's reading with the gain the model predicts.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from hapticdesk.files.profile import DeskProfile, EstimationSettings

SPAN_S = 0.003  # the second difference's half-width: its delay costs 6° of phase at 6 Hz


def compensates(profile: DeskProfile, settings: EstimationSettings | None = None) -> bool:
    """Whether the compensation runs on ``profile`` with ``settings`` (its own estimation
    settings by default). It needs the desk's sway frequency. ``sway_compensation: true`` or
    ``false`` decides; unset (auto), it runs for ``fused`` on a desk without an accelerometer
    (one measures the sway itself): dragged fingers make the desk ring, and without it a
    swipe at 0.5 m/s was missed one time in two and swipes in a row after the tenth nearly
    always (README "Sway compensation"). The paper's own methods stay as the paper has
    them."""
    settings = settings or profile.estimation
    if not profile.natural_frequency_hz:
        return False
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


class SwayStage:
    """Adds the inertial wrench, estimated from the low-passed force's curvature, to a
    packed low-passed wrench (3, k) complex (force + 1j·moment), in place."""

    def __init__(self, settings: SwaySettings) -> None:
        self.settings = settings
        self.history: np.ndarray | None = None  # (2, 2·span): the last samples of F_h
        self._lever: list[list[float]] = settings.moment_lever.tolist()

    def restart(self, packed: np.ndarray | list[complex]) -> None:
        """As if the force in ``packed`` (3,) had been read forever (no curvature)."""
        f = np.array([packed[0].real, packed[1].real])
        self.history = np.repeat(f[:, None], 2 * self.settings.span, axis=1)

    def process(self, lp: np.ndarray) -> None:
        """Correct ``lp`` (3, k) packed, in place; the correction of sample n uses F_h at
        n, n − span and n − 2·span (a central second difference, ``span`` samples late)."""
        s = self.settings
        if lp.shape[1] == 0:
            return
        f = lp.real[:2].copy()
        if self.history is None:
            self.restart(lp[:, 0])
        assert self.history is not None
        line = np.concatenate([self.history, f], axis=1)
        n2 = 2 * s.span
        curvature = line[:, n2:] - 2.0 * line[:, s.span : -s.span] + line[:, :-n2]
        curvature *= s.scale  # F̈_h / ω_n²
        lp[:2] += curvature
        lp += 1j * (s.moment_lever @ curvature)
        self.history = line[:, -n2:]

    def process_one(self, lp: list[Any]) -> list[Any]:
        """:meth:`process` for one sample on plain numbers (the single-sample path)."""
        s = self.settings
        if self.history is None:
            self.restart(lp)
        assert self.history is not None
        h = self.history
        fx, fy = lp[0].real, lp[1].real
        cx = (fx - 2.0 * float(h[0, s.span]) + float(h[0, 0])) * s.scale
        cy = (fy - 2.0 * float(h[1, s.span]) + float(h[1, 0])) * s.scale
        h[:, :-1] = h[:, 1:]
        h[0, -1], h[1, -1] = fx, fy
        (l00, l01), (l10, l11), (l20, l21) = self._lever
        return [
            lp[0] + cx + 1j * (l00 * cx + l01 * cy),
            lp[1] + cy + 1j * (l10 * cx + l11 * cy),
            lp[2] + 1j * (l20 * cx + l21 * cy),
        ]
