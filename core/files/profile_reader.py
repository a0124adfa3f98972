"""The desk profile's YAML reader: every key checked, every error with its place
(file:line:column) and what was expected. The model it fills is :mod:`.profile`."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from hapticdesk.files.profile import (
    ACCEL_AXES,
    AXES,
    LOWPASS_PER_NATURAL_FREQUENCY,
    METHODS,
    AccelerometerSpec,
    DeskProfile,
    EstimationSettings,
    SensorSpec,
    Surface,
    accel_column_prefix,
    is_body_inertia,
    rotation_matrix,
)
from hapticdesk.files.sensing import surface_locatable
from hapticdesk.files.yamlfile import (
    ConfigError,
    MarkedDict,
    MarkedList,
    as_number,
    check_keys,
    choice,
    flag,
    flag_or_auto,
    number,
    require_mapping,
    vector,
)

#: a desk's sample rate, Hz: fast enough for the paper's 4.77 Hz low-pass (below half of
#: it), and no faster than a force sensor samples (ATI's boards: 7 kHz); the estimator and
#: the simulator size buffers by it
MIN_SAMPLE_RATE_HZ = 10.0
MAX_SAMPLE_RATE_HZ = 100_000.0
#: the lowest low-pass cut-off as a share of the sample rate (0.0048 Hz at 1.2 kHz): the
#: estimator's noise gains sum impulse responses of 8 × rate / cut-off samples (2 million)
MIN_CUTOFF_PER_RATE = 4e-6
#: physical bounds on `estimation` values that are not windows: beyond them a value is a
#: typing mistake, and its square (a covariance) or inverse would overflow downstream
MAX_ESTIMATION = {
    "noise_force_n": 1e3,
    "noise_moment_nm": 1e3,
    "drift_force_n_per_min": 1e3,
    "drift_moment_nm_per_min": 1e3,
}
#: a desk's mass (kg): a heavier one is a typing mistake (the simulator's modes overflow)
MAX_DESK_MASS_KG = 1e4
#: a desk's lowest natural frequency (Hz) at least this (1e-300 divided by zero in the sway
#: model)
MIN_NATURAL_HZ = 0.5
#: a desk's principal moments of inertia (kg·m²): outside, a typing mistake (inverted, they
#: overflow)
MIN_INERTIA, MAX_INERTIA = 1e-6, 1e6
#: the longest estimation windows, seconds (the paper's: 0.166 s, a 1 s tare, 5 s settle)
MAX_WINDOW_S = {
    "diff_window_s": 5.0,
    "tare_s": 60.0,
    "max_gap_s": 60.0,
    "settle_s": 3600.0,
    "object_settle_s": 3600.0,
    "drift_settle_s": 3600.0,
}
#: enough for any surface outline drawn by hand (as a layout's regions)
MAX_SURFACE_POINTS = 500
#: how far from P_o a sensor, an accelerometer, the centre of mass or a surface may lie,
#: metres: a room, not a desk, is 100 m across (a sensor at 1e300 m made the wrench map's
#: moments infinite, and the estimator crashed on its covariances)
MAX_REACH_M = 100.0
#: a sensor's rating (`range`), N or N·m: a smaller one is a typing mistake, and its
#: inverse square (the estimator's weights) would overflow
MIN_RATING = 1e-3
MAX_RATING = 1e7

_TOP_KEYS = {
    "name",
    "sample_rate_hz",
    "sensors",
    "surfaces",
    "estimation",
    "can",
    "serial",
    "desk",
    "accelerometer",
    "accelerometers",
}
_SENSOR_KEYS = {
    "name",
    "position",
    "rotation_rpy_deg",
    "reports",
    "range",
    "kind",
    "axes",
    "channels",
    "calibration",
}
#: a sensor's `kind`: the channels it delivers (`axes` lists them for any other subset)
SENSOR_KINDS = {
    "six_axis": AXES,
    "load_cell": ("fz",),
    "three_axis": ("fx", "fy", "fz"),
}
#: the most raw channels one sensor may deliver (a force plate's amplifier: 8 to 12)
MAX_SENSOR_CHANNELS = 64
_SURFACE_KEYS = {"name", "origin", "normal", "polygon", "u_axis"}
_DESK_KEYS = {"mass_kg", "natural_frequency_hz", "center_of_mass_m", "inertia_kg_m2", "note"}
_ACCEL_KEYS = {"position", "rotation_rpy_deg", "axes", "noise_m_s2", "range_m_s2"}


def read_profile(doc: MarkedDict, path: Path) -> DeskProfile:
    """Validate an already loaded profile mapping."""
    check_keys(doc, _TOP_KEYS, "the desk profile", required={"name", "sample_rate_hz", "sensors"})
    name = doc["name"]
    if not isinstance(name, str) or not name:
        raise ConfigError(doc.where("name"), "`name` must be a non-empty text")
    rate = number(
        doc,
        "sample_rate_hz",
        "the desk profile",
        minimum=MIN_SAMPLE_RATE_HZ,
        maximum=MAX_SAMPLE_RATE_HZ,
    )

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
    _check_locatable(sensors, surfaces, doc, surfaces_raw)

    estimation = (
        _estimation(doc["estimation"], doc.where("estimation"))
        if "estimation" in doc
        else EstimationSettings()
    )
    can = doc.get("can")
    if can is not None:
        can = require_mapping(can, doc.where("can"), "`can`")
    serial = doc.get("serial")  # read by hapticdesk.boards.settings, when a run uses it
    if serial is not None:
        serial = require_mapping(serial, doc.where("serial"), "`serial`")
    mass = natural = com = inertia = None
    if "desk" in doc:
        desk = require_mapping(doc["desk"], doc.where("desk"), "`desk`")
        check_keys(desk, _DESK_KEYS, "`desk`")
        mass = (
            number(desk, "mass_kg", "`desk`", default=0.0, minimum=0.0, maximum=MAX_DESK_MASS_KG)
            or None
        )
        natural = number(desk, "natural_frequency_hz", "`desk`", default=0.0, minimum=0.0) or None
        # (too high for the rate: the low-passes it sets are refused by _check_against_rate)
        if natural is not None and natural < MIN_NATURAL_HZ:
            raise ConfigError(
                desk.where("natural_frequency_hz"),
                f"`natural_frequency_hz` of `desk` must be at least {MIN_NATURAL_HZ:g} Hz (no "
                f"desk sways slower), or 0 (not known), found {natural:g}",
            )
        if natural is not None and natural >= rate / 2:  # (1e300 overflowed the sway model)
            raise ConfigError(
                desk.where("natural_frequency_hz"),
                f"`natural_frequency_hz` of `desk` is {natural:g} Hz; a sway the sensors can "
                f"see must be below half the sample rate ({rate / 2:g} Hz at `sample_rate_hz` "
                f"{rate:g}); with sensors this slow give 0 (not known)",
            )
        if "center_of_mass_m" in desk:
            com = np.array(
                place(
                    desk["center_of_mass_m"],
                    desk.where("center_of_mass_m"),
                    "`center_of_mass_m` of `desk`",
                    3,
                )
            )
        if "inertia_kg_m2" in desk:
            moments = vector(
                desk["inertia_kg_m2"], desk.where("inertia_kg_m2"), "`inertia_kg_m2` of `desk`", 3
            )
            if not is_body_inertia(moments) or not all(
                MIN_INERTIA <= v <= MAX_INERTIA for v in moments
            ):
                raise ConfigError(
                    desk.where("inertia_kg_m2"),
                    "`inertia_kg_m2` of `desk` must be three positive principal moments of "
                    "inertia (kg·m², about the centre of mass along the desk's x, y, z), each "
                    f"at most the sum of the other two (a body's are) and {MIN_INERTIA:g} to "
                    f"{MAX_INERTIA:g}, found {moments}",
                )
            inertia = (moments[0], moments[1], moments[2])
    accelerometers = _accelerometers(doc)
    if accelerometers and mass is None:
        key = "accelerometer" if "accelerometer" in doc else "accelerometers"
        raise ConfigError(
            doc.where(key, of_key=True),
            f"`{key}` needs the desk's mass: give `desk: {{mass_kg: ...}}` "
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
    _check_against_rate(estimation, rate, doc, given)
    return DeskProfile(
        name=name,
        sample_rate_hz=rate,
        sensors=sensors,
        surfaces=surfaces,
        estimation=estimation,
        can=can,
        serial=serial,
        path=path,
        mass_kg=mass,
        natural_frequency_hz=natural,
        center_of_mass_m=com,
        inertia_kg_m2=inertia,
        accelerometers=accelerometers,
    )


def _check_locatable(
    sensors: tuple[SensorSpec, ...],
    surfaces: tuple[Surface, ...],
    doc: MarkedDict,
    surfaces_raw: Any,
) -> None:
    """Every surface must be one a touch on can be located on: the sensors see the force
    into it and the moments about its axes (3 upright load cells not on one line, or one
    six-axis sensor, for a horizontal board; :mod:`hapticdesk.files.sensing`)."""
    if not surfaces:
        return
    probe = DeskProfile(name="", sample_rate_hz=1.0, sensors=sensors, surfaces=surfaces)
    wrench_map = probe.wrench_map()
    for i, surface in enumerate(surfaces):
        if surface_locatable(wrench_map, surface):
            continue
        kinds = sorted({" ".join(s.channels) for s in sensors})
        raise ConfigError(
            surfaces_raw.where(i) if isinstance(surfaces_raw, MarkedList) else doc.where(),
            f"a touch on surface `{surface.name}` cannot be located with these sensors "
            f"({len(sensors)}, delivering {'; '.join(kinds)}): they must see the force into "
            "it and the moments about its two axes (a horizontal board needs 3 or more "
            "sensors not on one line, or one six-axis sensor)",
        )


def _check_against_rate(
    settings: EstimationSettings, rate: float, doc: MarkedDict, given: Any
) -> None:
    """The filters' cut-offs against the sample rate, each at the place that set it: the
    key in `estimation`, else `desk: natural_frequency_hz` (which sets the low-passes), else
    `sample_rate_hz` (a default cut-off)."""
    estimation = given if isinstance(given, MarkedDict) else None
    lowest = MIN_CUTOFF_PER_RATE * rate
    for key in ("force_lowpass_hz", "diff_lowpass_hz", "detect_lowpass_hz"):
        value = getattr(settings, key)
        if estimation is not None and key in estimation:
            where, source = estimation.where(key), f"`{key}` in `estimation`"
        elif (
            key != "detect_lowpass_hz"
            and isinstance(doc.get("desk"), MarkedDict)
            and ("natural_frequency_hz" in doc["desk"])
        ):
            where = doc["desk"].where("natural_frequency_hz")
            source = f"`{key}` (from `desk: natural_frequency_hz`)"
        else:
            where, source = doc.where("sample_rate_hz"), f"the default `{key}`"
        # the fast detection low-pass is held below 0.45 × the rate by the estimator itself
        if key != "detect_lowpass_hz" and value >= rate / 2:
            raise ConfigError(
                where,
                f"{source} is {value:g} Hz; a low-pass cut-off must be below half the sample "
                f"rate (the Nyquist frequency, {rate / 2:g} Hz at `sample_rate_hz` {rate:g})",
            )
        if value < lowest:
            raise ConfigError(
                where,
                f"{source} is {value:g} Hz; a cut-off must be at least {lowest:g} Hz "
                f"({MIN_CUTOFF_PER_RATE:g} × `sample_rate_hz` {rate:g}): lower, the filter "
                "would take longer to settle than any touch lasts",
            )


def place(value: Any, where: Any, what: str, length: int, origin: str = "P_o") -> list[float]:
    """A point of ``length`` coordinates (metres), none farther than :data:`MAX_REACH_M`
    from ``origin``."""
    out = vector(value, where, what, length)
    far = max(abs(v) for v in out)
    if far > MAX_REACH_M:
        raise ConfigError(
            where,
            f"{what} has a coordinate of {far:g} m from {origin}; a desk's parts lie within "
            f"{MAX_REACH_M:g} m of it",
        )
    return out


def _accelerometers(doc: MarkedDict) -> tuple[AccelerometerSpec, ...]:
    """``accelerometer:`` (one) or ``accelerometers:`` (a list: three or more, not on one
    line, measure the desk's rotation too; hapticdesk.estimator.inertia)."""
    if "accelerometer" in doc and "accelerometers" in doc:
        raise ConfigError(
            doc.where("accelerometers", of_key=True),
            "give either `accelerometer` (one) or `accelerometers` (a list), not both",
        )
    if "accelerometer" in doc:
        return (_accelerometer(doc["accelerometer"], doc.where("accelerometer"), 0),)
    if "accelerometers" not in doc:
        return ()
    items = doc["accelerometers"]
    if not isinstance(items, list) or not items:
        raise ConfigError(
            doc.where("accelerometers"),
            "`accelerometers` must be a list of accelerometers "
            f"({{position: [x, y, z], ...}} each), found {items!r}",
        )
    places = items if isinstance(items, MarkedList) else None
    return tuple(
        _accelerometer(
            item,
            places.where(i) if places is not None else doc.where("accelerometers"),
            i,
            f"accelerometer {i + 1} of `accelerometers`",
        )
        for i, item in enumerate(items)
    )


def _accelerometer(
    item: Any, where: Any, index: int, what: str = "`accelerometer`"
) -> AccelerometerSpec:
    m = require_mapping(item, where, what)
    check_keys(m, _ACCEL_KEYS, what, required={"position"})
    position = np.array(place(m["position"], m.where("position"), f"`position` of {what}", 3))
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
    return AccelerometerSpec(
        position, rotation_matrix(*rpy), axes, noise, limit, accel_column_prefix(index)
    )


def _sensor(item: Any, where: Any, index: int) -> SensorSpec:
    m = require_mapping(item, where, f"sensor {index + 1}")
    check_keys(m, _SENSOR_KEYS, f"sensor {index + 1}", required={"name", "position"})
    name = m["name"]
    if not isinstance(name, str) or not name.replace("_", "").isalnum():
        raise ConfigError(
            m.where("name"), f"sensor `name` must be letters, digits and _, found {name!r}"
        )
    what = f"sensor `{name}`"
    position = np.array(place(m["position"], m.where("position"), f"`position` of {what}", 3))
    rpy = vector(
        m.get("rotation_rpy_deg", [0, 0, 0]),
        m.where("rotation_rpy_deg"),
        f"`rotation_rpy_deg` of {what}",
        3,
    )
    reports = choice(m, "reports", ("reaction", "load"), what, default="reaction")
    channels, calibration = _sensor_channels(m, what)
    force_range = moment_range = channel_range = None
    if "range" in m:
        rng = require_mapping(m["range"], m.where("range"), f"`range` of {what}")
        if calibration is not None:
            check_keys(rng, {"channels"}, f"`range` of {what} (a calibrated sensor)")
            if "channels" in rng:
                channel_range = _ratings(rng, "channels", what, len(channels))
        else:
            check_keys(rng, {"force_n", "moment_nm"}, f"`range` of {what}")
            if "force_n" in rng:
                force_range = _ratings(rng, "force_n", what, 3)
            if "moment_nm" in rng:
                moment_range = _ratings(rng, "moment_nm", what, 3)
    return SensorSpec(
        name,
        position,
        rotation_matrix(*rpy),
        reports,
        force_range,
        moment_range,
        channels,
        calibration,
        channel_range,
    )


def _sensor_channels(m: MarkedDict, what: str) -> tuple[tuple[str, ...], np.ndarray | None]:
    """The raw channels a sensor delivers and, for a calibrated one, the (6, n) matrix from
    them to its wrench: ``kind`` (six_axis, the default; load_cell: fz; three_axis: fx, fy,
    fz), or ``axes`` (any subset of fx … mz), or ``channels`` with ``calibration``."""
    given = [key for key in ("kind", "axes", "channels") if key in m]
    if len(given) > 1:
        raise ConfigError(
            m.where(given[1], of_key=True),
            f"give one of `kind`, `axes` or `channels` for {what}, found "
            + " and ".join(f"`{key}`" for key in given),
        )
    if "calibration" in m and "channels" not in m:
        raise ConfigError(
            m.where("calibration", of_key=True),
            f"`calibration` of {what} maps its raw `channels` to its wrench: list the "
            "`channels` too",
        )
    if "kind" in m:
        kind = choice(m, "kind", tuple(SENSOR_KINDS), what)
        return SENSOR_KINDS[kind], None
    if "axes" in m:
        raw = m["axes"]
        if (
            not isinstance(raw, list)
            or not raw
            or any(a not in AXES for a in raw)
            or len(set(raw)) != len(raw)
        ):
            raise ConfigError(
                m.where("axes"),
                f"`axes` of {what} must list some of {', '.join(AXES)} once each, found {raw!r}",
            )
        return tuple(a for a in AXES if a in raw), None  # columns in fx … mz order
    if "channels" not in m:
        return AXES, None
    raw = m["channels"]
    if (
        not isinstance(raw, list)
        or not 1 <= len(raw) <= MAX_SENSOR_CHANNELS
        or not all(isinstance(c, str) and c.replace("_", "").isalnum() for c in raw)
        or len(set(raw)) != len(raw)
    ):
        raise ConfigError(
            m.where("channels"),
            f"`channels` of {what} must list 1 to {MAX_SENSOR_CHANNELS} different names of "
            f"letters, digits and _ (its raw channels: recording columns `<sensor>_<channel>`), "
            f"found {raw!r}",
        )
    channels = tuple(str(c) for c in raw)
    if "calibration" not in m:
        if all(c in AXES for c in channels):
            return tuple(a for a in AXES if a in channels), None
        raise ConfigError(
            m.where("channels"),
            f"{what} lists raw `channels` that are not axes ({', '.join(AXES)}): give its "
            f"`calibration`, 6 rows (fx, fy, fz, mx, my, mz) of {len(channels)} numbers, the "
            "sensor's wrench per unit of each channel",
        )
    rows = m["calibration"]
    if not isinstance(rows, list) or len(rows) != 6:
        raise ConfigError(
            m.where("calibration"),
            f"`calibration` of {what} must be 6 rows (fx, fy, fz, mx, my, mz) of "
            f"{len(channels)} numbers each, one per channel",
        )
    places = rows if isinstance(rows, MarkedList) else None
    matrix = np.array(
        [
            vector(
                row,
                places.where(i) if places is not None else m.where("calibration"),
                f"row {AXES[i]} of `calibration` of {what}",
                len(channels),
            )
            for i, row in enumerate(rows)
        ]
    )
    if not (np.abs(matrix) <= MAX_RATING).all() or not matrix.any():
        raise ConfigError(
            m.where("calibration"),
            f"`calibration` of {what} must have numbers within ±{MAX_RATING:g}, not all zero",
        )
    return channels, matrix


def _ratings(rng: MarkedDict, key: str, what: str, length: int) -> np.ndarray:
    """Ratings at ``key``: ``length`` numbers, or one number for all of them."""
    value = as_number(rng[key])
    if isinstance(value, int | float) and not isinstance(value, bool):
        value = [value] * length
    arr = np.array(vector(value, rng.where(key), f"`{key}`", length))
    if np.any(arr <= 0):
        raise ConfigError(rng.where(key), f"`{key}` of {what} must be positive ratings")
    if not np.all((arr >= MIN_RATING) & (arr <= MAX_RATING)):
        raise ConfigError(
            rng.where(key),
            f"`{key}` of {what} must be ratings from {MIN_RATING:g} to {MAX_RATING:g}, "
            f"found {arr.tolist()}",
        )
    return arr


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
    origin = np.array(place(m["origin"], m.where("origin"), f"`origin` of {what}", 3))
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
    if not isinstance(poly_raw, list) or not 3 <= len(poly_raw) <= MAX_SURFACE_POINTS:
        found = f", found {len(poly_raw)}" if isinstance(poly_raw, list) else ""
        raise ConfigError(
            m.where("polygon"),
            f"`polygon` of {what} must list 3 to {MAX_SURFACE_POINTS} [u, v] points{found}",
        )
    pts = np.array(
        [
            place(p, poly_raw.where(i), f"polygon point {i + 1} of {what}", 2, "its origin")  # type: ignore[attr-defined]
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
        elif key == "sway_compensation":
            values[key] = flag_or_auto(m, key, "`estimation`")
        elif key == "second_finger":
            values[key] = flag(m, key, "`estimation`", default=defaults.second_finger)
        elif key == "zeroed":
            values[key] = flag(m, key, "`estimation`", default=defaults.zeroed)
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
            values[key] = number(
                m,
                key,
                "`estimation`",
                minimum=0.0,
                exclusive_minimum=strict,
                maximum=MAX_WINDOW_S.get(key, MAX_ESTIMATION.get(key)),
            )
    settings = EstimationSettings(**values)
    if settings.min_normal_cos >= 1.0:
        raise ConfigError(m.where("min_normal_cos"), "`min_normal_cos` must be below 1")
    if settings.zeroed and not (settings.noise_force_n > 0 or settings.noise_moment_nm > 0):
        raise ConfigError(
            m.where("zeroed"),
            "`zeroed: true` (the readings come zeroed: no tare) needs the channels' noise, "
            "which a tare would have measured: give `noise_force_n` and `noise_moment_nm`",
        )
    if settings.release_hysteresis_n >= settings.contact_force_n:
        raise ConfigError(
            m.where("release_hysteresis_n"),
            "`release_hysteresis_n` must be smaller than `contact_force_n`",
        )
    return settings
