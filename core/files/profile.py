"""Desk profiles: where the sensors stand, which surfaces can be touched, and how to estimate.

The YAML format is a contract (../shared/DESIGN.md, "Desk profile"). Loading validates every
field and reports ``file:line:column: what was expected``. The profile also owns the one
linear map from the stacked sensor channels to the resultant wrench about P_o (paper eqs. 1–4),
which every consumer of sensor data uses.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from hapticdesk.files.yamlfile import (
    ConfigError,
    MarkedDict,
    MarkedList,
    check_keys,
    choice,
    load_marked_yaml,
    number,
    require_mapping,
    vector,
)

METHODS = ("force", "diff", "switched", "fused")
LOWPASS_PER_NATURAL_FREQUENCY = 4.77 / 5.9  # the paper's cut-off for its desk's lowest mode
AXES = ("fx", "fy", "fz", "mx", "my", "mz")
ACCEL_AXES = ("x", "y", "z")
STANDARD_GRAVITY = 9.80665  # m/s²: the desk's weight (simulator), an accelerometer's rest reading
DEFAULT_TOP_HEIGHT_M = 0.7  # a desk's top above its sensors when the profile has no surface
COM_HEIGHT_FRACTION = 0.85  # the default centre of mass: a heavy top on light legs


def rotation_matrix(roll_deg: float, pitch_deg: float, yaw_deg: float) -> np.ndarray:
    """R = Rz(yaw) · Ry(pitch) · Rx(roll): the sensor frame expressed in the desk frame."""
    r, p, y = (math.radians(v) for v in (roll_deg, pitch_deg, yaw_deg))
    cr, sr, cp, sp, cy, sy = (
        math.cos(r),
        math.sin(r),
        math.cos(p),
        math.sin(p),
        math.cos(y),
        math.sin(y),
    )
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


@dataclass(frozen=True)
class SensorSpec:
    """One six-axis sensor: its place, orientation, sign convention and rated range."""

    name: str
    position: np.ndarray  # (3,) desk frame, metres
    rotation: np.ndarray  # (3, 3) sensor frame -> desk frame
    reports: str = "reaction"  # "reaction" (the paper's) or "load" (opposite sign)
    force_range: np.ndarray | None = None  # (3,) N, |reading| >= range is saturated
    moment_range: np.ndarray | None = None  # (3,) N·m

    @property
    def sign(self) -> float:
        """+1 when the sensor reports the wrench it exerts on the desk, -1 for the load."""
        return 1.0 if self.reports == "reaction" else -1.0

    def channel_names(self) -> list[str]:
        """Recording column names of this sensor's six channels."""
        return [f"{self.name}_{axis}" for axis in AXES]


@dataclass(frozen=True)
class AccelerometerSpec:
    """An accelerometer fixed to the desk top (optional; issue 15 item 6).

    It is sampled with the sensors (one reading per sample, the same clock and rate) and
    reports the specific force (acceleration minus gravity, so +g upwards at rest) along
    ``axes`` of its own frame, in m/s²; recordings carry it as the columns
    :meth:`column_names` (``acc_x, acc_y, acc_z``).
    """

    position: np.ndarray  # (3,) desk frame, metres
    rotation: np.ndarray  # (3, 3) accelerometer frame -> desk frame
    axes: tuple[str, ...] = ACCEL_AXES  # which of its axes it measures, in column order
    noise_m_s2: float = 0.0  # σ of each axis's white noise (used by the simulator)
    range_m_s2: float = math.inf  # |reading| >= this is saturated

    def column_names(self) -> list[str]:
        """Recording columns of the accelerometer, in order."""
        return [f"acc_{axis}" for axis in self.axes]

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
    max_gap_s: float = 0.05  # a gap in sample times longer than this restarts the filters
    noise_force_n: float = 0.0  # per-channel noise σ if known; 0 = measure during the tare
    noise_moment_nm: float = 0.0


