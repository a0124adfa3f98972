"""Reading the desk profile's ``can:`` section into a :class:`~.config.CanConfig`: the bus
(interface, channel, bit rate, python-can options), the database (:mod:`.can_database`),
each sensor's and accelerometer's decoding (:mod:`.config_sensors`), how frames are assembled
into samples, and what a silent sensor does. Every error at ``file:line:column``; see
docs/can.md for every key."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from hapticdesk.canbus.can_database import check_scales, counter_modulus, load_database
from hapticdesk.canbus.config import (
    ASSEMBLE_MODES,
    SILENT_POLICIES,
    AtiSensor,
    CanConfig,
    SignalSensor,
)
from hapticdesk.canbus.config_sensors import (
    check_distinct_signals,
    read_accelerometers,
    read_sensors,
)
from hapticdesk.errors import ConfigError
from hapticdesk.files.marked_values import MarkedDict, as_flag
from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.validators import check_keys, choice, number, require_mapping, whole_number

#: the longest a `can:` wait may be, seconds (as a serial board's, boards.settings.MAX_WAIT_S):
#: beyond an hour a silence or a lost bus is a typing mistake, not a setting
MAX_CAN_WAIT_S = 3600.0
#: the longest pause within one sample's frames, seconds: a sample period of the slowest
#: desk (10 Hz); a longer gap would never start a sample
MAX_FRAME_GAP_S = 0.1
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


@dataclass(frozen=True)
class BusSettings:
    """Which bus the section names: interface, channel, bit rate, python-can's options."""

    interface: str | None = None
    channel: str | None = None
    bitrate: int | None = None
    bus_options: dict[str, Any] = field(default_factory=dict)


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
    bus = _bus(section)
    database_path, database = None, None
    if "database" in section:
        database_path, database = load_database(section, profile)
    sensors = read_sensors(section, profile, database)
    accelerometers = read_accelerometers(section, profile, database)
    check_distinct_signals(sensors, accelerometers)
    check_scales([*sensors.values(), *accelerometers], database, database_path)
    assemble = _assemble(section, sensors, accelerometers, database)
    frame_gap = None
    if "frame_gap_s" in section:
        frame_gap = number(
            section,
            "frame_gap_s",
            "`can`",
            minimum=0.0,
            exclusive_minimum=True,
            maximum=MAX_FRAME_GAP_S,
        )
    return CanConfig(
        sensors=sensors,
        interface=bus.interface,
        channel=bus.channel,
        bitrate=bus.bitrate,
        bus_options=bus.bus_options,
        database_path=database_path,
        database=database,
        assemble=assemble,
        frame_gap_s=frame_gap,
        silent_timeout_s=number(
            section,
            "silent_timeout_s",
            "`can`",
            default=0.2,
            minimum=0.0,
            exclusive_minimum=True,
            maximum=MAX_CAN_WAIT_S,
        ),
        silent_sensor=choice(
            section, "silent_sensor", SILENT_POLICIES, "`can`", default="continue"
        ),
        reconnect_timeout_s=number(
            section,
            "reconnect_timeout_s",
            "`can`",
            default=10.0,
            minimum=0.0,
            maximum=MAX_CAN_WAIT_S,
        ),
        where=section.where(),
        accelerometers=accelerometers,
    )


def _bus(section: MarkedDict) -> BusSettings:
    """``interface``, ``channel``, ``bitrate`` and ``bus_options`` (each optional: a run's
    ``--source can:INTERFACE:CHANNEL`` may give them)."""
    interface = _text(section, "interface") if "interface" in section else None
    channel = _text(section, "channel", allow_int=True) if "channel" in section else None
    bitrate = None
    if "bitrate" in section:
        bitrate = whole_number(section, "bitrate", "`can`", minimum=1)
    bus_options: dict[str, Any] = {}
    if "bus_options" in section:
        raw = require_mapping(section["bus_options"], section.where("bus_options"), "`bus_options`")
        # (python-can's options are typed: YAML 1.1's `fd: yes` stays the boolean it meant)
        bus_options = {k: as_flag(v) for k, v in raw.items()}
    return BusSettings(interface, channel, bitrate, bus_options)


def _text(m: MarkedDict, key: str, allow_int: bool = False) -> str:
    value = m[key]
    if allow_int and isinstance(value, int) and not isinstance(value, bool):
        return str(value)
    if not isinstance(value, str) or not value:
        raise ConfigError(m.where(key), f"`{key}` in `can` must be a text, found {value!r}")
    return value


def _assemble(
    section: MarkedDict,
    sensors: dict[str, SignalSensor | AtiSensor],
    accelerometers: tuple[SignalSensor, ...],
    database: Any,
) -> str:
    """``assemble``: ``counter`` (the default when every sensor and accelerometer has a
    counter, all wrapping alike) or ``time``."""
    counted = list(sensors.values()) + list(accelerometers)
    all_counted = all(isinstance(s, SignalSensor) and s.counters for s in counted)
    assemble = choice(
        section, "assemble", ASSEMBLE_MODES, "`can`", default="counter" if all_counted else "time"
    )
    if assemble != "counter":
        return assemble
    if not all_counted:
        raise ConfigError(
            section.where("assemble"),
            "`assemble: counter` needs a `counter` for every sensor; sensors "
            + ", ".join(
                n for n, s in sensors.items() if not (isinstance(s, SignalSensor) and s.counters)
            )
            + " have none (use `assemble: time`)",
        )
    moduli = {counter_modulus(database, c) for s in counted for c in s.counters}
    if len(moduli) > 1:
        raise ConfigError(
            section.where("sensors"),
            "`assemble: counter` matches all sensors by one counter, but their counter "
            f"signals wrap at different values ({', '.join(str(m) for m in sorted(moduli))})",
        )
    return assemble
