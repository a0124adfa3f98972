"""The desk profile's ``can:`` section: which bus, and how each sensor's frames are decoded.

Validated here with ``file:line:column`` positions (the profile keeps the section as a raw
:class:`~hapticdesk.files.marked_values.MarkedDict`). Two decodings, chosen per sensor:

- signals of a CAN database (DBC, KCD, SYM, ARXML, loaded by cantools; the path is relative
  to the profile): ``fl: {fx: FL_FORCE.Fx, …, counter: [FL_FORCE.Seq, FL_MOMENT.Seq]}``;
- the ATI NETCANOEM protocol: ``ft: {ati_netcanoem: {base: 0x20}}``.

A desk with an ``accelerometer`` reads it from database signals too:
``accelerometer: {x: ACCEL.Ax, y: ACCEL.Ay, z: ACCEL.Az, counter: ACCEL.Seq}``; it is
assembled with the sensors as one more group of channels (:func:`accel_group`). A desk with
several (profile ``accelerometers:``) lists them in the profile's order:
``accelerometers: [{x: ACCEL.Ax, …}, {x: ACCEL2.Ax, …}, …]``.

See docs/can.md for every key.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hapticdesk.canbus.ati_netcanoem import (
    FORCE_UNITS,
    TORQUE_UNITS,
    AtiCalibration,
)
from hapticdesk.errors import ConfigError, Position
from hapticdesk.files.marked_values import MarkedDict, MarkedList, as_flag
from hapticdesk.files.profile import AXES, DeskProfile
from hapticdesk.files.validators import check_keys, choice, number, require_mapping, vector

ASSEMBLE_MODES = ("counter", "time")
#: the (first) accelerometer's name among the groups of channels the frames are assembled
#: into (its x, y, z decode into the group's first three channels)
ACCEL_GROUP = "accelerometer"


def accel_group(index: int) -> str:
    """The group name of the desk's ``index``-th accelerometer (from 0): ``accelerometer``,
    then ``accelerometer2``, …"""
    return ACCEL_GROUP if index == 0 else f"{ACCEL_GROUP}{index + 1}"


SILENT_POLICIES = ("continue", "stop")
#: the largest CAN database read: a desk's is a few kB and a whole vehicle's DBC a few MB;
#: cantools holds some 70 times the file's size while parsing it
MAX_DATABASE_BYTES = 8 * 1024 * 1024
_CAN_KEYS = {
    "interface",
    "channel",
    "bitrate",
    "bus_options",
    "database",
    "assemble",
    "frame_gap_s",
    "silent_timeout_s",
    "silent_sensor",
    "reconnect_timeout_s",
    "sensors",
    "accelerometer",
    "accelerometers",
}
_SIGNAL_SENSOR_KEYS = set(AXES) | {"counter", "status"}
_ATI_KEYS = {"base", "calibration", "slot"}
_CALIBRATION_KEYS = {"matrix", "counts_per_force", "counts_per_torque", "force_unit", "torque_unit"}


@dataclass(frozen=True)
class SignalRef:
    """``Message.Signal`` of the database, with where the profile names it."""

    message: str
    signal: str
    where: Position | str

    def __str__(self) -> str:
        return f"{self.message}.{self.signal}"


@dataclass(frozen=True)
class SignalSensor:
    """A sensor decoded from database signals. Axes left out read 0 (e.g. Fz-only load cells)."""

    axes: dict[str, SignalRef]  # axis name (fx … mz) -> signal
    counters: tuple[SignalRef, ...] = ()  # one per message of the sensor, or none
    status: tuple[SignalRef, ...] = ()  # any non-zero value flags the sample invalid


@dataclass(frozen=True)
class AtiSensor:
    """A sensor speaking the ATI NETCANOEM protocol at ``base``."""

    base: int
    calibration: AtiCalibration | None = None  # None: read from the bus or the capture
    slot: int | None = None  # active calibration to select on a live bus


@dataclass(frozen=True)
class CanConfig:
    """The validated ``can:`` section."""

    sensors: dict[str, SignalSensor | AtiSensor]  # in the profile's sensor order
    interface: str | None = None
    channel: str | None = None
    bitrate: int | None = None
    bus_options: dict[str, Any] = field(default_factory=dict)
    database_path: Path | None = None
    database: Any = field(default=None, compare=False, repr=False)  # cantools Database
    assemble: str = "time"  # counter | time
    frame_gap_s: float | None = None  # None: half a sample period
    silent_timeout_s: float = 0.2
    silent_sensor: str = "continue"
    reconnect_timeout_s: float = 10.0
    where: Position | str = ""
    #: the desk's accelerometers from database signals, in the profile's order (axes fx, fy,
    #: fz stand for their x, y, z)
    accelerometers: tuple[SignalSensor, ...] = ()

    def groups(self) -> list[tuple[str, SignalSensor | AtiSensor]]:
        """The groups of channels assembled into samples: the sensors in the profile's
        order, then the accelerometers."""
        out: list[tuple[str, SignalSensor | AtiSensor]] = list(self.sensors.items())
        out += [(accel_group(i), a) for i, a in enumerate(self.accelerometers)]
        return out

    @property
    def ati_sensors(self) -> dict[str, AtiSensor]:
        return {n: s for n, s in self.sensors.items() if isinstance(s, AtiSensor)}


def can_config(profile: DeskProfile) -> CanConfig:
    """Validate ``profile.can``; a ConfigError at the offending key when it is wrong."""
    where = str(profile.path) if profile.path else profile.name
    if profile.can is None:
        raise ConfigError(
            where,
            f"desk profile `{profile.name}` has no `can:` section; add one saying how each "
            "sensor's frames are decoded (see docs/can.md), e.g. use the profile kitamura2017-can",
        )
    section = require_mapping(profile.can, where, "`can`")
    return parse_can_section(section, profile)


def parse_can_section(section: MarkedDict, profile: DeskProfile) -> CanConfig:
    """Validate a ``can:`` mapping for ``profile``'s sensors."""
    check_keys(section, _CAN_KEYS, "`can`", required={"sensors"})
    interface = _text(section, "interface") if "interface" in section else None
    channel = _text(section, "channel", allow_int=True) if "channel" in section else None
    bitrate = None
    if "bitrate" in section:
        bitrate = _integer(section, "bitrate", "`can`", minimum=1)
    bus_options: dict[str, Any] = {}
    if "bus_options" in section:
        raw = require_mapping(section["bus_options"], section.where("bus_options"), "`bus_options`")
        # (python-can's options are typed: YAML 1.1's `fd: yes` stays the boolean it meant)
        bus_options = {k: as_flag(v) for k, v in raw.items()}
    database_path, database = None, None
    if "database" in section:
        database_path, database = _load_database(section, profile)

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
    accelerometers = _accelerometers(section, profile, database)
    _check_distinct_signals(sensors, accelerometers)
    _check_scales([*sensors.values(), *accelerometers], database, database_path)

    counted = list(sensors.values()) + list(accelerometers)
    all_counted = all(isinstance(s, SignalSensor) and s.counters for s in counted)
    assemble = choice(
        section, "assemble", ASSEMBLE_MODES, "`can`", default="counter" if all_counted else "time"
    )
    if assemble == "counter":
        if not all_counted:
            raise ConfigError(
                section.where("assemble"),
                "`assemble: counter` needs a `counter` for every sensor; sensors "
                + ", ".join(
                    n
                    for n, s in sensors.items()
                    if not (isinstance(s, SignalSensor) and s.counters)
                )
                + " have none (use `assemble: time`)",
            )
        moduli = {_counter_modulus(database, c) for s in counted for c in s.counters}  # type: ignore[union-attr]
        if len(moduli) > 1:
            raise ConfigError(
                section.where("sensors"),
                "`assemble: counter` matches all sensors by one counter, but their counter "
                f"signals wrap at different values ({', '.join(str(m) for m in sorted(moduli))})",
            )
    frame_gap = None
    if "frame_gap_s" in section:
        frame_gap = number(section, "frame_gap_s", "`can`", minimum=0.0, exclusive_minimum=True)
    return CanConfig(
        sensors=sensors,
        interface=interface,
        channel=channel,
        bitrate=bitrate,
        bus_options=bus_options,
        database_path=database_path,
        database=database,
        assemble=assemble,
        frame_gap_s=frame_gap,
        silent_timeout_s=number(
            section, "silent_timeout_s", "`can`", default=0.2, minimum=0.0, exclusive_minimum=True
        ),
        silent_sensor=choice(
            section, "silent_sensor", SILENT_POLICIES, "`can`", default="continue"
        ),
        reconnect_timeout_s=number(
            section, "reconnect_timeout_s", "`can`", default=10.0, minimum=0.0
        ),
        where=section.where(),
        accelerometers=accelerometers,
    )


