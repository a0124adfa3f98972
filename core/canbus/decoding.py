"""How a desk's frames become fields and fields become each sensor's six channels.

A *frame kind* is one identifier and length that carries data (a database message, or one of
the two sample frames of an ATI board); decoding it fills some columns of a per-sample
*field table*. A *sensor reading* turns its columns into Fx … Mz in N and N·m and says which
samples its status marks invalid. Both are built once from the validated ``can:`` section;
the assembler (:mod:`hapticdesk.canbus.assembler`) decides which frames form one sample.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from hapticdesk.canbus import ati_netcanoem as ati
from hapticdesk.canbus.config import AtiSensor, CanConfig, SignalRef, SignalSensor
from hapticdesk.canbus.dbc_signals import SignalLayout, frame_words
from hapticdesk.canbus.frames import ERROR, EXTENDED, REMOTE, FrameArray
from hapticdesk.errors import ConfigError
from hapticdesk.files.profile import AXES, DeskProfile

# classification codes (kind indices are >= 0)
FOREIGN = -1  # an identifier the desk does not use (CANopen traffic, other devices)
WRONG_LENGTH = -2  # a desk identifier with a length no frame kind has
PROTOCOL = -3  # a desk identifier that is not sample data (ATI calibration traffic, …)
REQUEST = -4  # a poll for an ATI sample (length 0)
ERROR_FRAME = -5
REMOTE_FRAME = -6


@dataclass(frozen=True)
class FrameKind:
    """One identifier and length carrying sample data."""

    name: str
    ident: int  # with frames.EXTENDED set for 29-bit identifiers
    length: int
    slots: np.ndarray  # (nf,) field-table columns this kind fills
    decode: Callable[[np.ndarray], np.ndarray]  # (n, 8) uint8 -> (n, nf) float64
    counter: SignalLayout | None = None
    sensors: tuple[int, ...] = ()

    def label(self) -> str:
        return f"{self.name} (0x{self.ident & 0x1FFFFFFF:03X})"


class SensorReading:
    """A sensor's columns of the field table -> (k, 6) channels, invalid samples, status."""

    name: str
    columns: np.ndarray  # every column of this sensor

    def channels(self, table: np.ndarray) -> tuple[np.ndarray, np.ndarray, dict[str, int]]:
        """(wrench (k, 6), invalid (k,) bool, status counts by description)."""
        raise NotImplementedError


class SignalReading(SensorReading):
    """Channels straight from database signals (already scaled); unmapped axes read 0."""

    def __init__(
        self, name: str, axis_columns: dict[int, int], status_columns: list[tuple[str, int]]
    ):
        self.name = name
        self.axis_columns = axis_columns
        self.status_columns = status_columns
        self.columns = np.array(list(axis_columns.values()) + [c for _, c in status_columns])

    def channels(self, table: np.ndarray) -> tuple[np.ndarray, np.ndarray, dict[str, int]]:
        wrench = np.zeros((len(table), 6))
        for axis, col in self.axis_columns.items():
            wrench[:, axis] = table[:, col]
        invalid = np.zeros(len(table), dtype=bool)
        counts: dict[str, int] = {}
        for label, col in self.status_columns:
            bad = np.abs(table[:, col]) > 0  # NaN (frame missing) is not a status
            invalid |= bad
            if bad.any():
                counts[f"{label} non-zero"] = int(bad.sum())
        return wrench, invalid, counts


class AtiReading(SensorReading):
    """Gauges through the calibration; critical status bits invalidate the sample."""

    def __init__(self, name: str, first_column: int, calibration: ati.AtiCalibration):
        self.name = name
        # columns: status, sg0, sg2, sg4 (frame 0x0), then sg1, sg3, sg5 (frame 0x1)
        self.columns = np.arange(first_column, first_column + 7)
        self.calibration = calibration
        self.gauge_map = calibration.gauge_map()

    def channels(self, table: np.ndarray) -> tuple[np.ndarray, np.ndarray, dict[str, int]]:
        c = self.columns
        gauges = ati.gauges_from_fields(table[:, c[1:4]], table[:, c[4:7]])
        wrench = gauges @ self.gauge_map.T
        status = table[:, c[0]]
        known = ~np.isnan(status)
        word = np.where(known, status, 0).astype(np.int64)
        invalid = (word & ati.CRITICAL_MASK) != 0
        counts: dict[str, int] = {}
        if word.any():
            for bit in range(16):
                n = int(np.count_nonzero(word & (1 << bit)))
                if n:
                    counts[ati.status_bit_name(bit)] = n
        return wrench, invalid, counts