@dataclass(frozen=True)
class DeskProfile:
    """A desk: sensors, surfaces, estimation settings, and the optional CAN section."""

    name: str
    sample_rate_hz: float
    sensors: tuple[SensorSpec, ...]
    surfaces: tuple[Surface, ...]
    estimation: EstimationSettings = field(default_factory=EstimationSettings)
    can: dict[str, Any] | None = None
    path: Path | None = None
    mass_kg: float | None = None  # optional, used by the simulator
    natural_frequency_hz: float | None = None  # optional, used by the simulator
    # optional: the desk's centre of mass (desk frame, m); see :meth:`center_of_mass`
    center_of_mass_m: np.ndarray | None = None
    accelerometer: AccelerometerSpec | None = None  # optional, see AccelerometerSpec

    @property
    def sensor_names(self) -> list[str]:
        return [s.name for s in self.sensors]

    def channel_names(self) -> list[str]:
        """All recording columns after ``t``, in order."""
        return [c for s in self.sensors for c in s.channel_names()]

    def surface(self, name: str) -> Surface:
        for s in self.surfaces:
            if s.name == name:
                return s
        raise KeyError(
            f"desk {self.name!r} has no surface {name!r}; it has "
            f"{', '.join(s.name for s in self.surfaces) or 'none'}"
        )

    def top_height_m(self) -> float:
        """Height of the first surface above the sensors (0.7 m when there is none)."""
        positions = np.array([s.position for s in self.sensors], dtype=float)
        if self.surfaces:
            h = float(self.surfaces[0].origin[2] - positions[:, 2].mean())
            if h > 0.05:
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

    def wrench_map(self) -> np.ndarray:
        """(6, 6·S) matrix A with [F_o; M_o] = A · w for the stacked channels w.

        Paper eqs. (1)–(4): F_o = Σ f_i, M_o = Σ (m_i + p_i × f_i), with each reading rotated
        into the desk frame and its sign made "reaction".
        """
        blocks = []
        for s in self.sensors:
            r = s.sign * s.rotation
            p = s.position
            px = np.array([[0, -p[2], p[1]], [p[2], 0, -p[0]], [-p[1], p[0], 0]])
            block = np.zeros((6, 6))
            block[:3, :3] = r
            block[3:, 3:] = r
            block[3:, :3] = px @ r
            blocks.append(block)
        return np.hstack(blocks)

    def saturation_limits(self) -> np.ndarray | None:
        """(S, 6) rated limits per channel (inf where unknown), or None when no sensor has one."""
        if all(s.force_range is None and s.moment_range is None for s in self.sensors):
            return None
        lim = np.full((len(self.sensors), 6), np.inf)
        for i, s in enumerate(self.sensors):
            if s.force_range is not None:
                lim[i, :3] = s.force_range
            if s.moment_range is not None:
                lim[i, 3:] = s.moment_range
        return lim


# --- loading ---------------------------------------------------------------------------------

_TOP_KEYS = {
    "name",
    "sample_rate_hz",
    "sensors",
    "surfaces",
    "estimation",
    "can",
    "desk",
    "accelerometer",
}
_SENSOR_KEYS = {"name", "position", "rotation_rpy_deg", "reports", "range"}
_SURFACE_KEYS = {"name", "origin", "normal", "polygon", "u_axis"}
_DESK_KEYS = {"mass_kg", "natural_frequency_hz", "center_of_mass_m", "note"}
_ACCEL_KEYS = {"position", "rotation_rpy_deg", "axes", "noise_m_s2", "range_m_s2"}


def builtin_profile_path(name: str) -> Path | None:
    """The shipped profile called ``name``, if there is one."""
    candidate = resources.files("hapticdesk.profiles").joinpath(f"{name}.yaml")
    return Path(str(candidate)) if candidate.is_file() else None


