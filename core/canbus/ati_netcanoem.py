"""The ATI NETCANOEM six-axis F/T protocol (ATI manual 9610-05-1030-04, §7 and §10).

Facts from that manual (docs/can.md restates them). Identifiers are ``(base << 4) | opcode``;
all data big-endian; a reply differs from its request by its length. A sample is two frames:
opcode 0x0 (8 bytes: status, sg0, sg2, sg4) and opcode 0x1 (6 bytes: sg1, sg3, sg5). The
calibration matrix (opcode 0x2, one row per request, three reply frames), the counts per unit
(0x7) and the units (0x8) turn gauges into forces and torques::

    [Fx Fy Fz] = Matrix[0:3] @ gauges / counts_per_force
    [Tx Ty Tz] = Matrix[3:6] @ gauges / counts_per_torque

Everything here is vectorised over frames; the emulator uses the encoders.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field

import numpy as np

OP_GAUGES_A = 0x0  # request (no data) and first reply frame
OP_GAUGES_B = 0x1
OP_CAL_ROW = 0x2  # request 1 byte row; replies on 0x2, 0x3, 0x4
OP_SERIAL = 0x5
OP_ACTIVE_CAL = 0x6
OP_COUNTS = 0x7
OP_UNITS = 0x8
OP_ADC = 0x9
OP_RESET = 0xC
OP_SET_BASE = 0xD
OP_SET_BAUD = 0xE
OP_FIRMWARE = 0xF

DEFAULT_BASE = 0x20
GAUGES_A_LENGTH = 8
GAUGES_B_LENGTH = 6

# unit code -> (name, factor to N or N·m)
FORCE_UNITS = {
    1: ("lbf", 4.4482216152605),
    2: ("N", 1.0),
    3: ("klbf", 4448.2216152605),
    4: ("kN", 1000.0),
    5: ("kgf", 9.80665),
    6: ("gf", 0.00980665),
}
TORQUE_UNITS = {
    1: ("lbf-in", 0.1129848290276167),
    2: ("lbf-ft", 1.3558179483314004),
    3: ("N-m", 1.0),
    4: ("N-mm", 0.001),
    5: ("kgf-cm", 0.0980665),
    6: ("kN-m", 1000.0),
}
_FORCE_FACTOR = {name: f for name, f in FORCE_UNITS.values()}
_TORQUE_FACTOR = {name: f for name, f in TORQUE_UNITS.values()}

# status word: after a critical error the board keeps sending, the receiver must flag it
STATUS_BITS = {
    0: "watchdog reset",
    1: "DAC/ADC check",
    2: "DAC/ADC check",
    3: "analog ground",
    4: "supply",
    5: "supply",
    6: "bad active calibration",
    7: "EEPROM",
    8: "configuration invalid, defaults used",
    11: "temperature",
    12: "temperature",
    14: "CAN bus error seen",
    15: "any error",
}
CRITICAL_BITS = (1, 2, 3, 4, 5, 6, 7, 11, 12)
CRITICAL_MASK = sum(1 << b for b in CRITICAL_BITS)


def frame_bits(length: int) -> int:
    """Bits a CAN 2.0A data frame of ``length`` bytes takes on the wire: 44 + 8 × length,
    3 of interframe space, and at worst one stuff bit per 4 of the 34 + 8 × length stuffed
    bits (Bosch CAN 2.0 part A)."""
    return 47 + 8 * length + (33 + 8 * length) // 4


# a polled sample: the poll (no data), then the replies of 8 and 6 bytes: 305 bits
SAMPLE_BITS = frame_bits(0) + frame_bits(GAUGES_A_LENGTH) + frame_bits(GAUGES_B_LENGTH)


def max_poll_rate(boards: int, bitrate: float) -> float:
    """Samples per second a bus of ``bitrate`` carries for ``boards`` polled boards (no other
    traffic): 250 kbit/s, one board ~820/s; 1 Mbit/s, four boards ~820/s."""
    return bitrate / (max(boards, 1) * SAMPLE_BITS)


def frame_id(base: int, opcode: int) -> int:
    """The 11-bit identifier of ``opcode`` on the board at ``base``."""
    return ((base & 0x7F) << 4) | (opcode & 0xF)


def ati_frame_ids(base: int) -> set[int]:
    """Every identifier a board at ``base`` uses."""
    return {frame_id(base, op) for op in range(16)}


def status_bit_name(bit: int) -> str:
    kind = "critical" if bit in CRITICAL_BITS else "not critical"
    return f"bit {bit} ({STATUS_BITS.get(bit, 'undocumented')}, {kind})"


@dataclass(frozen=True)
class AtiCalibration:
    """Calibration matrix (rows Fx Fy Fz Tx Ty Tz over gauges sg0…sg5), counts per unit, units."""

    matrix: np.ndarray  # (6, 6)
    counts_per_force: float = 1e6
    counts_per_torque: float = 1e6
    force_unit: str = "N"
    torque_unit: str = "N-m"
    serial: str = field(default="", compare=False)

    def gauge_map(self) -> np.ndarray:
        """(6, 6) G with [F (N); T (N·m)] = G @ gauges: matrix, counts and units in one."""
        scale = np.array(
            [_FORCE_FACTOR[self.force_unit] / self.counts_per_force] * 3
            + [_TORQUE_FACTOR[self.torque_unit] / self.counts_per_torque] * 3
        )
        return np.asarray(self.matrix, dtype=float) * scale[:, None]

    def gauges_for(self, wrench: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`gauge_map` for (k, 6) wrenches: int gauges, clipped to int16."""
        gauges = np.linalg.solve(self.gauge_map(), np.asarray(wrench, dtype=float).T).T
        return np.clip(np.rint(gauges), -32768, 32767).astype(np.int64)