# --- pieces -----------------------------------------------------------------------------------


def _text(m: MarkedDict, key: str, allow_int: bool = False) -> str:
    value = m[key]
    if allow_int and isinstance(value, int) and not isinstance(value, bool):
        return str(value)
    if not isinstance(value, str) or not value:
        raise ConfigError(m.where(key), f"`{key}` in `can` must be a text, found {value!r}")
    return value


def _integer(
    m: MarkedDict, key: str, what: str, minimum: int = 0, maximum: int | None = None
) -> int:
    value = m[key]
    if isinstance(value, bool) or not isinstance(value, int):
        raise ConfigError(
            m.where(key), f"`{key}` in {what} must be a whole number, found {value!r}"
        )
    if value < minimum or (maximum is not None and value > maximum):
        bound = f"{minimum}…{maximum} (0x{minimum:X}…0x{maximum:X})" if maximum else f">= {minimum}"
        raise ConfigError(m.where(key), f"`{key}` in {what} must be {bound}, found {value}")
    return value


def _load_database(section: MarkedDict, profile: DeskProfile) -> tuple[Path, Any]:
    raw = section["database"]
    where = section.where("database")
    if not isinstance(raw, str) or not raw:
        raise ConfigError(where, f"`database` must be a file name, found {raw!r}")
    path = Path(raw)
    if not path.is_absolute() and profile.path is not None:
        path = profile.path.parent / path
    if not path.is_file():
        raise ConfigError(where, f"CAN database {raw!r} not found (looked for {path})")
    size = path.stat().st_size
    if size > MAX_DATABASE_BYTES:
        raise ConfigError(
            where,
            f"CAN database {path} is {size / 2**20:.1f} MiB; at most "
            f"{MAX_DATABASE_BYTES / 2**20:g} MiB is read (a desk's database is a few kB: keep "
            "its messages in a file of their own)",
        )
    if path.suffix.lower() == ".dbc":
        _check_dbc_sizes(path)
    import cantools  # lazily: only a desk on CAN needs it

    try:
        database = cantools.database.load_file(str(path), strict=True)
    except Exception as err:  # cantools raises many kinds (ParseError, UnsupportedDatabaseFormat…)
        raise ConfigError(where, f"cannot load CAN database {path}: {_load_failure(err)}") from None
    if not hasattr(database, "get_message_by_name"):
        raise ConfigError(where, f"{path} is a diagnostics database, expected a CAN database")
    return path, database