def resolve_profile_path(name_or_path: str | Path, relative_to: Path | None = None) -> Path:
    """A profile name from profiles/ or a path (relative to ``relative_to`` when given)."""
    text = str(name_or_path)
    if not text.endswith((".yaml", ".yml")) and "/" not in text:
        builtin = builtin_profile_path(text)
        if builtin is not None:
            return builtin
    path = Path(text)
    if not path.is_absolute() and relative_to is not None:
        path = relative_to / path
    if not path.is_file():
        shipped = ", ".join(sorted(p.stem for p in _shipped_profiles()))
        raise ConfigError(str(name_or_path), f"no such desk profile; shipped profiles: {shipped}")
    return path


def _shipped_profiles() -> list[Path]:
    root = resources.files("hapticdesk.profiles")
    return [Path(str(p)) for p in root.iterdir() if str(p).endswith(".yaml")]


def load_profile(name_or_path: str | Path, relative_to: Path | None = None) -> DeskProfile:
    """Load and validate a desk profile; raises :class:`ConfigError` on any problem."""
    path = resolve_profile_path(name_or_path, relative_to)
    doc = require_mapping(load_marked_yaml(path), str(path), "a desk profile")
    return profile_from_mapping(doc, path)


def profile_from_mapping(doc: MarkedDict, path: Path) -> DeskProfile:
    """Validate an already loaded profile mapping."""
    check_keys(doc, _TOP_KEYS, "the desk profile", required={"name", "sample_rate_hz", "sensors"})
    name = doc["name"]
    if not isinstance(name, str) or not name:
        raise ConfigError(doc.where("name"), "`name` must be a non-empty text")
    rate = number(doc, "sample_rate_hz", "the desk profile", minimum=0.0, exclusive_minimum=True)

    sensors_raw = doc["sensors"]
    if not isinstance(sensors_raw, MarkedList) or not sensors_raw:
        raise ConfigError(doc.where("sensors"), "`sensors` must be a list of at least one sensor")
    sensors = tuple(_sensor(item, sensors_raw.where(i), i) for i, item in enumerate(sensors_raw))
    names = [s.name for s in sensors]
    for i, n in enumerate(names):
        if names.index(n) != i:
            raise ConfigError(sensors_raw.where(i), f"sensor name `{n}` is used twice")

    surfaces_raw = doc.get("surfaces", MarkedList())
    if not isinstance(surfaces_raw, list):
        raise ConfigError(doc.where("surfaces"), "`surfaces` must be a list")
    surfaces = tuple(_surface(item, surfaces_raw.where(i)) for i, item in enumerate(surfaces_raw))  # type: ignore[attr-defined]
    snames = [s.name for s in surfaces]
    for i, n in enumerate(snames):
        if snames.index(n) != i:
            raise ConfigError(surfaces_raw.where(i), f"surface name `{n}` is used twice")  # type: ignore[attr-defined]
    if surfaces and len(sensors) < 3:
        raise ConfigError(
            doc.where("sensors"),
            f"a desk with surfaces needs 3 or more sensors to locate a touch, found {len(sensors)}",
        )

    estimation = (
        _estimation(doc["estimation"], doc.where("estimation"))
        if "estimation" in doc
        else EstimationSettings()
    )
    can = doc.get("can")
    if can is not None:
        can = require_mapping(can, doc.where("can"), "`can`")
    mass = natural = com = None
    if "desk" in doc:
        desk = require_mapping(doc["desk"], doc.where("desk"), "`desk`")
        check_keys(desk, _DESK_KEYS, "`desk`")
        mass = number(desk, "mass_kg", "`desk`", default=0.0, minimum=0.0) or None
        natural = number(desk, "natural_frequency_hz", "`desk`", default=0.0, minimum=0.0) or None
        if "center_of_mass_m" in desk:
            com = np.array(
                vector(
                    desk["center_of_mass_m"],
                    desk.where("center_of_mass_m"),
                    "`center_of_mass_m` of `desk`",
                    3,
                )
            )
    accelerometer = None
    if "accelerometer" in doc:
        accelerometer = _accelerometer(doc["accelerometer"], doc.where("accelerometer"))
        if mass is None:
            raise ConfigError(
                doc.where("accelerometer", of_key=True),
                "an `accelerometer` needs the desk's mass: give `desk: {mass_kg: ...}` "
                "(the inertial force it removes is mass × acceleration)",
            )
    given = doc["estimation"] if isinstance(doc.get("estimation"), MarkedDict) else {}
    if natural is not None:
        # the filters must stay below the desk's lowest mode, as the paper's 4.77 Hz stays
        # below its 5.9 Hz (ratio 0.81); a value given in `estimation` wins
        cutoff = round(LOWPASS_PER_NATURAL_FREQUENCY * natural, 2)
        for key in ("force_lowpass_hz", "diff_lowpass_hz"):
            if key not in given:
                estimation = replace(estimation, **{key: cutoff})
    return DeskProfile(
        name=name,
        sample_rate_hz=rate,
        sensors=sensors,
        surfaces=surfaces,
        estimation=estimation,
        can=can,
        path=path,
        mass_kg=mass,
        natural_frequency_hz=natural,
        center_of_mass_m=com,
        accelerometer=accelerometer,
    )


