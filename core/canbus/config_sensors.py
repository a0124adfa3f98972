"""The ``can:`` section's decodings, sensor by sensor: ``can.sensors`` (database signals, or
``ati_netcanoem`` with an optional calibration) and ``can.accelerometer(s)``, each checked
against the desk's profile and the database, and that no signal or identifier is read twice.
Part of :mod:`.config_reader`."""

from __future__ import annotations

from typing import Any

import numpy as np

from hapticdesk.canbus.ati_netcanoem import (
    FORCE_UNITS,
    TORQUE_UNITS,
    AtiCalibration,
    ati_frame_ids,
)
from hapticdesk.canbus.can_database import counter_modulus, signal_ref
from hapticdesk.canbus.config import AtiSensor, SignalRef, SignalSensor, accel_group
from hapticdesk.errors import ConfigError, Position
from hapticdesk.files.marked_values import MarkedDict, MarkedList
from hapticdesk.files.profile import AXES, DeskProfile
from hapticdesk.files.validators import (
    check_keys,
    choice,
    number,
    require_mapping,
    vector,
    whole_number,
)

_SIGNAL_SENSOR_KEYS = set(AXES) | {"counter", "status"}
_ATI_KEYS = {"base", "calibration", "slot"}
#: the most counts per newton (or N·m) an ATI calibration may give: its readings are 32-bit
#: counts, so more would leave the whole range within ±2 N
MAX_COUNTS_PER_UNIT = 1e9
_CALIBRATION_KEYS = {"matrix", "counts_per_force", "counts_per_torque", "force_unit", "torque_unit"}


def read_sensors(
    section: MarkedDict, profile: DeskProfile, database: Any
) -> dict[str, SignalSensor | AtiSensor]:
    """``can.sensors``: a decoding for every sensor of the desk and no other, in the
    profile's order (the order of the wrench's sensor axis)."""
    sensors_raw = require_mapping(section["sensors"], section.where("sensors"), "`can.sensors`")
    known = profile.sensor_names
    for name in sensors_raw:
        if name not in known:
            raise ConfigError(
                sensors_raw.where(name, of_key=True),
                f"`can.sensors` names `{name}`, which is not a sensor of desk `{profile.name}`; "
                f"its sensors are {', '.join(known)}",
            )
    missing = [n for n in known if n not in sensors_raw]
    if missing:
        raise ConfigError(
            sensors_raw.where(),
            f"`can.sensors` says nothing about sensor(s) {', '.join(missing)}; every sensor of "
            "the desk needs a decoding (database signals or `ati_netcanoem`)",
        )
    sensors: dict[str, SignalSensor | AtiSensor] = {}
    for name in known:  # the profile's order, which is the order of the wrench's sensor axis
        item = require_mapping(sensors_raw[name], sensors_raw.where(name), f"sensor `{name}`")
        if "ati_netcanoem" in item:
            sensors[name] = _ati_sensor(item, name)
        else:
            sensors[name] = _signal_sensor(item, name, database, section)
    _check_distinct_ids(sensors, database, sensors_raw)
    return sensors


def _signal_list(m: MarkedDict, key: str, what: str, database: Any) -> tuple[SignalRef, ...]:
    raw = m[key]
    if isinstance(raw, str):
        return (signal_ref(raw, m.where(key), f"`{key}` of {what}", database),)
    if not isinstance(raw, list) or not raw:
        raise ConfigError(
            m.where(key), f"`{key}` of {what} must be `Message.Signal` or a list of them"
        )
    return tuple(
        signal_ref(v, raw.where(i), f"`{key}` of {what}", database)  # type: ignore[attr-defined]
        for i, v in enumerate(raw)
    )


