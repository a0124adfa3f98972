"""The desk profile's ``sensors:`` and ``accelerometer(s):`` read and checked: each sensor's
place, orientation, the raw channels it delivers (a ``kind``, its ``axes``, or ``channels``
with a ``calibration``) and its ratings; each accelerometer's place and axes. Every error at
``file:line:column``. Part of :mod:`.profile_reader`."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from hapticdesk.errors import ConfigError
from hapticdesk.files.marked_values import MarkedDict, MarkedList, as_number
from hapticdesk.files.profile import (
    ACCEL_AXES,
    AXES,
    AccelerometerSpec,
    SensorSpec,
    accel_column_prefix,
)
from hapticdesk.files.rigid_body import rotation_matrix
from hapticdesk.files.validators import check_keys, choice, number, place, require_mapping, vector

#: a sensor's rating (`range`), N or N·m: a smaller one is a typing mistake, and its
#: inverse square (the estimator's weights) would overflow
MIN_RATING = 1e-3
MAX_RATING = 1e7
SENSOR_KEYS = {
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
#: an accelerometer's range and noise, m/s²: a shock accelerometer's range is 60,000 g, and
#: noise beyond 100 g is no reading of a desk (the estimator weighs by its inverse square)
MAX_ACCEL_RANGE_M_S2 = 1e6
MAX_ACCEL_NOISE_M_S2 = 1e3
ACCELEROMETER_KEYS = {"position", "rotation_rpy_deg", "axes", "noise_m_s2", "range_m_s2"}


def read_sensors(doc: MarkedDict) -> tuple[SensorSpec, ...]:
    """The profile's ``sensors:``: a list of at least one, each name used once."""
    items = doc["sensors"]
    if not isinstance(items, MarkedList) or not items:
        raise ConfigError(doc.where("sensors"), "`sensors` must be a list of at least one sensor")
    sensors = tuple(_sensor(item, items.where(i), i) for i, item in enumerate(items))
    names = [s.name for s in sensors]
    for i, n in enumerate(names):
        if names.index(n) != i:
            raise ConfigError(items.where(i), f"sensor name `{n}` is used twice")
    return sensors


def _sensor(item: Any, where: Any, index: int) -> SensorSpec:
    m = require_mapping(item, where, f"sensor {index + 1}")
    check_keys(m, SENSOR_KEYS, f"sensor {index + 1}", required={"name", "position"})
    name = m["name"]
    if not isinstance(name, str) or not name.replace("_", "").isalnum():
        raise ConfigError(
            m.where("name"), f"sensor `name` must be letters, digits and _, found {name!r}"
        )
    what = f"sensor `{name}`"
    position = np.array(place(m["position"], m.where("position"), f"`position` of {what}", 3))
    rotation = _rotation(m, what)
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
        rotation,
        reports,
        force_range,
        moment_range,
        channels,
        calibration,
        channel_range,
    )


def _rotation(m: MarkedDict, what: str) -> np.ndarray:
    """``rotation_rpy_deg`` (roll, pitch, yaw in degrees; none: aligned with the desk) as the
    rotation from the part's frame to the desk's."""
    rpy = vector(
        m.get("rotation_rpy_deg", [0, 0, 0]),
        m.where("rotation_rpy_deg"),
        f"`rotation_rpy_deg` of {what}",
        3,
    )
    if not all(abs(angle) <= 360 for angle in rpy):  # (1e300 was taken: cos and sin of noise)
        raise ConfigError(
            m.where("rotation_rpy_deg"),
            f"`rotation_rpy_deg` of {what} must be angles in degrees from -360 to 360, "
            f"found {list(rpy)}",
        )
    return rotation_matrix(*rpy)


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
        return _listed_axes(m, "axes", AXES, what), None
    if "channels" not in m:
        return AXES, None
    return _calibrated_channels(m, what)


def _listed_axes(m: MarkedDict, key: str, axes: tuple[str, ...], what: str) -> tuple[str, ...]:
    """Some of ``axes`` listed at ``key``, each once: in ``axes``' order (the columns')."""
    raw = m[key]
    if (
        not isinstance(raw, list)
        or not raw
        or any(a not in axes for a in raw)
        or len(set(raw)) != len(raw)
    ):
        raise ConfigError(
            m.where(key),
            f"`{key}` of {what} must list some of {', '.join(axes)} once each, found {raw!r}",
        )
    return tuple(a for a in axes if a in raw)


def _calibrated_channels(m: MarkedDict, what: str) -> tuple[tuple[str, ...], np.ndarray | None]:
    """A sensor's raw ``channels`` by name and, unless they are all axes, its
    ``calibration``: 6 rows (fx … mz) of one number per channel."""
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
    return channels, _calibration(m, what, len(channels))


def _calibration(m: MarkedDict, what: str, n_channels: int) -> np.ndarray:
    """``calibration``: (6, n) the sensor's wrench per unit of each raw channel."""
    rows = m["calibration"]
    if not isinstance(rows, list) or len(rows) != 6:
        raise ConfigError(
            m.where("calibration"),
            f"`calibration` of {what} must be 6 rows (fx, fy, fz, mx, my, mz) of "
            f"{n_channels} numbers each, one per channel",
        )
    places = rows if isinstance(rows, MarkedList) else None
    matrix = np.array(
        [
            vector(
                row,
                places.where(i) if places is not None else m.where("calibration"),
                f"row {AXES[i]} of `calibration` of {what}",
                n_channels,
            )
            for i, row in enumerate(rows)
        ]
    )
    if not (np.abs(matrix) <= MAX_RATING).all() or not matrix.any():
        raise ConfigError(
            m.where("calibration"),
            f"`calibration` of {what} must have numbers within ±{MAX_RATING:g}, not all zero",
        )
    return matrix


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


def read_accelerometers(doc: MarkedDict) -> tuple[AccelerometerSpec, ...]:
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
    check_keys(m, ACCELEROMETER_KEYS, what, required={"position"})
    position = np.array(place(m["position"], m.where("position"), f"`position` of {what}", 3))
    rotation = _rotation(m, what)
    # (columns in x, y, z order)
    axes = _listed_axes(m, "axes", ACCEL_AXES, what) if "axes" in m else ACCEL_AXES
    noise = number(m, "noise_m_s2", what, default=0.0, minimum=0.0, maximum=MAX_ACCEL_NOISE_M_S2)
    limit = number(
        m,
        "range_m_s2",
        what,
        default=math.inf,
        minimum=0.0,
        exclusive_minimum=True,
        maximum=MAX_ACCEL_RANGE_M_S2,
    )
    return AccelerometerSpec(position, rotation, axes, noise, limit, accel_column_prefix(index))