def example_calibration(seed: int = 0) -> AtiCalibration:
    """A plausible calibration for emulated boards: a strain-gauge matrix with cross-talk.

    Scaled so that the paper's sensor ratings (±150, ±150, ±300 N, ±4 N·m), all at once, stay
    inside the int16 gauges: a gauge count is worth about 0.03 N and 0.0006 N·m, finer than
    the paper's sensors' resolution of 1/2000 of the rated range.
    """
    rng = np.random.default_rng(1000 + seed)
    # a typical six-gauge layout: forces from gauge differences, torques from sums
    base = np.array(
        [
            [0.0, 0.0, -1.0, 1.0, 1.0, -1.0],
            [1.2, -0.6, -0.6, 1.2, -0.6, -0.6],
            [1.0, 1.0, 1.0, 1.0, 1.0, 1.0],
            [0.0, 1.0, 1.0, 0.0, -1.0, -1.0],
            [-1.2, 0.6, 0.6, 1.2, -0.6, -0.6],
            [1.0, -1.0, 1.0, -1.0, 1.0, -1.0],
        ]
    )
    matrix = base * (1.0 + 0.05 * rng.standard_normal((6, 6))) + 0.02 * rng.standard_normal((6, 6))
    matrix[:3] *= 13000.0  # force counts per gauge count, at 1e6 counts per N
    matrix[3:] *= 300.0  # torque counts per gauge count, at 1e6 counts per N·m
    return AtiCalibration(
        matrix=matrix.astype(np.float32).astype(float), serial=f"FT{29000 + seed:05d}"
    )


# --- sample frames, vectorised ----------------------------------------------------------------


def decode_gauges_a(data: np.ndarray) -> np.ndarray:
    """(n, 8) uint8 frames of opcode 0x0 -> (n, 4) float: status, sg0, sg2, sg4."""
    packed = np.ascontiguousarray(data[:, :8])
    out = packed.view(">i2").reshape(-1, 4).astype(np.float64)
    out[:, 0] = packed.view(">u2").reshape(-1, 4)[:, 0]
    return out


def decode_gauges_b(data: np.ndarray) -> np.ndarray:
    """(n, 8) uint8 frames of opcode 0x1 (6 bytes used) -> (n, 3) float: sg1, sg3, sg5."""
    words = np.ascontiguousarray(data[:, :6]).view(">i2").reshape(-1, 3)
    return words.astype(np.float64)