def _signal_sensor(item: MarkedDict, name: str, database: Any, section: MarkedDict) -> SignalSensor:
    what = f"sensor `{name}`"
    check_keys(item, _SIGNAL_SENSOR_KEYS | {"ati_netcanoem"}, f"`can.sensors.{name}`")
    axes = {
        axis: signal_ref(item[axis], item.where(axis), f"`{axis}` of {what}", database)
        for axis in AXES
        if axis in item
    }
    if not axes:
        raise ConfigError(
            item.where(),
            f"{what} maps no axis; give `fx` … `mz` as `Message.Signal` or `ati_netcanoem`",
        )
    messages = {ref.message for ref in axes.values()}
    counters = _signal_list(item, "counter", what, database) if "counter" in item else ()
    if counters:
        by_message: dict[str, SignalRef] = {}
        for ref in counters:
            if ref.message not in messages:
                raise ConfigError(
                    ref.where,
                    f"counter {ref} of {what} is in message `{ref.message}`, which carries none "
                    f"of its axes ({', '.join(sorted(messages))})",
                )
            if ref.message in by_message:
                raise ConfigError(ref.where, f"{what} lists two counters of `{ref.message}`")
            by_message[ref.message] = ref
        lacking = sorted(messages - set(by_message))
        if lacking:
            raise ConfigError(
                item.where("counter"),
                f"`counter` of {what} must name one counter signal in each of its messages; "
                f"missing for {', '.join(lacking)}",
            )
        moduli = {counter_modulus(database, c) for c in counters}
        if len(moduli) > 1:
            raise ConfigError(item.where("counter"), f"the counters of {what} wrap differently")
    status = _signal_list(item, "status", what, database) if "status" in item else ()
    for ref in status:
        if ref.message not in messages:
            raise ConfigError(
                ref.where, f"status {ref} of {what} is not in one of its axes' messages"
            )
    return SignalSensor(axes=axes, counters=counters, status=status)


def read_accelerometers(
    section: MarkedDict, profile: DeskProfile, database: Any
) -> tuple[SignalSensor, ...]:
    """``can.accelerometer`` (one) or ``can.accelerometers`` (a list, one entry for each of
    the profile's accelerometers in its order): their axes as database signals."""
    key = "accelerometers" if "accelerometers" in section else "accelerometer"
    if key not in section:
        return ()
    if "accelerometer" in section and "accelerometers" in section:
        raise ConfigError(
            section.where("accelerometers", of_key=True),
            "give either `can.accelerometer` (one) or `can.accelerometers` (a list), not both",
        )
    have = len(profile.accelerometers)
    if have == 0:
        raise ConfigError(
            section.where(key, of_key=True),
            f"`can.{key}` decodes an accelerometer, but desk `{profile.name}` has "
            "none: add `accelerometer:` to the profile (where it is mounted, its axes)",
        )
    if key == "accelerometer":
        if have > 1:
            raise ConfigError(
                section.where(key, of_key=True),
                f"`can.accelerometer` decodes one accelerometer, but desk `{profile.name}` has "
                f"{have}: list them as `can.accelerometers: [{{x: …, y: …, z: …}}, …]` in the "
                "profile's order",
            )
        items: list[tuple[Any, Any, str]] = [
            (section["accelerometer"], section.where(key), "`can.accelerometer`")
        ]
    else:
        raw = section["accelerometers"]
        if not isinstance(raw, MarkedList) or len(raw) != have:
            raise ConfigError(
                section.where(key),
                f"`can.accelerometers` must be a list of {have} entries, one for each of desk "
                f"`{profile.name}`'s accelerometers in its order, found "
                f"{len(raw) if isinstance(raw, list) else repr(raw)}",
            )
        items = [
            (item, raw.where(i), f"accelerometer {i + 1} of `can.accelerometers`")
            for i, item in enumerate(raw)
        ]
    return tuple(
        _accelerometer(item, where, what, i, profile, database, section)
        for i, (item, where, what) in enumerate(items)
    )


def _accelerometer(
    item: Any,
    where: Any,
    what: str,
    index: int,
    profile: DeskProfile,
    database: Any,
    section: MarkedDict,
) -> SignalSensor:
    """The profile's ``index``-th accelerometer's axes as database signals (``what``: its
    entry, for errors)."""
    spec = profile.accelerometers[index]
    item = require_mapping(item, where, what)
    check_keys(item, {"x", "y", "z", "counter", "status"}, what)
    given = [a for a in ("x", "y", "z") if a in item]
    if given != list(spec.axes):
        raise ConfigError(
            item.where(),
            f"{what} must give a signal for each of the accelerometer's axes "
            f"({', '.join(spec.axes)}), found {', '.join(given) or 'none'}",
        )
    # the same rules as a sensor's signals, its x, y, z in a sensor's fx, fy, fz
    renamed = MarkedDict({("f" + k if k in ("x", "y", "z") else k): v for k, v in item.items()})
    renamed.position = item.position
    renamed.key_positions = {
        ("f" + k if k in ("x", "y", "z") else k): p for k, p in item.key_positions.items()
    }
    renamed.value_positions = {
        ("f" + k if k in ("x", "y", "z") else k): p for k, p in item.value_positions.items()
    }
    return _signal_sensor(renamed, accel_group(index), database, section)


