"""Stage 1b, vibration compensation: the desk's inertial wrench, measured by an accelerometer on
the desk top, removed from the resultant wrench before anything is filtered or located.

The sensors under the legs carry the load on the desk *and* what it takes to accelerate the
desk: for the rigid desk of mass m with its centre of mass at c, moving by small motions
``q = [d; θ]`` about P_o, the resultant the wrench map recovers is (Newton–Euler; the same
equation the simulator integrates, :mod:`hapticdesk.sim.desk`)

    [F_o; M_o] = M q̈ - u,     M q̈ = [m a_c; m c × a_c + I θ̈]

where u is the load about P_o (paper eqs. 1–4 hold for a desk at rest, q̈ = 0). A swaying
desk therefore reads as a wobbling extra force — the 5.9 Hz ring a dragging finger leaves in
the located path. In every case

    [F_o; M_o] ← [F_o; M_o] - G (f - f_rest)

with ``f`` the readings (specific force, m/s²; the axes the profile lists) and
``f_rest`` the readings of a desk at rest (gravity along each axis), so a still desk is left
untouched and the correction is linear: it commutes with the filters, needs no state, and
gives the same output for any split of the input. ``G`` depends on how many accelerometers:

- **One** measures a, the acceleration of the desk taken as translating (θ̈ is not
  observable from one three-axis accelerometer; the paper's desk sways in translation):
  ``G = [m I₃; m [c]×] · R_a``, ``R_a`` its axes in the desk frame. A press on an upright
  panel twists the desk in yaw, which this leaves (docs/stability.md).
- **Three or more**, not on one line (``accelerometers:``), measure the rigid motion itself:
  the mount at p accelerates by d̈ + θ̈ × p (the tilt's share of gravity, g·θ, is about 1 %
  of θ̈ × p at 5.9 Hz, and the sway's modes barely tilt: left), so the stacked readings are
  ``f - f_rest = H q̈`` with the rows ``R_iᵀ [I₃, -[p_i]×]`` of each accelerometer i, and
  ``G = M H⁺`` (:func:`rigid_motion`), M the desk's spatial inertia about P_o (mass, centre
  of mass and inertia tensor from the profile: :meth:`DeskProfile.inertia_about_com`; a
  wrong inertia leaves a wrong moment: give it when the desk is no uniform box). Two
  accelerometers, or three on one line or with two axes each, leave some rotation unseen;
  of the motions that fit their readings the one with the least rotation is taken.

A reading that is missing (NaN, no accelerometer data given at all) or at its range is not
used. With one accelerometer that sample is left uncompensated and flagged
``FLAG_NO_ACCEL``, never NaN. With several, the sample is compensated from the readings that
are usable (the motion they see; with one board of three lost the rotation about the
other two's line is unseen: 7-10 % of a random motion's wrench left) and flagged only when
none is. The
desk's mass and centre of mass come from the profile (``desk.mass_kg``,
``desk.center_of_mass_m`` or its default, :meth:`DeskProfile.center_of_mass`).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from hapticdesk.estimator.contacts import FLAG_NO_ACCEL
from hapticdesk.estimator.kernel_slots import J_PARTIAL, J_PARTIAL_PATTERN
from hapticdesk.estimator.notices import Notice, add_notice
from hapticdesk.files.profile import STANDARD_GRAVITY, AccelerometerSpec, DeskProfile
from hapticdesk.files.recording import named_columns
from hapticdesk.files.rigid_body import skew, spatial_inertia


@dataclass(frozen=True, eq=False)
class InertiaSettings:
    """One desk's fixed quantities for the compensation (see the module docstring)."""

    gain: np.ndarray  # (6, A): the inertial wrench per unit of reading (module docstring)
    rest: np.ndarray  # (A,): the reading of a desk at rest (gravity along each axis)
    limit: np.ndarray  # (A,): |reading| at or beyond this is saturated
    n_axes: int
    columns: tuple[str, ...]  # the recording columns the readings come from
    # several accelerometers: the rows of H and their weights, with M, for the gain without
    # some readings (gain_from); None with one (the translating desk needs all its axes)
    rows: np.ndarray | None = None  # (A, 6)
    weights: np.ndarray | None = None  # (A,)
    spatial: np.ndarray | None = None  # (6, 6) the desk's spatial inertia M
    _partial: dict[bytes, np.ndarray] = field(
        default_factory=dict, init=False, repr=False, compare=False
    )

    def gain_from(self, usable: np.ndarray) -> np.ndarray | None:
        """The gain (6, A) from only the ``usable`` readings (A,) bool (zero columns for the
        others), or None where they cannot give the motion (one accelerometer, or none
        usable). Cached per pattern: a lost frame or a saturated axis recurs."""
        usable = np.asarray(usable, dtype=bool)
        if usable.shape != (self.n_axes,):
            raise ValueError(f"usable must be ({self.n_axes},) bool, found {usable.shape}")
        if self.rows is None or self.weights is None or self.spatial is None or not usable.any():
            return None
        key = usable.tobytes()
        gain = self._partial.get(key)
        if gain is None:
            gain = np.zeros((6, self.n_axes))
            gain[:, usable] = self.spatial @ rigid_motion(self.rows[usable], self.weights[usable])
            self._partial[key] = gain
        return gain

    @classmethod
    def of(cls, profile: DeskProfile) -> InertiaSettings | None:
        """The settings for ``profile``, or None when it has no accelerometer."""
        specs = profile.accelerometers
        if not specs:
            return None
        if profile.mass_kg is None:  # (the profile loader refuses this; a hand-made profile)
            raise ValueError(f"desk {profile.name!r} has an accelerometer but no mass_kg")
        m = profile.mass_kg
        c = profile.center_of_mass()
        axes = np.hstack([spec.axis_matrix() for spec in specs])  # (3, A)
        spatial = spatial_inertia(m, c, profile.inertia_about_com())
        rows = weights = None
        if len(specs) == 1:  # the desk taken as translating: d̈ = R_a f, M q̈ = [m d̈; m c × d̈]
            gain = spatial[:, :3] @ axes  # (6, A)
        else:  # the rigid motion q̈ from the readings, then M q̈
            rows, weights = motion_rows(specs)
            gain = spatial @ rigid_motion(rows, weights)
        rest = axes.T @ np.array([0.0, 0.0, STANDARD_GRAVITY])
        limit = np.concatenate([np.full(len(spec.axes), spec.range_m_s2) for spec in specs])
        return cls(
            gain=np.ascontiguousarray(gain),
            rest=rest,
            limit=limit,
            n_axes=axes.shape[1],
            columns=tuple(profile.accelerometer_columns()),
            rows=rows,
            weights=weights,
            spatial=spatial,
        )