class AtiReadings:
    """The ATI boards' readings side by side: :meth:`AtiReading.channels` for all at once
    (one gather, one stacked product, one status pass instead of one of each a board)."""

    def __init__(self, readings: list[tuple[int, AtiReading]]) -> None:
        self.index = np.array([s for s, _ in readings], dtype=np.int64)
        columns = [r.columns for _, r in readings]
        # sg0 … sg5 from the columns status, sg0, sg2, sg4 (frame 0x0), sg1, sg3, sg5 (0x1)
        self.gauge_columns = np.array([c[[1, 4, 2, 5, 3, 6]] for c in columns], dtype=np.int64)
        self.status_columns = np.array([c[0] for c in columns], dtype=np.int64)
        # each map transposed as a view, as AtiReading's product takes it (the same sums)
        self.maps_t = (
            np.stack([r.gauge_map for _, r in readings]).transpose(0, 2, 1) if readings else None
        )

    def channels(
        self,
        table: np.ndarray,
        wrench: np.ndarray,
        invalid: np.ndarray,
        counts: list[dict[str, int]],
    ) -> None:
        """Fill the ATI readings' places of ``wrench``, ``invalid`` and ``counts``."""
        if self.maps_t is None:
            return
        gauges = np.ascontiguousarray(table[:, self.gauge_columns].transpose(1, 0, 2))
        wrench[:, self.index] = np.matmul(gauges, self.maps_t).transpose(1, 0, 2)
        status = table[:, self.status_columns]
        word = np.where(np.isnan(status), 0, status).astype(np.int64)
        invalid[:, self.index] = (word & ati.CRITICAL_MASK) != 0
        if not word.any():
            return
        per_bit = ((word[:, :, None] >> np.arange(16)) & 1).sum(axis=0)  # (boards, 16)
        for j, bit in zip(*np.nonzero(per_bit), strict=True):
            counts[int(self.index[j])][ati.status_bit_name(int(bit))] = int(per_bit[j, bit])