def _accelerometer(item: Any, where: Any) -> AccelerometerSpec:
    what = "`accelerometer`"
    m = require_mapping(item, where, what)
    check_keys(m, _ACCEL_KEYS, what, required={"position"})
    position = np.array(vector(m["position"], m.where("position"), f"`position` of {what}", 3))
    rpy = vector(
        m.get("rotation_rpy_deg", [0, 0, 0]),
        m.where("rotation_rpy_deg"),
        f"`rotation_rpy_deg` of {what}",
        3,
    )
    axes: tuple[str, ...] = ACCEL_AXES
    if "axes" in m:
        raw = m["axes"]
        if (
            not isinstance(raw, list)
            or not raw
            or any(a not in ACCEL_AXES for a in raw)
            or len(set(raw)) != len(raw)
        ):
            raise ConfigError(
                m.where("axes"),
                f"`axes` of {what} must list some of x, y, z once each, found {raw!r}",
            )
        axes = tuple(a for a in ACCEL_AXES if a in raw)  # columns in x, y, z order
    noise = number(m, "noise_m_s2", what, default=0.0, minimum=0.0)
    limit = number(m, "range_m_s2", what, default=math.inf, minimum=0.0, exclusive_minimum=True)
    return AccelerometerSpec(position, rotation_matrix(*rpy), axes, noise, limit)


def _sensor(item: Any, where: Any, index: int) -> SensorSpec:
    m = require_mapping(item, where, f"sensor {index + 1}")
    check_keys(m, _SENSOR_KEYS, f"sensor {index + 1}", required={"name", "position"})
    name = m["name"]
    if not isinstance(name, str) or not name.replace("_", "").isalnum():
        raise ConfigError(
            m.where("name"), f"sensor `name` must be letters, digits and _, found {name!r}"
        )
    what = f"sensor `{name}`"
    position = np.array(vector(m["position"], m.where("position"), f"`position` of {what}", 3))
    rpy = vector(
        m.get("rotation_rpy_deg", [0, 0, 0]),
        m.where("rotation_rpy_deg"),
        f"`rotation_rpy_deg` of {what}",
        3,
    )
    reports = choice(m, "reports", ("reaction", "load"), what, default="reaction")
    force_range = moment_range = None
    if "range" in m:
        rng = require_mapping(m["range"], m.where("range"), f"`range` of {what}")
        check_keys(rng, {"force_n", "moment_nm"}, f"`range` of {what}")
        if "force_n" in rng:
            force_range = np.array(vector(rng["force_n"], rng.where("force_n"), "`force_n`", 3))
        if "moment_nm" in rng:
            moment_range = np.array(
                vector(rng["moment_nm"], rng.where("moment_nm"), "`moment_nm`", 3)
            )
        for arr, key in ((force_range, "force_n"), (moment_range, "moment_nm")):
            if arr is not None and np.any(arr <= 0):
                raise ConfigError(rng.where(key), f"`{key}` of {what} must be positive ratings")
    return SensorSpec(name, position, rotation_matrix(*rpy), reports, force_range, moment_range)


