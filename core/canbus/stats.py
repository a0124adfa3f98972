"""What the CAN side tells a user: counts of every frame the assembler saw (:class:`CanStats`,
its summary lines, CANopen's names for foreign traffic) and notices about the bus or a sensor."""

from __future__ import annotations

from dataclasses import dataclass, field

from hapticdesk.errors import ConfigError


@dataclass(frozen=True)
class CanNotice:
    """Something about the bus or a sensor a user should know: silent, back, bus, …"""

    t: float  # sample time, seconds
    kind: str
    message: str


class SensorSilentError(ConfigError):
    """A sensor stopped sending and the profile says ``silent_sensor: stop``."""


@dataclass
class CanStats:
    """Counts of everything the assembler saw, for the summary a user reads."""

    frames: int = 0
    data_frames: int = 0
    requests: int = 0
    protocol: int = 0
    error_frames: int = 0
    remote_frames: int = 0
    foreign: dict[int, int] = field(default_factory=dict)  # identifier -> frames
    wrong_length: dict[int, int] = field(default_factory=dict)  # identifier -> frames
    late: int = 0  # frames that came after their sample was given out
    duplicates: int = 0  # frames of a kind seen twice in one sample (both dropped)
    counter_mismatch: int = 0  # samples where one sensor's frames carried different counters
    lost_samples: int = 0  # samples skipped by the counter or the clock
    samples: int = 0
    incomplete: dict[str, int] = field(default_factory=dict)  # sensor -> samples with NaN
    #: sensor -> samples in which a missing frame's values were held from the sample before
    held: dict[str, int] = field(default_factory=dict)
    #: frames whose time is before an earlier frame's (a corrupt or merged log); their
    #: counters still place them
    time_back: int = 0
    invalid: dict[str, int] = field(default_factory=dict)  # sensor -> samples its status voided
    status: dict[str, dict[str, int]] = field(default_factory=dict)  # sensor -> bit -> samples

    def summary(self) -> list[str]:
        """Human-readable lines, only for what is not perfectly normal (plus the totals)."""
        lines = [f"{self.frames} frames, {self.samples} samples"]
        if self.foreign:
            n = sum(self.foreign.values())
            kinds: dict[str, int] = {}
            for ident, count in self.foreign.items():
                label = canopen_function(ident)
                kinds[label] = kinds.get(label, 0) + count
            shown = ", ".join(f"{k} {v}" for k, v in sorted(kinds.items(), key=lambda kv: -kv[1]))
            lines.append(f"ignored {n} frames of other traffic ({shown})")
        if self.wrong_length:
            shown = ", ".join(f"0x{i:03X}: {n}" for i, n in sorted(self.wrong_length.items()))
            lines.append(f"dropped frames of the wrong length ({shown})")
        for label, value in (
            ("frames came after their sample was given out (dropped)", self.late),
            ("frames doubled within one sample (dropped)", self.duplicates),
            ("samples whose frames carried different counters", self.counter_mismatch),
            ("samples lost (counter or clock jumped, or not polled in time)", self.lost_samples),
            ("error frames", self.error_frames),
            ("frames came with a time before an earlier frame's", self.time_back),
        ):
            if value:
                lines.append(f"{value} {label}")
        for name, n in self.incomplete.items():
            if n:
                # the estimator skips these samples, and a tare needs a quiet second of whole
                # ones: many of them show up downstream as "tare refused"
                share = 100.0 * n / max(self.samples, 1)
                lines.append(f"sensor {name}: {n} samples ({share:.1f} %) with missing data (NaN)")
        for name, n in self.held.items():
            if n:
                share = 100.0 * n / max(self.samples, 1)
                lines.append(
                    f"sensor {name}: {n} samples ({share:.1f} %) lacked a frame; its values "
                    "were held from the sample before"
                )
        for name, n in self.invalid.items():
            if n:
                lines.append(f"sensor {name}: {n} samples voided by its status")
        for name, bits in self.status.items():
            for bit, n in bits.items():
                lines.append(f"sensor {name}: status {bit} in {n} samples")
        return lines


def canopen_function(ident: int) -> str:
    """What an 11-bit identifier is in CANopen's predefined connection set."""
    if ident & 0x8000_0000:
        return "extended id"
    if ident == 0x000:
        return "CANopen NMT"
    if ident == 0x080:
        return "CANopen SYNC"
    if 0x081 <= ident <= 0x0FF:
        return "CANopen EMCY"
    if ident == 0x100:
        return "CANopen TIME"
    if 0x181 <= ident <= 0x57F:
        return "CANopen PDO"
    if 0x581 <= ident <= 0x67F:
        return "CANopen SDO"
    if 0x701 <= ident <= 0x77F:
        return "CANopen heartbeat"
    return f"id 0x{ident:03X}"


def silence_message(name: str, timeout_s: float, last_t: float, late_frames: int) -> str:
    """What a user is told when sensor ``name`` has given no usable frame for ``timeout_s``:
    silent, or sending frames that all came too late to join a sample."""
    if late_frames:
        return (
            f"sensor {name} sends, but none of its frames fit the other sensors' samples since "
            f"t={last_t:.3f} s ({late_frames} dropped as late: a counter that restarted, or "
            "counters not shared; see `assemble`)"
        )
    return f"sensor {name} has sent nothing for {timeout_s:g} s (last data at t={last_t:.3f} s)"
