"""What a six-axis force/torque sensor adds to the true wrench: offset and drift, noise,
resolution and saturation (applied in that order, in each sensor's own frame).

Noise. The paper gives one number: "F_z measured when no external force is applied shows a
maximum 0.4 N amplitude" on the total F_z of the desk (§3.1). Here that amplitude is read as
``noise_amplitude_sigmas`` (3) standard deviations of Gaussian white noise on the *sum* of
the sensors' F_z, including the rounding error of the sensors' resolution (whose variance is
step²/12 when the true value sits anywhere between two steps: the amplitude holds on
average over the sensors' random zero offsets, and varies by a few per cent from one set of
offsets to another). Every channel of a sensor gets the same fraction of its rated output as
noise σ, so F_x, F_y (rated 150 N) are half as noisy as F_z (300 N) and moments follow their
4 N·m rating. Sensors without a ``range`` in the profile are treated as rated like the paper's
(±150 N, ±150 N, ±300 N, ±4 N·m) for noise; they have no resolution or saturation.

Resolution: readings are rounded to 1/2000 of the rated output (paper Table 2). Saturation:
readings are then clipped to ± the rated range; the estimator flags a channel at its limit.

Drift: every channel starts at a random zero offset and drifts linearly at a random rate
(both Gaussian, given for an F_z rated 300 N and scaled by each channel's rating).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.rigid_body import skew
from hapticdesk.sim.desk import STANDARD_GRAVITY

PAPER_RATING = np.array([150.0, 150.0, 300.0, 4.0, 4.0, 4.0])  # Table 2


@dataclass(frozen=True)
class SensorParameters:
    """Sensor imperfections. Amounts are for an F_z channel rated 300 N (see module doc).

    - ``noise_amplitude_n``: amplitude of the noise on the desk's total F_z at rest.
    - ``noise_amplitude_sigmas``: how many σ that amplitude stands for.
    - ``resolution``: the reading's step as a fraction of the rated output.
    - ``offset_n``: σ of each channel's zero offset.
    - ``drift_n_per_min``: σ of each channel's drift rate.
    """

    noise_amplitude_n: float = 0.4
    noise_amplitude_sigmas: float = 3.0
    resolution: float = 1.0 / 2000.0
    offset_n: float = 0.3
    drift_n_per_min: float = 0.05


class SensorModel:
    """Turns true readings (k, S, 6) into what the sensors deliver. Which effects apply is
    chosen per call, so one model serves any :class:`~hapticdesk.sim.SimEffects`."""

    def __init__(
        self,
        profile: DeskProfile,
        params: SensorParameters | None = None,
        *,
        quantisation: bool = True,
    ) -> None:
        self.params = p = params or SensorParameters()
        if not (p.noise_amplitude_n >= 0 and p.noise_amplitude_sigmas > 0 and p.resolution >= 0):
            raise ValueError(
                "noise_amplitude_n and resolution must be >= 0, noise_amplitude_sigmas > 0"
            )
        n = len(profile.sensors)
        rating = np.tile(PAPER_RATING, (n, 1))
        limits = np.full((n, 6), np.inf)
        for i, s in enumerate(profile.sensors):
            if s.force_range is not None:
                rating[i, :3] = limits[i, :3] = s.force_range
            if s.moment_range is not None:
                rating[i, 3:] = limits[i, 3:] = s.moment_range
        self.rating = rating  # (S, 6) for scaling noise and drift
        self.limits = limits  # (S, 6) saturation (inf where the profile gives no range)
        self.step = np.where(np.isfinite(limits), limits * p.resolution, 0.0)  # (S, 6)
        fraction = rating / PAPER_RATING[2]  # each channel relative to a 300 N F_z

        # Solve the noise level a (σ = a·rating) so that σ of Σ F_z (desk frame) is the target.
        # A reading v_s maps to ±R·v_s, so the desk's F_z row of sensor i is R_i[2, :].
        rows = np.array([s.rotation[2] for s in profile.sensors])  # (S, 3)
        weight = rows**2
        target_var = (p.noise_amplitude_n / p.noise_amplitude_sigmas) ** 2
        rounding_var = float(np.sum(weight * self.step[:, :3] ** 2) / 12.0) if quantisation else 0.0
        per_unit_var = float(np.sum(weight * rating[:, :3] ** 2))
        a2 = max(target_var - rounding_var, 0.0) / per_unit_var
        self.noise_sigma = np.sqrt(a2) * rating  # (S, 6)
        self.offset_sigma = p.offset_n * fraction
        self.drift_sigma = p.drift_n_per_min / 60.0 * fraction  # per second

    def draw_drift(self, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """Per-channel zero offsets and drift rates (S, 6) each."""
        offset = rng.standard_normal(self.rating.shape) * self.offset_sigma
        rate = rng.standard_normal(self.rating.shape) * self.drift_sigma
        return offset, rate

    def apply(
        self,
        readings: np.ndarray,
        t: np.ndarray,
        *,
        noise_rng: np.random.Generator | None,
        drift: tuple[np.ndarray, np.ndarray] | None,
        quantisation: bool,
        saturation: bool,
    ) -> np.ndarray:
        """The delivered readings for true ``readings`` (k, S, 6) at times ``t`` (k,).

        ``noise_rng`` None = no noise; ``drift`` None = no offset or drift.
        """
        out = np.array(readings, dtype=float)
        if drift is not None:
            offset, rate = drift
            out += offset + rate * t[:, None, None]
        if noise_rng is not None:
            out += noise_rng.standard_normal(out.shape) * self.noise_sigma
        if quantisation:
            has_step = self.step > 0
            step = np.where(has_step, self.step, 1.0)
            out = np.where(has_step, np.round(out / step) * step, out)
        if saturation:  # after rounding, so a saturated reading sits exactly at the limit
            np.clip(out, -self.limits, self.limits, out=out)
        return out


class AccelerometerModel:
    """The accelerometers fixed to the desk (profile ``accelerometer`` or ``accelerometers``):
    the specific force at each mount, in its own frame, plus white noise, clipped at its range.

    For the small motions of :class:`~hapticdesk.sim.desk.DeskModel` (``q = [d; θ]`` about
    the desk origin) the mount at ``p`` accelerates by ``a_p = d̈ + θ̈ × p`` and the
    accelerometer, turned by ``θ``, reads ``Rᵀ (a_p - g + θ × g)`` with g = (0, 0, -9.81)
    m/s² in the desk frame: +g upwards at rest, and the tilt's share of gravity as a real one
    does. Readings are the accelerometers' axes one after the other (their columns' order).
    """

    def __init__(self, profile: DeskProfile) -> None:
        if not profile.accelerometers:
            raise ValueError(f"desk {profile.name!r} has no accelerometer")
        self.specs = profile.accelerometers
        self.columns = profile.accelerometer_columns()
        self._parts = [(spec.axis_matrix(), skew(spec.position)) for spec in self.specs]
        self._noise = np.concatenate([np.full(len(s.axes), s.noise_m_s2) for s in self.specs])
        self._limit = np.concatenate([np.full(len(s.axes), s.range_m_s2) for s in self.specs])

    def readings(
        self,
        qdd: np.ndarray,
        q: np.ndarray,
        *,
        noise_rng: np.random.Generator | None,
        saturation: bool,
    ) -> np.ndarray:
        """Readings (k, A) for desk accelerations ``q̈`` and positions ``q`` (k, 6) each."""
        gravity = np.array([0.0, 0.0, -STANDARD_GRAVITY])
        tilt = np.cross(q[:, 3:], gravity)
        parts = []
        for axes, lever in self._parts:
            accel = qdd[:, :3] - qdd[:, 3:] @ lever.T  # d̈ + θ̈ × p = d̈ - [p]× θ̈
            parts.append((accel - gravity + tilt) @ axes)
        out = parts[0] if len(parts) == 1 else np.hstack(parts)
        if noise_rng is not None and (self._noise > 0).any():
            out += noise_rng.standard_normal(out.shape) * self._noise
        if saturation:
            np.clip(out, -self._limit, self._limit, out=out)
        return out