#: how much a rotation the accelerometers cannot tell apart costs against a translation in
#: :func:`rigid_motion` (rad/s² per m/s²): what they do not see is taken as translation
UNSEEN_ROTATION_SCALE = 1e-2


def motion_rows(specs: tuple[AccelerometerSpec, ...]) -> tuple[np.ndarray, np.ndarray]:
    """The rows (A, 6) of H, R_iᵀ [I₃, −[p_i]×] for each accelerometer i (its readings less
    gravity are H q̈), and their weights (A,): 1/σ of each accelerometer when all give a
    noise, else equal."""
    rows, sigma = [], []
    for spec in specs:
        rows.append(spec.axis_matrix().T @ np.hstack([np.eye(3), -skew(spec.position)]))
        sigma += [spec.noise_m_s2] * len(spec.axes)
    noise = np.array(sigma)
    weights = 1.0 / noise if (noise > 0).all() else np.ones(len(noise))
    return np.vstack(rows), weights


def rigid_motion(rows: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """(6, A): the desk's rigid motion q̈ = [d̈; θ̈] from readings less gravity, the weighted
    least-squares solution of f − f_rest = H q̈ (:func:`motion_rows`). Three accelerometers
    not on one line see the whole motion and this is exact; fewer leave some rotations
    unseen, and of the motions that fit the readings this takes the one with the least
    rotation (scaled by UNSEEN_ROTATION_SCALE), not a mix of translation and rotation."""
    scale = np.diag([1.0, 1.0, 1.0] + [UNSEEN_ROTATION_SCALE] * 3)
    return scale @ np.linalg.pinv((weights[:, None] * rows) @ scale) * weights[None, :]


class InertiaStage:
    """The readings checked, and the inertial wrench removed from a whole resultant wrench at
    once: the model the kernel runs per sample (``_inertial`` in
    :mod:`hapticdesk.estimator.kernel_inertia`), for the analyses that look at the compensated
    wrench itself (its balance, the ring left after a swipe).

    Stateless: each sample's correction depends on its own reading only.
    """

    def __init__(self, settings: InertiaSettings) -> None:
        self.settings = settings

    def check(self, accel: np.ndarray | None, k: int) -> np.ndarray | None:
        """``accel`` as (k, A) floats, or None; a clear error for a wrong shape."""
        if accel is None:
            return None
        accel = np.asarray(accel, dtype=float)
        s = self.settings
        if accel.shape != (k, s.n_axes):
            raise ValueError(
                f"accel must have shape (k, A) = ({k}, {s.n_axes}) for the accelerometers' "
                f"columns {', '.join(s.columns)}, found {accel.shape}"
            )
        return accel

    def usable_axes(self, accel: np.ndarray) -> np.ndarray:
        """Which axes' readings (..., A) can be used: finite and inside the range."""
        with np.errstate(invalid="ignore"):  # NaN compares False: not usable
            return np.asarray(np.abs(accel) < self.settings.limit)

    def partial_gain_into(
        self, readings: np.ndarray, sf: np.ndarray, si: np.ndarray, gain_at: int
    ) -> None:
        """Several accelerometers, some ``readings`` (A,) not usable: the gain from the
        usable ones, or none usable, into the kernel's state (``sf`` at ``gain_at``, ``si``)
        for it to use while the same ones are."""
        usable = self.usable_axes(readings)
        gain = self.settings.gain_from(usable)
        # (the kernel keeps this gain for the same usable readings: one bit each)
        si[J_PARTIAL_PATTERN] = sum(1 << int(j) for j in np.flatnonzero(usable)) + 1
        if gain is None:
            si[J_PARTIAL] = 2
            return
        sf[gain_at : gain_at + gain.size] = gain.ravel()
        si[J_PARTIAL] = 1

    def tell_missing(self, notices: list[Notice], t: float, desk: str) -> None:
        """A warning that samples of ``desk`` come without the accelerometer's readings (a
        recording without its columns, a source that does not pass them): they are estimated
        uncompensated, and only the ``no_accel`` flag would say so."""
        add_notice(
            notices,
            t,
            "no_accel",
            f"no accelerometer readings ({', '.join(self.settings.columns)}) come with "
            f"the samples of desk {desk!r}: its sway is not compensated (the "
            "samples are flagged no_accel)",
            logging.WARNING,
        )

    def usable(self, accel: np.ndarray) -> np.ndarray:
        """Which readings (..., A) can be used whole: every axis finite and inside the range."""
        return np.asarray(self.usable_axes(accel).all(axis=-1))

    def process(self, raw: np.ndarray, accel: np.ndarray | None) -> np.ndarray:
        """Subtract the inertial wrench from ``raw`` (6, k) in place where the readings in
        ``accel`` (k, A) are usable; returns the flags (k,) uint8, ``FLAG_NO_ACCEL`` where
        the sample is left uncompensated (every sample when ``accel`` is None). With several
        accelerometers a sample some of whose axes are lost or saturated is compensated from
        the others (:meth:`InertiaSettings.gain_from`), unflagged while any is usable."""
        flags = np.zeros(raw.shape[1], np.uint8)
        if accel is None:
            flags[:] = FLAG_NO_ACCEL
            return flags
        axes = self.usable_axes(accel)
        usable = axes.all(axis=1)
        if usable.all():
            raw -= inertial_wrench(self.settings, accel).T
            return flags
        # the rest reading where an axis is not usable: none of it (and no NaN) gets in
        accel = np.where(axes, accel, self.settings.rest)
        raw[:, usable] -= inertial_wrench(self.settings, accel[usable]).T
        partial = np.flatnonzero(~usable)
        patterns, which = np.unique(axes[partial], axis=0, return_inverse=True)
        for j, pattern in enumerate(patterns):
            at = partial[which.reshape(-1) == j]
            gain = self.settings.gain_from(pattern)
            if gain is None:
                flags[at] = FLAG_NO_ACCEL
            else:
                raw[:, at] -= gain @ (accel[at] - self.settings.rest).T
        return flags


def inertial_wrench(settings: InertiaSettings, accel: np.ndarray) -> np.ndarray:
    """The desk's inertial wrench ``[m a; m c × a]`` (..., 6) about P_o for readings
    (..., A) (see the module docstring)."""
    return (accel - settings.rest) @ settings.gain.T


def accelerometer_readings(
    profile: DeskProfile, columns: dict[str, np.ndarray]
) -> np.ndarray | None:
    """The accelerometer's readings (k, A) from a recording's extra columns, or None when the
    desk has no accelerometer or the recording lacks its columns (then every sample is
    estimated uncompensated, flagged)."""
    return named_columns(columns, profile.accelerometer_columns())