#: a DBC message's length in bytes at most this (a CAN FD frame's); cantools builds tables
#: as long as the length it is told (BO_ … : 99999999 ran past a minute and 2.8 GB)
MAX_FRAME_BYTES = 64
#: signals in a DBC at most this many (2000 messages of 64 signals took cantools 25 s, 475 MB)
MAX_DBC_SIGNALS = 10_000
_DBC_MESSAGE = re.compile(r"^\s*BO_\s+\d+\s+\w+\s*:\s*(\d+)")
_DBC_SIGNAL = re.compile(r"^\s*SG_\s")


def _check_dbc_sizes(path: Path) -> None:
    """Refuse, at its line, a DBC message longer than a CAN frame, and a DBC with more
    signals than any desk has, before cantools builds them (file:line:column)."""
    signals = 0
    with path.open(encoding="utf-8", errors="replace") as lines:  # (size checked above)
        for number, line in enumerate(lines, 1):
            found = _DBC_MESSAGE.match(line)
            if found and (len(found[1]) > 3 or int(found[1]) > MAX_FRAME_BYTES):
                raise ConfigError(
                    Position(str(path), number, found.start(1) + 1),
                    f"message length {found[1]} bytes; a CAN frame carries at most "
                    f"{MAX_FRAME_BYTES} (CAN FD)",
                )
            signals += bool(_DBC_SIGNAL.match(line))
            if signals > MAX_DBC_SIGNALS:
                raise ConfigError(
                    Position(str(path), number, 1),
                    f"more than {MAX_DBC_SIGNALS:,} signals: a desk's database has a few dozen "
                    "(keep its messages in a file of their own)",
                )


def _load_failure(err: BaseException) -> str:
    """Why cantools could not load a database, never empty: cantools reports each format it
    tried (``DBC: "…"``), and an exception without a message (a MemoryError) reads as ``""``."""
    tried = [
        (name.upper(), getattr(err, f"e_{name}", None))
        for name in ("arxml", "dbc", "kcd", "sym", "cdd")
    ]
    parts = [f'{name}: "{_exception_text(e)}"' for name, e in tried if e is not None]
    return ", ".join(parts) if parts else _exception_text(err)


def _exception_text(err: BaseException) -> str:
    text = str(err).strip()
    if text:
        return text
    if isinstance(err, MemoryError):
        return "it needs more memory than there is"
    return f"an unexplained {type(err).__name__}"


def _check_scales(
    groups: list[SignalSensor | AtiSensor], database: Any, database_path: Path | None
) -> None:
    """A signal read as a force, moment or acceleration needs a finite non-zero scale: with
    scale 0 every frame decodes as the offset (and encoding one divides by zero)."""
    for group in groups:
        if not isinstance(group, SignalSensor):
            continue
        for ref in group.axes.values():
            message = database.get_message_by_name(ref.message)
            scale = float(message.get_signal_by_name(ref.signal).scale)
            if scale == 0.0 or not math.isfinite(scale):
                raise ConfigError(
                    ref.where,
                    f"signal `{ref}` of CAN database {database_path} has scale {scale:g}; "
                    "expected a finite non-zero scale (with 0 every frame reads the same)",
                )


