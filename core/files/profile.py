"""Desk profiles: where the sensors stand, which surfaces can be touched, and how to estimate.

The YAML format is a contract (docs/reference/profile.md); this module is the model it fills,
knowing nothing of YAML (:mod:`.profile_reader` loads and checks a profile), and owns the one
map from the sensors' channels to the wrench about P_o (paper eqs. 1–4) all consumers use.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from hapticdesk.files.rigid_body import skew

METHODS = ("force", "diff", "switched", "fused")
LOWPASS_PER_NATURAL_FREQUENCY = 4.77 / 5.9  # the paper's cut-off for its desk's lowest mode
AXES = ("fx", "fy", "fz", "mx", "my", "mz")
ACCEL_AXES = ("x", "y", "z")
STANDARD_GRAVITY = 9.80665  # m/s²: the desk's weight (simulator), an accelerometer's rest reading
DEFAULT_TOP_HEIGHT_M = 0.7  # a desk's top above its sensors when the profile has no surface
COM_HEIGHT_FRACTION = 0.85  # the default centre of mass: a heavy top on light legs


@dataclass(frozen=True)
class SensorSpec:
    """One sensor under the desk: its place, orientation, sign convention, rated range, and
    which raw channels it delivers.

    A six-axis force/torque sensor (the paper's, the default) delivers ``fx … mz``; a load
    cell only ``fz``; a three-axis cell ``fx, fy, fz`` (``channels`` a subset of
    :data:`AXES`, each channel its axis). A force plate's amplifier delivers raw channels
    (a Kistler plate's ``fx12, fx34, fy14, fy23, fz1 … fz4``, or a plate's six calibrated
    outputs) and a ``calibration`` matrix (6, n) maps them to the wrench [f; m] the sensor
    measures at its ``position``, in its own frame.
    """

    name: str
    position: np.ndarray  # (3,) desk frame, metres
    rotation: np.ndarray  # (3, 3) sensor frame -> desk frame
    reports: str = "reaction"  # "reaction" (the paper's) or "load" (opposite sign)
    force_range: np.ndarray | None = None  # (3,) N, |reading| >= range is saturated
    moment_range: np.ndarray | None = None  # (3,) N·m
    #: the raw channels' names (recording columns ``<name>_<channel>``), in order
    channels: tuple[str, ...] = AXES
    #: (6, n): raw channels -> the sensor's own wrench; None: each channel is the axis it names
    calibration: np.ndarray | None = None
    #: (n,): a raw channel at or beyond this is saturated (a calibrated sensor's amplifier)
    channel_range: np.ndarray | None = None

    @property
    def sign(self) -> float:
        """+1 when the sensor reports the wrench it exerts on the desk, -1 for the load."""
        return 1.0 if self.reports == "reaction" else -1.0

    @property
    def is_six_axis(self) -> bool:
        """True for a sensor whose six channels are fx … mz (the paper's kind)."""
        return self.calibration is None and self.channels == AXES

    def channel_names(self) -> list[str]:
        """Recording column names of this sensor's raw channels."""
        return [f"{self.name}_{channel}" for channel in self.channels]

    def own_wrench_matrix(self) -> np.ndarray:
        """(6, n): the sensor's wrench [f; m] in its own frame from its raw channels."""
        if self.calibration is not None:
            return np.array(self.calibration, dtype=float)
        out = np.zeros((6, len(self.channels)))
        for j, axis in enumerate(self.channels):
            out[AXES.index(axis), j] = 1.0
        return out

    def channel_limits(self) -> np.ndarray:
        """(n,) each raw channel's saturation limit (inf where the profile gives none)."""
        if self.calibration is not None:
            if self.channel_range is None:
                return np.full(len(self.channels), np.inf)
            return np.array(self.channel_range, dtype=float)
        per_axis = np.full(6, np.inf)
        if self.force_range is not None:
            per_axis[:3] = self.force_range
        if self.moment_range is not None:
            per_axis[3:] = self.moment_range
        return np.array([per_axis[AXES.index(axis)] for axis in self.channels])


def accel_column_prefix(index: int) -> str:
    """The recording columns' prefix of a desk's ``index``-th accelerometer (from 0): ``acc``,
    then ``acc2``, ``acc3``, …"""
    return "acc" if index == 0 else f"acc{index + 1}"


ACCEL_COLUMN = re.compile(r"acc(?:[2-9]|[1-9][0-9]+)?_[xyz]")  # any accelerometer's column


@dataclass(frozen=True)
class AccelerometerSpec:
    """An accelerometer fixed to the desk top (optional; issue 15 item 6).

    It is sampled with the sensors (one reading per sample, the same clock and rate) and
    reports the specific force (acceleration minus gravity, so +g upwards at rest) along
    ``axes`` of its own frame, in m/s²; recordings carry it as the columns
    :meth:`column_names` (``acc_x, acc_y, acc_z``; a desk's second and third accelerometers,
    profile ``accelerometers:``, ``acc2_x, …`` and ``acc3_x, …``: :func:`accel_column_prefix`).
    """

    position: np.ndarray  # (3,) desk frame, metres
    rotation: np.ndarray  # (3, 3) accelerometer frame -> desk frame
    axes: tuple[str, ...] = ACCEL_AXES  # which of its axes it measures, in column order
    noise_m_s2: float = 0.0  # σ of each axis's white noise (used by the simulator)
    range_m_s2: float = math.inf  # |reading| >= this is saturated
    prefix: str = "acc"  # its recording columns' prefix: see accel_column_prefix

    def column_names(self) -> list[str]:
        """Recording columns of the accelerometer, in order."""
        return [f"{self.prefix}_{axis}" for axis in self.axes]

    def axis_matrix(self) -> np.ndarray:
        """(3, A): the measured axes as unit vectors in the desk frame."""
        return self.rotation[:, [ACCEL_AXES.index(a) for a in self.axes]]


@dataclass(frozen=True)
class Surface:
    """A touchable plane with an outline (top board, shelf, a side panel, …).

    Points on the surface have local coordinates (u, v): ``P = origin + u·u_axis + v·v_axis``
    shifted by ``offset_uv`` so that horizontal surfaces without ``u_axis`` use desk (x, y).
    """

    name: str
    origin: np.ndarray  # (3,)
    normal: np.ndarray  # (3,) unit, pointing to where touches come from
    u_axis: np.ndarray  # (3,) unit, in the plane
    v_axis: np.ndarray  # (3,) unit, normal × u_axis
    polygon: np.ndarray  # (N, 2) outline in (u, v)
    offset_uv: np.ndarray = field(default_factory=lambda: np.zeros(2))

    def to_desk(self, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Local (u, v) -> desk points (..., 3)."""
        du = np.asarray(u) - self.offset_uv[0]
        dv = np.asarray(v) - self.offset_uv[1]
        return self.origin + du[..., None] * self.u_axis + dv[..., None] * self.v_axis

    def to_local(self, points: np.ndarray) -> np.ndarray:
        """Desk points (..., 3) -> local (u, v) (..., 2), projected onto the plane."""
        rel = np.asarray(points) - self.origin
        return np.stack([rel @ self.u_axis, rel @ self.v_axis], axis=-1) + self.offset_uv

    @property
    def is_desk_xy(self) -> bool:
        """True when (u, v) are the desk's (x, y) (a horizontal surface without u_axis)."""
        return bool(np.allclose(self.u_axis, [1, 0, 0]) and np.allclose(self.v_axis, [0, 1, 0]))


@dataclass(frozen=True)
class EstimationSettings:
    """How contacts are estimated. Defaults are the paper's (§3.2, §5.2)."""

    method: str = "switched"
    tare_s: float = 1.0
    tare_quiet_n: float = 1.0  # the tare window's low-passed |F| may vary this much at most
    contact_force_n: float = 2.0  # contact only while |F| >= this (paper §3.3 step 4)
    release_hysteresis_n: float = 0.5  # contact ends below contact_force_n - this
    # ... or, for a fall of the fast force steeper than this (N/s), where it is predicted to
    # cross contact_force_n (the fast low-pass's delay ahead); 0: the hysteresis alone
    release_slope_n_s: float = 10.0
    diff_window_s: float = 0.166  # n·T_s of the pseudo-differentiation, paper eq. (8)
    diff_lowpass_hz: float = 4.77  # below the desk's 5.9 Hz natural frequency
    force_lowpass_hz: float = 4.77  # the conventional second-order low-pass
    detect_lowpass_hz: float = 30.0  # fast path for touch-down and release
    touch_threshold_n: float = 5.67  # F_tth
    release_threshold_n: float = 11.8  # F_rth
    phase_rate_n_s: float = 4.0  # |d|F|/dt| below this is "hold"
    min_normal_cos: float = 0.2  # |n·F̂| below this is too oblique to trust
    max_sigma_m: float = 0.008  # `diff` and `fused` report a point only when its 1-σ is below
    contact_speed_m_s: float = 0.005  # expected finger drift, the model error of eq. (11)
    settle_s: float = 5.0  # a still load held this long becomes part of the zero
    object_settle_s: float = 0.6  # ... this long when it is as still as the idle desk (0: never)
    drift_settle_s: float = 0.4  # a desk idle and still this long is re-zeroed (0: never)
    drift_max_n: float = 1.0  # ... when what is left on it is less than this (0 s: never)
    drift_force_n_per_min: float = 0.05  # expected σ of a force channel's drift rate
    drift_moment_nm_per_min: float = 0.001  # ... and of a moment channel's
    still_n: float = 0.15  # "still": low-passed |F| varies less than this per window
    # a gap in sample times longer than this restarts the filters; a profile that does not
    # give it takes at least 2.5 sample intervals (below 50 Hz: 0.125 s at 20 Hz)
    max_gap_s: float = 0.05
    noise_force_n: float = 0.0  # per-channel noise σ if known; 0 = measure during the tare
    noise_moment_nm: float = 0.0
    # the readings come zeroed (a force plate's ZERO frames taken off by its reader, a board
    # that tares itself): no tare, the zero is 0 from the first sample and stays (no drift
    # followed, no object absorbed: a person standing still on a plate is no object); the
    # covariances take noise_force_n / noise_moment_nm, which must then be given
    zeroed: bool = False
    # the legs as the accelerometer: the desk's inertial force from the measured force's
    # curvature and `desk.natural_frequency_hz` (hapticdesk.estimator.sway); None (auto,
    # the default): on for `fused` on a desk without an accelerometer
    sway_compensation: bool | None = None
    # flag a second finger that lands while the first holds, and locate it
    # (hapticdesk.estimator.multitouch); a layout that binds two_finger_tap turns it on
    second_finger: bool = False
    hold_jumps: bool = True  # hold over a reading that jumps for one sample (a corrupt one)


@dataclass(frozen=True)
class DeskProfile:
    """A desk: sensors, surfaces, estimation settings, and the optional CAN and serial
    sections."""

    name: str
    sample_rate_hz: float
    sensors: tuple[SensorSpec, ...]
    surfaces: tuple[Surface, ...]
    estimation: EstimationSettings = field(default_factory=EstimationSettings)
    can: dict[str, Any] | None = None
    #: a board on a serial line: port, baud, scales (see hapticdesk.boards.settings)
    serial: dict[str, Any] | None = None
    path: Path | None = None
    mass_kg: float | None = None  # optional, used by the simulator
    natural_frequency_hz: float | None = None  # optional, used by the simulator
    # optional: the desk's centre of mass (desk frame, m); see :meth:`center_of_mass`
    center_of_mass_m: np.ndarray | None = None
    # optional: principal moments of inertia about the centre of mass along the desk's axes
    # (kg·m²); see :meth:`inertia_about_com`
    inertia_kg_m2: tuple[float, float, float] | None = None
    # optional accelerometers on the desk (see AccelerometerSpec): one measures the desk's
    # translation; three or more, not on one line, its rotation too (hapticdesk.estimator.inertia)
    accelerometers: tuple[AccelerometerSpec, ...] = ()

    @property
    def sensor_names(self) -> list[str]:
        return [s.name for s in self.sensors]

    def channel_names(self) -> list[str]:
        """All recording columns after ``t``, in order: every sensor's raw channels."""
        return [c for s in self.sensors for c in s.channel_names()]

    @property
    def channel_count(self) -> int:
        """C, the number of raw channels the desk's sensors deliver per sample."""
        return sum(len(s.channels) for s in self.sensors)

    @property
    def six_axis_only(self) -> bool:
        """True when every sensor is a six-axis one: samples may then come as (k, S, 6),
        the same numbers in the same order as (k, C)."""
        return all(s.is_six_axis for s in self.sensors)

    def flat_channels(self, readings: np.ndarray) -> np.ndarray:
        """Readings (k, C), or (k, S, 6) for a desk of six-axis sensors, as (k, C) (a view
        where it can be); a ValueError naming the expected shapes otherwise."""
        readings = np.asarray(readings, dtype=float)
        c = self.channel_count
        if readings.ndim == 2 and readings.shape[1] == c:
            return readings
        n = len(self.sensors)
        if readings.ndim == 3 and readings.shape[1:] == (n, 6) and self.six_axis_only:
            return readings.reshape(len(readings), c)
        expected = f"(k, {c})" + (f" or (k, {n}, 6)" if self.six_axis_only else "")
        raise ValueError(
            f"sensor readings for desk {self.name!r} must have shape {expected} (its channels "
            f"{', '.join(self.channel_names()[:8])}{', …' if c > 8 else ''}), "
            f"found {readings.shape}"
        )

    def with_estimation(self, **changes: Any) -> DeskProfile:
        """The same desk with these :class:`EstimationSettings` changed."""
        return replace(self, estimation=replace(self.estimation, **changes))

    def surface(self, name: str) -> Surface:
        for s in self.surfaces:
            if s.name == name:
                return s
        raise KeyError(
            f"desk {self.name!r} has no surface {name!r}; it has "
            f"{', '.join(s.name for s in self.surfaces) or 'none'}"
        )

    def top_height_m(self) -> float:
        """Height of the first surface above the sensors, however close (a board's top 4 cm
        over its cells, a desk's top 3 cm over cells under it); 0.7 m when there is no
        surface, or it is not above the sensors (nothing says how tall the desk is then)."""
        positions = np.array([s.position for s in self.sensors], dtype=float)
        if self.surfaces:
            h = float(self.surfaces[0].origin[2] - positions[:, 2].mean())
            # (a floor of 5 cm here had taken every top close to its cells for none: the
            # balance board's was 0.7 m tall, its default inertia a 0.7 m box)
            if h > 0:
                return h
        return DEFAULT_TOP_HEIGHT_M

    def center_of_mass(self) -> np.ndarray:
        """The desk's centre of mass (3,), desk frame: ``desk.center_of_mass_m`` when the
        profile gives it, else above the sensors' centroid at 85 % of the top's height (a
        heavy top on light legs; the simulator's default too)."""
        if self.center_of_mass_m is not None:
            return np.array(self.center_of_mass_m, dtype=float)
        positions = np.array([s.position for s in self.sensors], dtype=float)
        return np.array(
            [
                *positions[:, :2].mean(axis=0),
                positions[:, 2].mean() + COM_HEIGHT_FRACTION * self.top_height_m(),
            ]
        )

    def __post_init__(self) -> None:
        columns = self.accelerometer_columns()
        if len(set(columns)) != len(columns):  # (the reader numbers them; a hand-made one)
            raise ValueError(
                f"desk {self.name!r}: its accelerometers' columns must differ, found "
                f"{', '.join(columns)}: give each its own prefix (accel_column_prefix)"
            )

    @property
    def accelerometer(self) -> AccelerometerSpec | None:
        """The desk's first accelerometer, or None when it has none."""
        return self.accelerometers[0] if self.accelerometers else None

    def accelerometer_columns(self) -> list[str]:
        """The recording columns of all the desk's accelerometers, in order."""
        return [c for a in self.accelerometers for c in a.column_names()]

    def inertia_about_com(self, mass_kg: float | None = None) -> np.ndarray:
        """The desk's inertia tensor (3, 3) about its centre of mass, desk axes:
        ``desk.inertia_kg_m2`` when the profile gives it, else a solid box of ``mass_kg``
        (default the profile's) as wide and deep as the top board (its first horizontal
        surface's outline, else the legs' span plus 0.1 m) and as tall as the top; the
        simulator's default too."""
        if self.inertia_kg_m2 is not None:
            return np.diag(np.asarray(self.inertia_kg_m2, dtype=float))
        m = float(mass_kg if mass_kg is not None else self.mass_kg or 0.0)
        lx, ly = self.footprint_m()
        h = self.top_height_m()
        return np.diag([m / 12 * (ly**2 + h**2), m / 12 * (lx**2 + h**2), m / 12 * (lx**2 + ly**2)])

    def footprint_m(self) -> tuple[float, float]:
        """Width and depth of the desk: the first horizontal surface's outline, else the legs'
        span plus 0.1 m."""
        for surf in self.surfaces:
            if surf.is_desk_xy:
                span = np.ptp(surf.polygon, axis=0)
                return float(span[0]), float(span[1])
        positions = np.array([s.position for s in self.sensors], dtype=float)
        span = np.ptp(positions[:, :2], axis=0) + 0.1
        return float(span[0]), float(span[1])

    def wrench_map(self) -> np.ndarray:
        """(6, C) matrix A with [F_o; M_o] = A · w for the desk's raw channels w (C of them,
        :meth:`channel_names` order; 6·S for six-axis sensors).

        Paper eqs. (1)–(4): F_o = Σ f_i, M_o = Σ (m_i + p_i × f_i), with each sensor's wrench
        (from its channels, :meth:`SensorSpec.own_wrench_matrix`) rotated into the desk frame
        and its sign made "reaction". A component no sensor measures (a load cell's shear)
        has a row of zeros: the estimator takes it as zero (see :mod:`.sensing`).
        """
        blocks = []
        for s in self.sensors:
            r = s.sign * s.rotation
            px = skew(s.position)
            block = np.zeros((6, 6))
            block[:3, :3] = r
            block[3:, 3:] = r
            block[3:, :3] = px @ r
            blocks.append(block @ s.own_wrench_matrix())
        return np.hstack(blocks)

    @property
    def measures_horizontal_force(self) -> bool:
        """True when a sensor measures a horizontal force (F_x or F_y of the wrench map not
        all zero): six-axis sensors do, upright load cells do not."""
        return bool(np.any(self.wrench_map()[:2] != 0.0))

    def moment_channels(self) -> np.ndarray:
        """(C,) True for a raw channel that measures a moment (N·m: its nominal noise and
        drift are a moment's), False for a force (a calibrated channel counts as a moment
        only when its calibration column has no force in it)."""
        return np.concatenate(
            [np.abs(s.own_wrench_matrix()[:3]).sum(axis=0) == 0 for s in self.sensors]
        )

    def channel_limits(self) -> np.ndarray | None:
        """(C,) each raw channel's saturation limit (inf where unknown), or None when no
        sensor gives one."""
        limits = np.concatenate([s.channel_limits() for s in self.sensors])
        return limits if np.isfinite(limits).any() else None

    def saturation_limits(self) -> np.ndarray | None:
        """(S, 6) rated limits per channel of a desk of six-axis sensors (inf where unknown),
        or None when no sensor has one; :meth:`channel_limits` for a desk of any sensors."""
        if not self.six_axis_only:
            raise ValueError(
                f"desk {self.name!r} has sensors other than six-axis ones: use channel_limits()"
            )
        limits = self.channel_limits()
        return None if limits is None else limits.reshape(len(self.sensors), 6)