@dataclass
class DeskDecoding:
    """Everything needed to turn a desk's frames into samples."""

    kinds: list[FrameKind]
    # in the profile's sensor order, then the accelerometers' (config.accel_group) if any
    readings: list[SensorReading]
    n_fields: int
    request_sensor: dict[int, int]  # ATI sample-request identifier -> sensor index
    protocol_ids: frozenset[int]
    counter_modulus: int | None  # set when every kind has a counter
    # kind of a reply's second frame -> kind of its first (an ATI board's 0x1 after its 0x0)
    second_halves: dict[int, int] = field(default_factory=dict)
    n_accelerometers: int = 0  # the last readings are the accelerometers' (config.groups)

    def __post_init__(self) -> None:
        keys, codes = [], []
        for i, kind in enumerate(self.kinds):
            keys.append(_lookup_key(kind.ident, kind.length))
            codes.append(i)
        for ident in self.request_sensor:
            keys.append(_lookup_key(ident, 0))
            codes.append(REQUEST)
        order = np.argsort(keys)
        self._keys = np.asarray(keys, dtype=np.uint64)[order]
        self._codes = np.asarray(codes, dtype=np.int64)[order]
        self._data_ids = np.unique(np.array([k.ident for k in self.kinds], dtype=np.uint32))
        self._protocol_ids = np.array(sorted(self.protocol_ids), dtype=np.uint32)
        self.kind_sensors = [np.array(k.sensors, dtype=np.int64) for k in self.kinds]
        self._ati = AtiReadings(
            [(s, r) for s, r in enumerate(self.readings) if isinstance(r, AtiReading)]
        )

    @property
    def sensor_names(self) -> list[str]:
        return [r.name for r in self.readings]

    @property
    def accel_axes(self) -> list[list[int]]:
        """For each accelerometer on the bus, in order, the channels of its group that hold
        its axes (x, y, z order); empty when the desk has none (their groups come last)."""
        first = len(self.readings) - self.n_accelerometers
        out = []
        for reading in self.readings[first:]:
            assert isinstance(reading, SignalReading)  # (accelerometers are database signals)
            out.append(sorted(reading.axis_columns))
        return out

    def channels(self, table: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[dict[str, int]]]:
        """Every reading's channels from the field table: wrench (k, R, 6), invalid (k, R)
        and the status counts of each (as :meth:`SensorReading.channels`, the ATI boards'
        all at once)."""
        n = len(self.readings)
        wrench = np.empty((len(table), n, 6))
        invalid = np.zeros((len(table), n), dtype=bool)
        counts: list[dict[str, int]] = [{} for _ in range(n)]
        self._ati.channels(table, wrench, invalid, counts)
        for s, reading in enumerate(self.readings):
            if not isinstance(reading, AtiReading):
                wrench[:, s], invalid[:, s], counts[s] = reading.channels(table)
        return wrench, invalid, counts

    def classify(self, frames: FrameArray) -> np.ndarray:
        """Code per frame: a kind index (>= 0) or FOREIGN, WRONG_LENGTH, PROTOCOL, REQUEST, …"""
        n = len(frames)
        codes = np.full(n, FOREIGN, dtype=np.int64)
        if n == 0:
            return codes
        keys = (frames.ident.astype(np.uint64) << np.uint64(8)) | frames.dlc.astype(np.uint64)
        pos = np.minimum(np.searchsorted(self._keys, keys), len(self._keys) - 1)
        hit = self._keys[pos] == keys
        codes[hit] = self._codes[pos[hit]]
        rest = ~hit
        if rest.any():  # (a live desk's frames are all its own: no set lookups then)
            codes[rest & np.isin(frames.ident, self._data_ids)] = WRONG_LENGTH
            codes[rest & np.isin(frames.ident, self._protocol_ids)] = PROTOCOL
        flagged = (frames.flags & (REMOTE | ERROR)) != 0
        if flagged.any():
            codes[(frames.flags & REMOTE) != 0] = REMOTE_FRAME
            codes[(frames.flags & ERROR) != 0] = ERROR_FRAME
        return codes


def _lookup_key(ident: int, length: int) -> int:
    return (int(ident) << 8) | int(length)


def build_decoding(
    config: CanConfig,
    profile: DeskProfile,
    calibrations: dict[str, ati.AtiCalibration] | None = None,
) -> DeskDecoding:
    """Frame kinds and sensor readings for ``profile``; ATI boards need a calibration each
    (from the profile, or ``calibrations`` read from the bus or a capture)."""
    calibrations = calibrations or {}
    builder = _DecodingBuilder(config)
    for index, (name, sensor) in enumerate(config.groups()):  # sensors, then accelerometer
        if isinstance(sensor, AtiSensor):
            cal = sensor.calibration or calibrations.get(name)
            if cal is None:
                raise ConfigError(
                    config.where,
                    f"ATI sensor `{name}` (base 0x{sensor.base:02X}) has no calibration: it is "
                    "read from the bus at start, taken from the replies in a capture, or given "
                    "as `calibration` in the profile",
                )
            builder.add_ati(index, name, sensor, cal)
        else:
            assert isinstance(sensor, SignalSensor)
            builder.add_signals(index, name, sensor)
    return builder.decoding()