def _signal_ref(value: Any, where: Position | str, what: str, database: Any) -> SignalRef:
    if not isinstance(value, str) or "." not in value:
        raise ConfigError(where, f"{what} must be `Message.Signal`, found {value!r}")
    message_name, _, signal_name = value.rpartition(".")
    ref = SignalRef(message_name, signal_name, where)
    if database is None:
        raise ConfigError(where, f"{what} names signal {value} but `can` gives no `database`")
    try:
        message = database.get_message_by_name(message_name)
    except KeyError:
        names = sorted(m.name for m in database.messages)
        raise ConfigError(
            where,
            f"{what}: the database has no message `{message_name}`; it has "
            f"{', '.join(names[:12])}{' …' if len(names) > 12 else ''}",
        ) from None
    if message.is_container:
        raise ConfigError(where, f"{what}: `{message_name}` is a container message (unsupported)")
    if message.length > 8:
        raise ConfigError(
            where,
            f"{what}: `{message_name}` is {message.length} bytes long; only classic CAN "
            "frames of up to 8 bytes are supported",
        )
    try:
        signal = message.get_signal_by_name(signal_name)
    except KeyError:
        raise ConfigError(
            where,
            f"{what}: message `{message_name}` has no signal `{signal_name}`; it has "
            + ", ".join(s.name for s in message.signals),
        ) from None
    if signal.multiplexer_ids or signal.is_multiplexer:
        raise ConfigError(where, f"{what}: `{value}` is multiplexed (unsupported)")
    return ref


def _signal_list(m: MarkedDict, key: str, what: str, database: Any) -> tuple[SignalRef, ...]:
    raw = m[key]
    if isinstance(raw, str):
        return (_signal_ref(raw, m.where(key), f"`{key}` of {what}", database),)
    if not isinstance(raw, list) or not raw:
        raise ConfigError(
            m.where(key), f"`{key}` of {what} must be `Message.Signal` or a list of them"
        )
    return tuple(
        _signal_ref(v, raw.where(i), f"`{key}` of {what}", database)  # type: ignore[attr-defined]
        for i, v in enumerate(raw)
    )


def _signal_sensor(item: MarkedDict, name: str, database: Any, section: MarkedDict) -> SignalSensor:
    what = f"sensor `{name}`"
    check_keys(item, _SIGNAL_SENSOR_KEYS | {"ati_netcanoem"}, f"`can.sensors.{name}`")
    axes = {
        axis: _signal_ref(item[axis], item.where(axis), f"`{axis}` of {what}", database)
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
        moduli = {_counter_modulus(database, c) for c in counters}
        if len(moduli) > 1:
            raise ConfigError(item.where("counter"), f"the counters of {what} wrap differently")
    status = _signal_list(item, "status", what, database) if "status" in item else ()
    for ref in status:
        if ref.message not in messages:
            raise ConfigError(
                ref.where, f"status {ref} of {what} is not in one of its axes' messages"
            )
    return SignalSensor(axes=axes, counters=counters, status=status)


def _accelerometers(
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


def _counter_modulus(database: Any, ref: SignalRef) -> int:
    signal = database.get_message_by_name(ref.message).get_signal_by_name(ref.signal)
    if signal.is_float or signal.is_signed:
        raise ConfigError(ref.where, f"counter {ref} must be an unsigned integer signal")
    return 1 << int(signal.length)


def _ati_sensor(item: MarkedDict, name: str) -> AtiSensor:
    check_keys(item, {"ati_netcanoem"}, f"`can.sensors.{name}` (with `ati_netcanoem`)")
    what = f"`ati_netcanoem` of sensor `{name}`"
    raw = item["ati_netcanoem"]
    if raw is None:  # `ati_netcanoem:` alone: the board's defaults
        return AtiSensor(base=0x20)
    m = require_mapping(raw, item.where("ati_netcanoem"), what)
    check_keys(m, _ATI_KEYS, what)
    base = _integer(m, "base", what, 0, 0x7F) if "base" in m else 0x20
    slot = _integer(m, "slot", what, 0, 15) if "slot" in m else None
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
            m, "counts_per_force", what, default=1e6, minimum=0.0, exclusive_minimum=True
        ),
        counts_per_torque=number(
            m, "counts_per_torque", what, default=1e6, minimum=0.0, exclusive_minimum=True
        ),
        force_unit=choice(m, "force_unit", tuple(force_names), what, default="N"),
        torque_unit=choice(m, "torque_unit", tuple(torque_names), what, default="N-m"),
    )


def _check_distinct_signals(
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
    from hapticdesk.canbus.ati_netcanoem import ati_frame_ids

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
