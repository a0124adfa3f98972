"""The desk profile's ``can:`` section as a model: which bus, and how each sensor's frames are
decoded (:class:`CanConfig`). It is read and checked, every error at ``file:line:column``, by
:mod:`.config_reader` (``can_config``); the profile keeps the section as a raw
:class:`~hapticdesk.files.marked_values.MarkedDict` until a run uses it. Two decodings, chosen
per sensor:

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

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hapticdesk.canbus.ati_netcanoem import AtiCalibration
from hapticdesk.errors import Position

ASSEMBLE_MODES = ("counter", "time")
SILENT_POLICIES = ("continue", "stop")
#: the (first) accelerometer's name among the groups of channels the frames are assembled
#: into (its x, y, z decode into the group's first three channels)
ACCEL_GROUP = "accelerometer"


def accel_group(index: int) -> str:
    """The group name of the desk's ``index``-th accelerometer (from 0): ``accelerometer``,
    then ``accelerometer2``, …"""
    return ACCEL_GROUP if index == 0 else f"{ACCEL_GROUP}{index + 1}"


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
