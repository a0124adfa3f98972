"""The physical desk: a rigid body standing on S legs, each leg a 6-DOF spring-damper.

A desk on four legs is statically indeterminate: how a load splits between the legs, and how
much of it each sensor carries as its own moment, depends on the legs' stiffness. Each leg is
modelled as a spring-damper with six degrees of freedom at its *spring point*, a height
``leg_spring_height_m`` above its sensor (by default half-way up to the top board, where a leg
bent in double curvature has its inflection point, so a horizontal shear ``f`` reaches the
sensor with a moment ``h·f``). The sensor under the leg reads the spring's wrench moved to the
sensor's position, rotated into the sensor's frame and signed as the sensor reports it.

Small motions of the rigid desk about the desk origin P_o, ``q = [d; θ]`` (translation and
rotation), obey

    M q̈ + C q̇ + K q = u,       u = Σ [F_j; P_j × F_j]   (loads, about P_o)

with ``K = Σ T_iᵀ K_i T_i`` and ``T_i`` mapping the desk's motion to leg i's spring point.
The supports' resultant (what :meth:`DeskProfile.wrench_map` recovers from the readings) is
``-K q - C q̇ = M q̈ - u``: the negated load plus the inertial term, paper eqs. (1)–(2) for a
desk at rest.

A leg on a load cell (a sensor that measures no moment: ``kind: load_cell``, a three-axis
cell) stands on a *pin*: it passes its axial force to the cell and no moment, and what holds
the desk sideways (friction at the foot, the frame the cell is bolted to) acts at the cell,
where the cell does not feel it. Its spring point is the cell itself and it has no
rotational stiffness (``DeskParameters.legs``), so the cells' axial forces alone carry the
desk's moments about horizontal axes: Σ fz_i at p_i gives F_z, M_x and M_y exactly, as the
weight tables of the literature assume. A finger's sideways push ``f`` at the top's height
``h`` is not seen as a force, but its moment ``h·f`` is, as a centre of pressure moved by
``h·f/F_z`` (a load cell cannot tell it from a press elsewhere).

Stiffness is set from the frequencies a user knows: the horizontal ("sway") stiffness of the
legs is scaled so the lowest mode is the desk's natural frequency (the paper's 5.9 Hz) and
the vertical stiffness puts the vertical mode at ``vertical_frequency_hz``, far above the
sample rate. Sway and vertical damping are stiffness-proportional per leg with separate
factors, so each family of modes gets roughly its own damping ratio.

Integration is exact for an input held constant over each sample interval (zero-order hold;
each sample's load is held over the interval that ends at it, so a reading responds to the
load at its own time): the discrete model comes from the matrix exponential of the augmented
matrix ``[[A, B], [0, 0]]`` (``scipy.linalg.expm``), so modes far above the sample rate
neither blow up nor need a smaller step. The discrete recursion is diagonalised and each
mode runs as a first-order ``scipy.signal.lfilter`` with carried state: vectorised, and
identical for any split into blocks (:mod:`.discrete_desk`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import scipy.linalg
import scipy.optimize

from hapticdesk.files.profile import STANDARD_GRAVITY, DeskProfile, SensorSpec
from hapticdesk.files.rigid_body import skew, spatial_inertia
from hapticdesk.sim.discrete_desk import DiscreteDesk

DEFAULT_MASS_KG = 13.7  # the paper's desk (Table 1)
DEFAULT_SWAY_HZ = 5.9  # the paper's desk (§3.2)
LEG_KINDS = ("auto", "clamped", "pinned")


def measures_moment(sensor: SensorSpec) -> bool:
    """True when some channel of ``sensor`` measures a moment (a six-axis sensor, a force
    plate's amplifier), False for a load cell or a three-axis cell."""
    return bool(np.abs(sensor.own_wrench_matrix()[3:]).any())


def point_load(force: np.ndarray, point: np.ndarray) -> np.ndarray:
    """Wrench [F; P × F] about the desk origin of forces (..., 3) applied at points (..., 3)."""
    force = np.asarray(force, dtype=float)
    point = np.asarray(point, dtype=float)
    return np.concatenate([force, np.cross(point, force)], axis=-1)


@dataclass(frozen=True)
class DeskParameters:
    """Mechanical parameters of the simulated desk. ``None`` means "derive from the profile".

    - ``mass_kg``: the desk's mass (profile ``desk.mass_kg``, else the paper's 13.7 kg).
    - ``sway_frequency_hz``: the lowest natural frequency (profile ``desk.natural_frequency_hz``,
      else the paper's 5.9 Hz).
    - ``vertical_frequency_hz``: the desk bouncing on its legs' (and sensors') axial stiffness.
    - ``sway_damping``, ``vertical_damping``: damping ratios of the two families of modes.
    - ``center_of_mass``: desk frame, metres (default: the profile's
      :meth:`~DeskProfile.center_of_mass`, given or above the sensors' centroid at 85 % of
      the top board's height, a heavy top on light legs).
    - ``inertia_kg_m2``: principal moments about the centre of mass along the desk axes
      (default: a solid box as wide and deep as the top board and as tall as the desk).
    - ``leg_spring_height_m``: height of each leg's spring point above its sensor (default:
      half the top board's height, the inflection point of a leg bent in double curvature).
    - ``leg_rotation_ratio``: each leg's rotational stiffness as a fraction of
      ``k_horizontal · leg_spring_height²`` (how much moment a leg joint resists itself).
    - ``legs``: ``"clamped"`` (the 6-DOF springs above), ``"pinned"`` (each leg a strut on a
      pin at its sensor: axial force only, held sideways at the sensor, no moment; the two
      settings above do not apply) or ``"auto"``: pinned when no sensor of the desk measures
      a moment (load cells, three-axis cells), clamped otherwise.
    """

    mass_kg: float | None = None
    sway_frequency_hz: float | None = None
    vertical_frequency_hz: float = 3000.0
    sway_damping: float = 0.03
    vertical_damping: float = 0.05
    center_of_mass: tuple[float, float, float] | None = None
    inertia_kg_m2: tuple[float, float, float] | None = None
    leg_spring_height_m: float | None = None
    leg_rotation_ratio: float = 0.25
    legs: str = "auto"


class _LegLevers(NamedTuple):
    """What placing the legs gives their springs: the spring point's height above the sensor
    and the rotational stiffness ratio (both 0 on pinned legs)."""

    spring_height_m: float
    rotation_ratio: float


class DeskModel:
    """The continuous-time model of a desk described by a profile (see the module docstring).

    Attributes: ``mass_matrix``, ``stiffness``, ``damping`` (6, 6) about the desk origin;
    ``center_of_mass`` (3,); ``spring_points`` (S, 3); ``mass_kg``.
    """

    def __init__(self, profile: DeskProfile, params: DeskParameters | None = None) -> None:
        params = params or DeskParameters()
        self.profile = profile
        self.params = params
        self._set_frequencies(profile, params)
        self._set_inertia(profile, params)
        levers = self._place_legs(profile, params)
        self._set_leg_springs(params, levers)
        self._set_readout(profile.sensors)

    def _set_frequencies(self, profile: DeskProfile, params: DeskParameters) -> None:
        """The mass and the two mode frequencies, given or the profile's, checked."""
        self.mass_kg = float(params.mass_kg or profile.mass_kg or DEFAULT_MASS_KG)
        self.sway_frequency_hz = float(
            params.sway_frequency_hz or profile.natural_frequency_hz or DEFAULT_SWAY_HZ
        )
        self.vertical_frequency_hz = float(params.vertical_frequency_hz)
        _check_positive(
            mass_kg=self.mass_kg,
            sway_frequency_hz=self.sway_frequency_hz,
            vertical_frequency_hz=self.vertical_frequency_hz,
        )
        if self.vertical_frequency_hz <= self.sway_frequency_hz:
            raise ValueError(
                f"vertical_frequency_hz ({self.vertical_frequency_hz:g}) must be above the sway "
                f"frequency ({self.sway_frequency_hz:g})"
            )

    def _set_inertia(self, profile: DeskProfile, params: DeskParameters) -> None:
        """The centre of mass and the spatial inertia about the origin."""
        com = (
            np.array(params.center_of_mass, dtype=float)
            if params.center_of_mass is not None
            else profile.center_of_mass()
        )
        self.center_of_mass = com
        if params.inertia_kg_m2 is not None:
            inertia = np.diag(np.asarray(params.inertia_kg_m2, dtype=float))
        else:  # the profile's, or a solid box of this mass (the estimator's default too)
            inertia = profile.inertia_about_com(self.mass_kg)
        # spatial inertia about the origin for small motions (d, θ): momentum = M [ḋ; θ̇]
        self.mass_matrix = spatial_inertia(self.mass_kg, com, inertia)

    def _place_legs(self, profile: DeskProfile, params: DeskParameters) -> _LegLevers:
        """Clamped or pinned legs, their spring points and the transfers T_i to them."""
        sensors = profile.sensors
        positions = np.array([s.position for s in sensors], dtype=float)
        if params.legs not in LEG_KINDS:
            raise ValueError(f"legs must be one of {', '.join(LEG_KINDS)}, found {params.legs!r}")
        self.pinned = params.legs == "pinned" or (
            params.legs == "auto" and not any(measures_moment(s) for s in sensors)
        )
        h_spring = params.leg_spring_height_m
        h_spring = 0.5 * profile.top_height_m() if h_spring is None else float(h_spring)
        rotation_ratio = params.leg_rotation_ratio
        if self.pinned:  # the spring is the pin at the cell: no lever, no moment
            h_spring, rotation_ratio = 0.0, 0.0
        self.spring_points = positions + np.array([0.0, 0.0, h_spring])
        # T_i: desk motion about the origin -> displacement and rotation at spring point i
        self._transfer = np.zeros((len(sensors), 6, 6))
        for i, s in enumerate(self.spring_points):
            self._transfer[i] = np.eye(6)
            self._transfer[i, :3, 3:] = -skew(s)
        return _LegLevers(h_spring, rotation_ratio)

    def _set_leg_springs(self, params: DeskParameters, levers: _LegLevers) -> None:
        """Each leg's stiffness and damping, the sway stiffness solved for the lowest mode."""
        n = len(self.spring_points)
        # vertical stiffness from the vertical mode of the desk as one mass on all legs
        k_vertical = self.mass_kg * (2 * math.pi * self.vertical_frequency_hz) ** 2 / n
        rot_ratio = levers.rotation_ratio * max(levers.spring_height_m, 0.05) ** 2
        sway_unit = np.array([1.0, 1.0, 0.0, rot_ratio, rot_ratio, rot_ratio])
        vert_unit = np.array([0.0, 0.0, k_vertical, 0.0, 0.0, 0.0])
        target = 2 * math.pi * self.sway_frequency_hz
        k_h = self._sway_stiffness(sway_unit, vert_unit, target)
        leg_sway = k_h * sway_unit
        self.leg_stiffness = leg_sway + vert_unit  # (6,) diagonal of each K_i
        beta_sway = 2 * params.sway_damping / target
        beta_vert = 2 * params.vertical_damping / (2 * math.pi * self.vertical_frequency_hz)
        self.leg_damping = beta_sway * leg_sway + beta_vert * vert_unit
        self.stiffness = self._assemble(self.leg_stiffness)
        self.damping = self._assemble(self.leg_damping)

    def _sway_stiffness(self, sway_unit: np.ndarray, vert_unit: np.ndarray, target: float) -> float:
        """The legs' sway stiffness that puts the lowest mode at ``target`` rad/s."""

        def lowest(log_k: float) -> float:
            k = self._assemble(math.exp(log_k) * sway_unit + vert_unit)
            lowest_mode = scipy.linalg.eigh(k, self.mass_matrix, eigvals_only=True)[0]
            return float(np.sqrt(lowest_mode)) - target

        # the lowest mode rises monotonically with the sway stiffness: bracket, then solve
        lo, hi = math.log(1e-3), math.log(1e13)  # (up to the profile's 10 t at 0.4 fs)
        if lowest(lo) > 0 or lowest(hi) < 0:
            raise ValueError(
                f"cannot place the lowest mode at {self.sway_frequency_hz:g} Hz with these legs"
            )
        return math.exp(scipy.optimize.brentq(lowest, lo, hi, xtol=1e-13, rtol=1e-14))

    def _set_readout(self, sensors: tuple[SensorSpec, ...]) -> None:
        """Readings: leg spring wrench -> at the sensor -> sensor frame and sign."""
        n = len(sensors)
        readout = np.zeros((n, 6, 6))
        for i, s in enumerate(sensors):
            move = np.eye(6)
            move[3:, :3] = skew(self.spring_points[i] - s.position)
            frame = np.zeros((6, 6))
            frame[:3, :3] = frame[3:, 3:] = s.sign * s.rotation.T
            readout[i] = frame @ move
        self._readout = readout
        # stacked readings (6S,) = read_q @ q + read_v @ q̇
        self.read_q = -np.concatenate(
            [readout[i] @ (self.leg_stiffness[:, None] * self._transfer[i]) for i in range(n)]
        )
        self.read_v = -np.concatenate(
            [readout[i] @ (self.leg_damping[:, None] * self._transfer[i]) for i in range(n)]
        )
        self._static = self.read_q @ np.linalg.inv(self.stiffness)  # (6S, 6)

    def _assemble(self, leg_diag: np.ndarray) -> np.ndarray:
        return np.einsum("iab,a,iac->bc", self._transfer, leg_diag, self._transfer)

    @property
    def n_sensors(self) -> int:
        return len(self.profile.sensors)

    def weight(self) -> np.ndarray:
        """The desk's own weight as a load (6,) about the origin."""
        return point_load(
            np.array([0.0, 0.0, -self.mass_kg * STANDARD_GRAVITY]), self.center_of_mass
        )

    def natural_frequencies_hz(self) -> np.ndarray:
        """Undamped natural frequencies (6,), ascending."""
        eig = scipy.linalg.eigh(self.stiffness, self.mass_matrix, eigvals_only=True)
        return np.sqrt(np.maximum(eig, 0.0)) / (2 * math.pi)

    def state_matrices(self) -> tuple[np.ndarray, np.ndarray]:
        """Continuous ``ẋ = A x + B u`` for ``x = [q; q̇]`` (12,) and loads ``u`` (6,)."""
        m_inv = np.linalg.inv(self.mass_matrix)
        a = np.zeros((12, 12))
        a[:6, 6:] = np.eye(6)
        a[6:, :6] = -m_inv @ self.stiffness
        a[6:, 6:] = -m_inv @ self.damping
        b = np.zeros((12, 6))
        b[6:] = m_inv
        return a, b

    def static_readings(self, loads: np.ndarray) -> np.ndarray:
        """Readings (k, S, 6) in each sensor's frame for loads (k, 6) held still (no dynamics)."""
        loads = np.atleast_2d(np.asarray(loads, dtype=float))
        return (loads @ self._static.T).reshape(len(loads), self.n_sensors, 6)

    def readings(self, q: np.ndarray, qdot: np.ndarray) -> np.ndarray:
        """Readings (k, S, 6) for desk motions q, q̇ (k, 6)."""
        flat = np.atleast_2d(q) @ self.read_q.T + np.atleast_2d(qdot) @ self.read_v.T
        return flat.reshape(len(flat), self.n_sensors, 6)

    def accelerations(self, loads: np.ndarray, motion: np.ndarray) -> np.ndarray:
        """``q̈`` (k, 6) from the equation of motion, ``M q̈ = u - K q - C q̇``, for loads
        (k, 6) and motions ``[q, q̇]`` (k, 12)."""
        rhs = loads - motion[:, :6] @ self.stiffness.T - motion[:, 6:] @ self.damping.T
        return np.linalg.solve(self.mass_matrix, rhs.T).T

    def discretize(self, dt: float) -> DiscreteDesk:
        """The exact zero-order-hold discrete model for sample time ``dt``."""
        a, b = self.state_matrices()
        return DiscreteDesk(a, b, np.hstack([self.read_q, self.read_v]), dt)


def _check_positive(**values: float) -> None:
    for name, value in values.items():
        if not (value > 0 and math.isfinite(value)):
            raise ValueError(f"{name} must be a positive number, found {value}")
