"""The desk's moments of inertia, fitted from a recording of presses on a desk that has three
or more accelerometers (issue 15 item 4: the rotation's inertial moment is only as right as
the inertia the estimator assumes).

The sensors read the desk's inertial wrench less the load (:mod:`hapticdesk.estimator.inertia`):
``F_o = m (d̈ + θ̈ × c) − f`` and ``M_o = m c × d̈ + (I_c − m [c]×²) θ̈ − P × f``, with the
finger's force f at P. The accelerometers give q̈ = [d̈; θ̈]; the estimator, run with the
profile as it is, gives where each press held still (its located point over the hold, once
the desk's ring has died down); the first equation gives f. What is left is linear in the
inertia about the centre of mass:

    I_c θ̈ = M_o − m c × d̈ + m [c]×² θ̈ + P × f

so each principal moment is a least-squares slope, over the samples around the presses and
the free ring after them, both sides band-passed alike (``BAND_HZ``: the sway and yaw modes,
without the tare's and the held force's slow errors). A moment is reported only where the
recording moved the desk about that axis enough to fit it (the correlation of the two sides
at least ``MIN_CORRELATION``): presses on an upright panel's ends twist the desk in yaw,
which is the moment the panel needs; presses hardly roll or pitch a desk on stiff legs, so
those are usually left as the profile has them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from scipy import signal

from hapticdesk.estimator import ContactEstimator
from hapticdesk.estimator.contacts import ContactBlock
from hapticdesk.estimator.inertia import (
    InertiaSettings,
    InertiaStage,
    accelerometer_readings,
    rigid_motion,
)
from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.recording import Recording
from hapticdesk.files.rigid_body import is_body_inertia, spatial_inertia

BAND_HZ = (2.0, 40.0)
HOLD_AFTER_S = 0.3  # a press's point: where it held from this long after touch-down
MIN_HOLD_SAMPLES = 10
AROUND_S = 0.3  # a press's point applies from this long before touch-down to after release
# a touch that did not hold still (a tap) has no known point: the samples this near it are
# left out of the fit (the band-pass spreads its error about this far)
UNKNOWN_MARGIN_S = 1.0
MIN_CORRELATION = 0.9


@dataclass(frozen=True)
class InertiaFit:
    """Per desk axis (x, y, z): the fitted principal moment about the centre of mass (kg·m²),
    None where the recording did not move the desk enough about it; and how well it fits."""

    moments: tuple[float | None, float | None, float | None]
    correlation: tuple[float, float, float]
    presses: int
    reason: str = ""  # why nothing was fitted

    def with_profile(self, profile: DeskProfile) -> list[float]:
        """The three moments to give the profile: the fitted ones, the profile's elsewhere,
        those scaled up just enough that each moment is at most the sum of the other two (a
        body's are, and the profile reader refuses others). A fitted yaw above the assumed
        roll and pitch's sum says those were too small: a desk is closer to a flat plate,
        where the yaw moment is their sum, than the profile's box. Only scaling up is tried:
        a fit that would need the others smaller (a fitted moment too small for them) is
        returned as it is, and is no body's (see :func:`is_body_inertia`)."""
        current = np.diag(profile.inertia_about_com())
        fitted = np.array([m if m is not None else 0.0 for m in self.moments])
        kept = np.where([m is None for m in self.moments], current, 0.0)
        scale = _least_body_scale(fitted, kept)
        for margin in (1.0, 1.0001, 1.001, 1.01):  # (the snippet is rounded to 4 digits)
            moments = [float(f"{v:.4g}") for v in fitted + scale * margin * kept]
            if is_body_inertia(moments):
                return moments
        return [float(f"{v:.4g}") for v in fitted + scale * kept]


def _least_body_scale(fitted: np.ndarray, kept: np.ndarray) -> float:
    """The least s ≥ 1 for which I = fitted + s·kept (each axis one or the other) has every
    moment at most the sum of the other two; 1 where no s ≥ 1 gives that."""
    scale = 1.0
    for a in range(3):
        b, c = (a + 1) % 3, (a + 2) % 3
        # I_a ≤ I_b + I_c  ⇔  s (kept_a − kept_b − kept_c) ≤ fitted_b + fitted_c − fitted_a
        slope = kept[a] - kept[b] - kept[c]
        room = fitted[b] + fitted[c] - fitted[a]
        if slope < 0 and scale * slope > room:
            scale = room / slope
    return scale


def fit_inertia(
    profile: DeskProfile,
    recording: Recording,
    baseline: np.ndarray,
    sample_rate_hz: float | None = None,
) -> InertiaFit:
    """Fit the desk's moments of inertia from ``recording`` (see the module docstring);
    ``baseline`` (k, 6) or (1, 6): the resultant wrench of the idle desk at each sample (its
    tare); ``sample_rate_hz``: the recording's (default the profile's)."""
    settings = InertiaSettings.of(profile)
    nothing = (None, None, None)
    no = (0.0, 0.0, 0.0)
    if settings is None or settings.rows is None or settings.weights is None:
        return InertiaFit(nothing, no, 0, "needs several accelerometers (`accelerometers:`)")
    accel = accelerometer_readings(profile, recording.extra)
    if accel is None:
        return InertiaFit(nothing, no, 0, "the recording has no accelerometer readings")
    fs = sample_rate_hz or profile.sample_rate_hz
    k = len(recording.t)
    if k < 4 * round(fs / BAND_HZ[0]):
        return InertiaFit(nothing, no, 0, "the recording is too short")
    usable = InertiaStage(settings).usable(accel)
    if not usable.any():
        return InertiaFit(nothing, no, 0, "no usable accelerometer reading in the recording")
    block = ContactEstimator(profile).push(recording.t, recording.wrench, accel)
    pressed = _press_points(block, fs)
    if pressed.presses == 0:
        return InertiaFit(nothing, no, 0, "no press held still long enough")
    readings = np.where(usable[:, None], accel, settings.rest) - settings.rest
    motion = readings @ rigid_motion(settings.rows, settings.weights).T
    t_acc = motion[:, 3:]
    wrench = recording.wrench.reshape(k, -1) @ profile.wrench_map().T - baseline
    # M q̈ without I_c θ̈: [m (d̈ + θ̈ × c); m c × d̈ − m [c]×² θ̈]
    known = (
        motion
        @ spatial_inertia(
            float(profile.mass_kg or 0.0), profile.center_of_mass(), np.zeros((3, 3))
        ).T
    )
    force = known[:, :3] - wrench[:, :3]  # the finger's, f
    left = wrench[:, 3:] - known[:, 3:] + np.cross(pressed.points, force)  # = I_c θ̈
    left[~usable] = 0.0
    spin = np.where(usable[:, None], t_acc, 0.0)
    sos = signal.butter(2, BAND_HZ, btype="band", fs=fs, output="sos")
    left = signal.sosfiltfilt(sos, np.nan_to_num(left), axis=0)
    spin = signal.sosfiltfilt(sos, spin, axis=0)
    left[pressed.unknown] = 0.0  # (out of the sums below)
    spin[pressed.unknown] = 0.0
    return _fit_moments(left, spin, pressed.presses)


def _fit_moments(left: np.ndarray, spin: np.ndarray, presses: int) -> InertiaFit:
    """Per axis, I = the slope of I_c θ̈ (``left``) against θ̈ (``spin``), both band-passed
    (k, 3), kept where they correlate by :data:`MIN_CORRELATION` or more."""
    moments: list[float | None] = []
    correlation = []
    for axis in range(3):
        power = float(spin[:, axis] @ spin[:, axis])
        rho = (
            float(np.corrcoef(left[:, axis], spin[:, axis])[0, 1])
            if power > 0 and float(left[:, axis] @ left[:, axis]) > 0
            else 0.0
        )
        correlation.append(rho)
        slope = float(left[:, axis] @ spin[:, axis]) / power if power > 0 else 0.0
        moments.append(slope if rho >= MIN_CORRELATION and slope > 0 else None)
    return InertiaFit(
        (moments[0], moments[1], moments[2]),
        (correlation[0], correlation[1], correlation[2]),
        presses,
    )


class _PressPoints(NamedTuple):
    """Per sample, the point (3,) of the press around it (where it held still), zero away
    from presses (``points`` (k, 3)); where a touch without such a point is too near to fit
    (``unknown`` (k,) bool); and how many presses gave a point."""

    points: np.ndarray
    unknown: np.ndarray
    presses: int


def _press_points(block: ContactBlock, fs: float) -> _PressPoints:
    """Where each press held still, for the samples around it (:class:`_PressPoints`)."""
    k = len(block)
    points = np.zeros((k, 3))
    unknown = np.zeros(k, bool)
    margin = round(UNKNOWN_MARGIN_S * fs)
    inside = block.in_contact.astype(np.int8)
    edges = np.diff(np.concatenate([[0], inside, [0]]))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    pad = round(AROUND_S * fs)
    presses = 0
    for a, e in zip(starts.tolist(), ends.tolist(), strict=True):
        hold = np.arange(a + round(HOLD_AFTER_S * fs), e)
        hold = hold[block.located[hold]]
        if len(hold) < MIN_HOLD_SAMPLES:
            unknown[max(0, a - margin) : min(k, e + margin)] = True
            continue
        point = [float(np.median(getattr(block, name)[hold])) for name in ("x", "y", "z")]
        points[max(0, a - pad) : min(k, e + pad)] = point
        presses += 1
    return _PressPoints(points, unknown, presses)