class _DecodingBuilder:
    """The frame kinds, field-table columns and readings of a desk, group by group."""

    def __init__(self, config: CanConfig) -> None:
        self.config = config
        self.kinds: list[FrameKind] = []
        self.readings: list[SensorReading] = []
        self.request_sensor: dict[int, int] = {}
        self.protocol: set[int] = set()
        self.second_halves: dict[int, int] = {}
        self.column = 0  # the next free column of the field table
        # database messages may carry several sensors' signals: one kind per message
        self.message_fields: dict[str, list[tuple[int, SignalLayout]]] = {}
        self.message_sensors: dict[str, list[int]] = {}
        self.message_counter: dict[str, SignalLayout] = {}

    def add_ati(self, index: int, name: str, sensor: AtiSensor, cal: ati.AtiCalibration) -> None:
        """An ATI board: its two sample frames (gauges 0x0, then 0x1), the poll that asks
        for them, the rest of its identifiers as protocol traffic."""
        first = self.column
        self.column += 7
        gauges_a = ati.frame_id(sensor.base, ati.OP_GAUGES_A)
        gauges_b = ati.frame_id(sensor.base, ati.OP_GAUGES_B)
        self.kinds.append(
            FrameKind(
                f"{name} gauges 0x0",
                gauges_a,
                ati.GAUGES_A_LENGTH,
                np.arange(first, first + 4),
                ati.decode_gauges_a,
                None,
                (index,),
            )
        )
        self.kinds.append(
            FrameKind(
                f"{name} gauges 0x1",
                gauges_b,
                ati.GAUGES_B_LENGTH,
                np.arange(first + 4, first + 7),
                ati.decode_gauges_b,
                None,
                (index,),
            )
        )
        self.second_halves[len(self.kinds) - 1] = len(self.kinds) - 2
        self.request_sensor[gauges_a] = index
        self.protocol |= ati.ati_frame_ids(sensor.base) - {gauges_a, gauges_b}
        self.readings.append(AtiReading(name, first, cal))

    def add_signals(self, index: int, name: str, sensor: SignalSensor) -> None:
        """A sensor (or accelerometer) of database signals: a column per axis and status
        signal, filled by the kind of the message that carries it."""
        axis_columns: dict[int, int] = {}
        status_columns: list[tuple[str, int]] = []
        for axis, ref in sensor.axes.items():
            axis_columns[AXES.index(axis)] = self.column
            self._add_field(ref)
            self.message_sensors.setdefault(ref.message, []).append(index)
        for ref in sensor.status:
            status_columns.append((str(ref), self.column))
            self._add_field(ref)
        for ref in sensor.counters:
            self.message_counter[ref.message] = _layout(self.config, ref)
        self.readings.append(SignalReading(name, axis_columns, status_columns))

    def _add_field(self, ref: SignalRef) -> None:
        fields = self.message_fields.setdefault(ref.message, [])
        fields.append((self.column, _layout(self.config, ref)))
        self.column += 1

    def decoding(self) -> DeskDecoding:
        """The decoding: a kind per database message, after the ATI boards' kinds."""
        kinds = list(self.kinds)
        for message_name, slots in self.message_fields.items():
            message = self.config.database.get_message_by_name(message_name)
            ident = int(message.frame_id) | (int(EXTENDED) if message.is_extended_frame else 0)
            kinds.append(
                FrameKind(
                    message_name,
                    ident,
                    int(message.length),
                    np.array([c for c, _ in slots]),
                    _signal_decoder([layout for _, layout in slots]),
                    self.message_counter.get(message_name),
                    tuple(sorted(set(self.message_sensors.get(message_name, [])))),
                )
            )
        modulus = None
        if kinds and all(k.counter is not None for k in kinds):
            modulus = 1 << kinds[0].counter.length  # type: ignore[union-attr]
        return DeskDecoding(
            kinds,
            self.readings,
            self.column,
            self.request_sensor,
            frozenset(self.protocol),
            modulus,
            self.second_halves,
            len(self.config.accelerometers),
        )


def _layout(config: CanConfig, ref: object) -> SignalLayout:
    message = config.database.get_message_by_name(ref.message)  # type: ignore[attr-defined]
    return SignalLayout.from_cantools(message, message.get_signal_by_name(ref.signal))  # type: ignore[attr-defined]


def _signal_decoder(layouts: list[SignalLayout]) -> Callable[[np.ndarray], np.ndarray]:
    def decode(data: np.ndarray) -> np.ndarray:
        words = frame_words(data)
        out = np.empty((len(data), len(layouts)))
        for i, layout in enumerate(layouts):
            out[:, i] = layout.decode(words)
        return out

    return decode