def _unit(v: list[float], where: Any, what: str) -> np.ndarray:
    arr = np.array(v)
    norm = float(np.linalg.norm(arr))
    if norm < 1e-12:
        raise ConfigError(where, f"{what} must not be the zero vector")
    return arr / norm


def _surface(item: Any, where: Any) -> Surface:
    m = require_mapping(item, where, "a surface")
    check_keys(m, _SURFACE_KEYS, "a surface", required={"name", "origin", "normal", "polygon"})
    name = m["name"]
    if not isinstance(name, str) or not name:
        raise ConfigError(m.where("name"), "surface `name` must be a non-empty text")
    what = f"surface `{name}`"
    origin = np.array(vector(m["origin"], m.where("origin"), f"`origin` of {what}", 3))
    normal = _unit(
        vector(m["normal"], m.where("normal"), f"`normal` of {what}", 3),
        m.where("normal"),
        f"`normal` of {what}",
    )
    offset = np.zeros(2)
    if "u_axis" in m:
        u_raw = _unit(
            vector(m["u_axis"], m.where("u_axis"), f"`u_axis` of {what}", 3),
            m.where("u_axis"),
            f"`u_axis` of {what}",
        )
        u = u_raw - (u_raw @ normal) * normal  # keep it in the plane
        if np.linalg.norm(u) < 1e-6:
            raise ConfigError(
                m.where("u_axis"), f"`u_axis` of {what} must not be parallel to its normal"
            )
        u = u / np.linalg.norm(u)
        v = np.cross(normal, u)
    else:
        if abs(abs(normal[2]) - 1.0) > 1e-9:
            raise ConfigError(
                m.where("normal"),
                f"{what} is not horizontal: give `u_axis` so its polygon has axes",
            )
        u, v = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
        offset = origin[:2].copy()  # the polygon is in desk (x, y)
    poly_raw = m["polygon"]
    if not isinstance(poly_raw, list) or len(poly_raw) < 3:
        raise ConfigError(
            m.where("polygon"), f"`polygon` of {what} must list 3 or more [u, v] points"
        )
    pts = np.array(
        [
            vector(p, poly_raw.where(i), f"polygon point {i + 1} of {what}", 2)  # type: ignore[attr-defined]
            for i, p in enumerate(poly_raw)
        ]
    )
    area = 0.5 * float(
        np.sum(pts[:, 0] * np.roll(pts[:, 1], -1) - np.roll(pts[:, 0], -1) * pts[:, 1])
    )
    if abs(area) < 1e-12:
        raise ConfigError(m.where("polygon"), f"`polygon` of {what} has no area")
    return Surface(name, origin, normal, u, v, pts, offset)


def _estimation(item: Any, where: Any) -> EstimationSettings:
    m = require_mapping(item, where, "`estimation`")
    defaults = EstimationSettings()
    allowed = set(EstimationSettings.__dataclass_fields__)
    check_keys(m, allowed, "`estimation`")
    values: dict[str, Any] = {}
    for key in allowed:
        if key == "method":
            values[key] = choice(m, "method", METHODS, "`estimation`", default=defaults.method)
        elif key in m:
            strict = key not in (
                "noise_force_n",
                "noise_moment_nm",
                "min_normal_cos",
                "contact_speed_m_s",
                "release_hysteresis_n",
                "release_slope_n_s",
                "drift_settle_s",
                "object_settle_s",
                "drift_force_n_per_min",
                "drift_moment_nm_per_min",
            )
            values[key] = number(m, key, "`estimation`", minimum=0.0, exclusive_minimum=strict)
    settings = EstimationSettings(**values)
    if settings.min_normal_cos >= 1.0:
        raise ConfigError(m.where("min_normal_cos"), "`min_normal_cos` must be below 1")
    if settings.release_hysteresis_n >= settings.contact_force_n:
        raise ConfigError(
            m.where("release_hysteresis_n"),
            "`release_hysteresis_n` must be smaller than `contact_force_n`",
        )
    return settings