def encode_gauge_frames(status: np.ndarray, gauges: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(k,) status and (k, 6) gauges -> frames of opcode 0x0 (k, 8) and 0x1 (k, 8, 6 used)."""
    k = len(gauges)
    g = np.asarray(gauges).astype(">i2")
    a = np.empty((k, 4), dtype=">u2")
    a[:, 0] = np.asarray(status, dtype=np.uint16)
    a[:, 1:] = g[:, [0, 2, 4]].view(">u2")
    b = np.zeros((k, 4), dtype=">i2")
    b[:, :3] = g[:, [1, 3, 5]]
    return a.view(np.uint8).reshape(k, 8), b.view(np.uint8).reshape(k, 8)


def gauges_from_fields(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(k, 3) sg0 sg2 sg4 and (k, 3) sg1 sg3 sg5 -> (k, 6) sg0 … sg5."""
    out = np.empty((len(a), 6))
    out[:, 0::2] = a
    out[:, 1::2] = b
    return out


# --- requests and calibration replies ---------------------------------------------------------


def request(base: int, opcode: int, payload: bytes = b"") -> tuple[int, bytes]:
    """A request frame: identifier and data."""
    return frame_id(base, opcode), payload


def calibration_requests(base: int, slot: int | None = None) -> list[tuple[int, bytes]]:
    """What a host sends after power-up to learn how to convert gauges."""
    out = [request(base, OP_ACTIVE_CAL, bytes([slot]))] if slot is not None else []
    out += [request(base, OP_CAL_ROW, bytes([row])) for row in range(6)]
    out += [request(base, OP_COUNTS), request(base, OP_UNITS), request(base, OP_SERIAL)]
    return out


def replies(base: int, ident: int, payload: bytes, cal: AtiCalibration) -> list[tuple[int, bytes]]:
    """A board's reply to a non-sample request (the emulator's side of the protocol)."""
    if ident >> 4 != base or len(payload) > 1:
        return []
    opcode = ident & 0xF
    if opcode == OP_CAL_ROW and len(payload) == 1 and payload[0] < 6:
        row = np.asarray(cal.matrix[payload[0]], dtype=">f4")
        return [
            (frame_id(base, OP_CAL_ROW + i), row[2 * i : 2 * i + 2].tobytes()) for i in range(3)
        ]
    if opcode == OP_COUNTS and not payload:
        return [(ident, struct.pack(">ii", int(cal.counts_per_force), int(cal.counts_per_torque)))]
    if opcode == OP_UNITS and not payload:
        force = next(c for c, (n, _) in FORCE_UNITS.items() if n == cal.force_unit)
        torque = next(c for c, (n, _) in TORQUE_UNITS.items() if n == cal.torque_unit)
        return [(ident, bytes([force, torque]))]
    if opcode == OP_SERIAL and not payload:
        return [(ident, cal.serial.encode("ascii")[:8].ljust(8, b" "))]
    if opcode == OP_ACTIVE_CAL and len(payload) == 1:
        return [(ident, payload)]
    if opcode == OP_FIRMWARE and not payload:
        return [(ident, struct.pack(">HHH", 2, 1, 0))]
    return []


class CalibrationCollector:
    """Collects calibration replies of one board, from a live bus or a capture.

    A row reply does not say which row it is: it is the row of the latest row request, so a
    capture must hold the requests too (hapticdesk's own logs do).
    """

    def __init__(self, base: int) -> None:
        self.base = base
        self.rows: dict[int, np.ndarray] = {}
        self.counts: tuple[float, float] | None = None
        self.units: tuple[str, str] | None = None
        self.serial = ""
        self._row: int | None = None
        self._parts: dict[int, bytes] = {}
        self.unpaired_rows = 0  # row replies seen without a request before them

    def feed(self, ident: int, data: bytes) -> None:
        """One frame of any kind; only this board's calibration traffic is used."""
        if ident >> 4 != self.base or ident > 0x7FF:
            return
        opcode = ident & 0xF
        if opcode == OP_CAL_ROW and len(data) == 1:
            self._row, self._parts = data[0], {}
        elif OP_CAL_ROW <= opcode <= OP_CAL_ROW + 2 and len(data) == 8:
            if self._row is None:
                self.unpaired_rows += 1
                return
            self._parts[opcode - OP_CAL_ROW] = data
            if len(self._parts) == 3 and self._row < 6:
                raw = b"".join(self._parts[i] for i in range(3))
                self.rows[self._row] = np.frombuffer(raw, dtype=">f4").astype(float)
                self._row, self._parts = None, {}
        elif opcode == OP_COUNTS and len(data) == 8:
            force, torque = struct.unpack(">ii", data)
            if force > 0 and torque > 0:
                self.counts = (float(force), float(torque))
        elif opcode == OP_UNITS and len(data) == 2:
            if data[0] in FORCE_UNITS and data[1] in TORQUE_UNITS:
                self.units = (FORCE_UNITS[data[0]][0], TORQUE_UNITS[data[1]][0])
        elif opcode == OP_SERIAL and len(data) == 8:
            self.serial = data.decode("ascii", "replace").strip()

    def missing(self) -> list[str]:
        """What is still needed, in words; empty when :meth:`calibration` can be built."""
        out = [f"matrix row {r}" for r in range(6) if r not in self.rows]
        if self.counts is None:
            out.append("counts per unit (opcode 0x7)")
        return out

    def calibration(self) -> AtiCalibration | None:
        """The calibration, once every row and the counts are known (units default N, N·m)."""
        if self.missing():
            return None
        assert self.counts is not None
        matrix = np.stack([self.rows[r] for r in range(6)])
        if not np.all(np.isfinite(matrix)) or np.linalg.matrix_rank(matrix) < 6:
            return None
        force_unit, torque_unit = self.units or ("N", "N-m")
        return AtiCalibration(
            matrix, self.counts[0], self.counts[1], force_unit, torque_unit, self.serial
        )