def _ati_sensor(item: MarkedDict, name: str) -> AtiSensor:
    check_keys(item, {"ati_netcanoem"}, f"`can.sensors.{name}` (with `ati_netcanoem`)")
    what = f"`ati_netcanoem` of sensor `{name}`"
    raw = item["ati_netcanoem"]
    if raw is None:  # `ati_netcanoem:` alone: the board's defaults
        return AtiSensor(base=0x20)
    m = require_mapping(raw, item.where("ati_netcanoem"), what)
    check_keys(m, _ATI_KEYS, what)
    base = whole_number(m, "base", what, 0, 0x7F) if "base" in m else 0x20
    slot = whole_number(m, "slot", what, 0, 15) if "slot" in m else None
    calibration = (
        _calibration(m["calibration"], m.where("calibration"), name) if "calibration" in m else None
    )
    return AtiSensor(base=base, calibration=calibration, slot=slot)


def _calibration(raw: Any, where: Position | str, name: str) -> AtiCalibration:
    what = f"`calibration` of sensor `{name}`"
    m = require_mapping(raw, where, what)
    check_keys(m, _CALIBRATION_KEYS, what, required={"matrix"})
    rows = m["matrix"]
    if not isinstance(rows, MarkedList) or len(rows) != 6:
        raise ConfigError(
            m.where("matrix"), f"`matrix` of {what} must be 6 rows (Fx Fy Fz Tx Ty Tz) of 6 numbers"
        )
    matrix = np.array(
        [
            vector(r, rows.where(i), f"row {i + 1} of the matrix of {what}", 6)
            for i, r in enumerate(rows)
        ]
    )
    if abs(np.linalg.det(matrix)) < 1e-300 or np.linalg.matrix_rank(matrix) < 6:
        raise ConfigError(m.where("matrix"), f"`matrix` of {what} is singular")
    force_names = [u for u, _ in FORCE_UNITS.values()]
    torque_names = [u for u, _ in TORQUE_UNITS.values()]
    return AtiCalibration(
        matrix=matrix,
        counts_per_force=number(
            m,
            "counts_per_force",
            what,
            default=1e6,
            minimum=0.0,
            exclusive_minimum=True,
            maximum=MAX_COUNTS_PER_UNIT,
        ),
        counts_per_torque=number(
            m,
            "counts_per_torque",
            what,
            default=1e6,
            minimum=0.0,
            exclusive_minimum=True,
            maximum=MAX_COUNTS_PER_UNIT,
        ),
        force_unit=choice(m, "force_unit", tuple(force_names), what, default="N"),
        torque_unit=choice(m, "torque_unit", tuple(torque_names), what, default="N-m"),
    )


def check_distinct_signals(
    sensors: dict[str, SignalSensor | AtiSensor],
    accelerometers: tuple[SignalSensor, ...],
) -> None:
    """No signal read as two axes (a copied line left unedited: two axes would read one
    value, and the desk's balance of forces and moments would be wrong without a word)."""
    owners = [(f"sensor `{n}`", s) for n, s in sensors.items() if isinstance(s, SignalSensor)]
    owners += [(f"accelerometer {i + 1}", a) for i, a in enumerate(accelerometers)]
    first: dict[str, tuple[str, SignalRef]] = {}
    for label, sensor in owners:
        for axis, ref in sensor.axes.items():
            # (an accelerometer's x, y, z ride in a sensor's fx, fy, fz)
            said = f"`{axis[1:] if label.startswith('accel') else axis}` of {label}"
            if str(ref) in first:
                other, other_ref = first[str(ref)]
                raise ConfigError(
                    ref.where,
                    f"{said} reads signal `{ref}`, which {other} reads already (at "
                    f"{other_ref.where}); each axis needs its own signal",
                )
            first[str(ref)] = (said, ref)


def _check_distinct_ids(
    sensors: dict[str, SignalSensor | AtiSensor], database: Any, where_map: MarkedDict
) -> None:
    """No two sensors' frames may share an identifier (else they could not be told apart)."""
    owner: dict[int, str] = {}
    for name, sensor in sensors.items():
        if isinstance(sensor, AtiSensor):
            ids = ati_frame_ids(sensor.base)
            label = f"sensor `{name}` (ATI base 0x{sensor.base:02X})"
        else:
            messages = [database.get_message_by_name(r.message) for r in sensor.axes.values()]
            ids = {m.frame_id for m in messages if not m.is_extended_frame}
            label = f"sensor `{name}`"
        for ident in ids:
            other = owner.get(ident)
            # signal sensors may share a message; an ATI board shares its ids with nobody
            if other is not None and other != label and ("ATI" in label or "ATI" in other):
                raise ConfigError(
                    where_map.where(name),
                    f"{label} uses CAN id 0x{ident:03X}, which {other} uses too",
                )
            owner.setdefault(ident, label)
