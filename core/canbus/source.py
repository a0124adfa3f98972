"""The live CAN source: a python-can bus in, wrench blocks out.

``open_can_source("can:virtual:desk", profile)`` opens any interface python-can offers
(socketcan, pcan, kvaser, slcan, virtual, udp_multicast, …); the profile's ``can:`` section
gives the defaults (interface, channel, bitrate, ``bus_options``) and the decoding. At start it
reads each ATI board's calibration from the bus (unless the profile gives it) and then polls
the boards at the profile's sample rate from a thread of its own; database desks just stream.

The bus may fail: a python-can error or a bus-off error frame closes the bus and opens it
again every ``RECONNECT_INTERVAL_S`` until ``reconnect_timeout_s`` has passed, then the source
stops with a clear error. A sensor that goes silent is reported by the assembler
(:mod:`hapticdesk.canbus.assembler`) and, with ``silent_sensor: stop``, ends the source after
the samples before it were given out.
"""

from __future__ import annotations

import collections
import logging
import threading
import time
from collections.abc import Callable
from typing import Any

from hapticdesk.canbus import ati_netcanoem as ati
from hapticdesk.canbus.assembler import NOTICES_KEPT, AssembledBlock, FrameAssembler
from hapticdesk.canbus.config import CanConfig
from hapticdesk.canbus.config_reader import can_config
from hapticdesk.canbus.decoding import build_decoding
from hapticdesk.canbus.frames import FrameArray
from hapticdesk.canbus.stats import CanNotice, CanStats
from hapticdesk.errors import ConfigError
from hapticdesk.files.profile import DeskProfile
from hapticdesk.runtime.source import Source, WrenchBlock

log = logging.getLogger("hapticdesk.canbus.source")

RECONNECT_INTERVAL_S = 0.2
BLOCK_S = 0.01  # gather frames this long before assembling them
CAN_ERR_BUSOFF = 0x40  # SocketCAN error class bit in an error frame's identifier


def bus_cannot_open(interface: str, channel: str | None, err: Exception) -> str:
    """Why python-can could not open ``interface`` ``channel``, for a message (a live source
    and ``emulate`` say it alike). An interface's own bug when its driver library is missing
    (python-can's kvaser raises NameError: canGetNumberOfChannels) is as much a bus that
    cannot be opened, said as such."""
    import can

    said = f"cannot open CAN interface {interface!r} channel {channel!r}: "
    if isinstance(err, (can.CanError, OSError, ValueError, ImportError, TypeError)):
        return said + str(err)
    return (
        said + f"python-can failed with {type(err).__name__}: {err} (is the interface's driver "
        "library installed?)"
    )


class CanSourceError(ConfigError):
    """The bus could not be opened, or was lost and did not come back."""


def parse_spec(spec: str, config: CanConfig | None) -> tuple[str, str | None]:
    """``can:INTERFACE:CHANNEL`` (or ``INTERFACE:CHANNEL``, or ``can`` for the profile's)."""
    text = spec[4:] if spec.startswith("can:") else ("" if spec == "can" else spec)
    interface, _, channel = text.partition(":")
    interface = interface or (config.interface if config else None) or ""
    if not interface:
        raise CanSourceError(
            spec,
            "no CAN interface: write --source can:INTERFACE:CHANNEL (e.g. can:socketcan:can0, "
            "can:virtual:desk) or give `interface` and `channel` in the profile's `can:`",
        )
    return interface, channel or (config.channel if config else None)


class CanSource(Source):
    """Samples of a desk read from a live CAN bus. See the module docstring."""

    def __init__(
        self,
        spec: str,
        profile: DeskProfile,
        *,
        bitrate: int | None = None,
        bus_options: dict[str, Any] | None = None,
        frame_sink: Callable[[list[Any]], None] | None = None,
        bus_factory: Callable[..., Any] | None = None,
        calibration_timeout_s: float = 0.5,
    ) -> None:
        self.spec = spec
        self.profile = profile
        self.config = can_config(profile)
        self.interface, self.channel = parse_spec(spec, self.config)
        self.bus_kwargs: dict[str, Any] = dict(self.config.bus_options)
        if bitrate or self.config.bitrate:
            self.bus_kwargs["bitrate"] = bitrate or self.config.bitrate
        self.bus_kwargs.update(bus_options or {})
        self.frame_sink = frame_sink
        self._bus_factory = bus_factory
        # the most recent ones: a bus that keeps failing must not grow this for the whole run
        self.notices: collections.deque[CanNotice] = collections.deque(maxlen=NOTICES_KEPT)
        self.reconnects = 0
        self._lock = threading.Lock()  # guards self._bus between the poller and the reader
        self._polls: collections.deque[Any] = collections.deque()  # sent, not yet assembled
        self._poller: threading.Thread | None = None
        # (the base last: nothing to close when the spec or the section is wrong)
        super().__init__(
            profile.sensor_names, profile.sample_rate_hz, channel_count=profile.channel_count
        )
        self._bus: Any = None
        self._stop_after: BaseException | None = None  # a stop, raised after its samples
        self._quiet_since: float | None = None  # since when no frame came (None: not reading)
        self._quiet_told = False
        try:
            self._bus = self._open_bus()
            calibrations = self._read_calibrations(calibration_timeout_s)
            decoding = build_decoding(self.config, profile, calibrations)
        except BaseException:
            self.close()
            raise
        self.calibrations = calibrations
        self.assembler = FrameAssembler(
            decoding,
            profile.sample_rate_hz,
            assemble=self.config.assemble,
            frame_gap_s=self.config.frame_gap_s,
            silent_timeout_s=self.config.silent_timeout_s,
            silent_sensor=self.config.silent_sensor,
            where=spec,
        )
        self._plan_polls()
        self._check_bus_capacity()

    def _plan_polls(self) -> None:
        """The ATI boards' poll frames, and the frame that ends a round of their replies."""
        self._poll_ids = [
            ati.frame_id(s.base, ati.OP_GAUGES_A) for s in self.config.ati_sensors.values()
        ]
        # the last reply frame of a poll round (the last board's second frame, the lowest
        # priority of them): the reader tells the poller when it came
        self._round_end_id = (
            ati.frame_id(list(self.config.ati_sensors.values())[-1].base, ati.OP_GAUGES_B)
            if self._poll_ids
            else None
        )
        self._round_answered = threading.Event()
        self._poll_id_set = frozenset(self._poll_ids)

    @property
    def stats(self) -> CanStats:
        return self.assembler.stats

    def summary(self) -> list[str]:
        return [f"CAN {self.interface}:{self.channel}: {line}" for line in self.stats.summary()]

    # --- bus ----------------------------------------------------------------------------

    def _open_bus(self) -> Any:
        import can  # lazily: only a CAN source needs python-can

        factory = self._bus_factory or can.Bus
        try:
            return factory(interface=self.interface, channel=self.channel, **self.bus_kwargs)
        except Exception as err:
            raise CanSourceError(
                self.spec, bus_cannot_open(self.interface, self.channel, err)
            ) from None

    def _shutdown_bus(self) -> None:
        with self._lock:
            bus, self._bus = self._bus, None
        if bus is not None:
            try:
                bus.shutdown()
            except Exception as err:  # a broken driver must not hide why we are closing
                log.debug("shutting the bus down failed: %s", err)

    def _send(self, ident: int, data: bytes, *, poll: bool = False) -> None:
        """Send a request. Polls are queued for the reader first (so a reply can never be
        assembled before its poll); other requests go to the frame sink at once."""
        import can

        msg = can.Message(arbitration_id=ident, data=data, is_extended_id=False)
        with self._lock:
            if self._bus is None:
                raise can.CanOperationError("bus is closed")
            msg.timestamp, msg.is_rx = time.time(), False
            if poll:
                self._polls.append(msg)
            self._bus.send(msg)
        if not poll and self.frame_sink is not None:
            self.frame_sink([msg])

    def _reconnect(self, reason: str) -> None:
        """Close and reopen the bus until it works or ``reconnect_timeout_s`` passes."""
        self._notice(
            "bus", f"CAN bus {self.interface}:{self.channel} failed ({reason}); reconnecting"
        )
        self._shutdown_bus()
        deadline = time.monotonic() + self.config.reconnect_timeout_s
        while not self._closing.is_set():
            try:
                bus = self._open_bus()
            except CanSourceError as err:
                if time.monotonic() >= deadline:
                    raise CanSourceError(
                        self.spec,
                        f"CAN bus lost ({reason}) and not back within "
                        f"{self.config.reconnect_timeout_s:g} s: {err.message}",
                    ) from None
                self._closing.wait(RECONNECT_INTERVAL_S)
                continue
            with self._lock:
                self._bus = bus
            self.reconnects += 1
            self._notice("bus", f"CAN bus {self.interface}:{self.channel} is back")
            return

    def _check_bus_capacity(self) -> None:
        """Say at start when the boards cannot be polled at the desk's rate on this bus."""
        bitrate = self.bus_kwargs.get("bitrate")
        if not self._poll_ids or not bitrate or self.interface in ("virtual", "udp_multicast"):
            return  # no bit rate to run out of (software buses are bound by the host)
        most = ati.max_poll_rate(len(self._poll_ids), float(bitrate))
        if self.sample_rate_hz > most:
            self._notice(
                "capacity",
                f"{len(self._poll_ids)} ATI board(s) polled at {self.sample_rate_hz:g} Hz need "
                f"{len(self._poll_ids) * ati.SAMPLE_BITS * self.sample_rate_hz / 1000:.0f} "
                f"kbit/s (a poll and two replies, {ati.SAMPLE_BITS} bits a board); the bus "
                f"runs at {float(bitrate) / 1000:g} kbit/s and carries at most ~{most:.0f} "
                "samples/s: lower `sample_rate_hz` or raise the bit rate (board opcode 0xE)",
            )

    def _notice(self, kind: str, message: str) -> None:
        log.warning("%s", message)
        t = self.assembler.last_sample_time if hasattr(self, "assembler") else None
        self.notices.append(CanNotice(t or 0.0, kind, message))

    # --- ATI start-up and polling ---------------------------------------------------------

    def _read_calibrations(self, timeout_s: float) -> dict[str, ati.AtiCalibration]:
        out: dict[str, ati.AtiCalibration] = {}
        for name, sensor in self.config.ati_sensors.items():
            if sensor.calibration is not None and sensor.slot is None:
                continue
            collector = ati.CalibrationCollector(sensor.base)
            for ident, payload in ati.calibration_requests(sensor.base, sensor.slot):
                self._ask(collector, ident, payload, timeout_s, name, sensor.base)
            cal = collector.calibration()
            if sensor.calibration is not None:
                continue  # the profile's wins; we only selected the slot
            if cal is None:
                raise CanSourceError(
                    self.spec,
                    f"ATI sensor `{name}` (base 0x{sensor.base:02X}) gave no usable "
                    f"calibration ({', '.join(collector.missing()) or 'singular matrix'})",
                )
            log.info("ATI sensor %s: serial %s, units %s", name, cal.serial, collector.units)
            out[name] = cal
        return out

    def _ask(
        self,
        collector: ati.CalibrationCollector,
        ident: int,
        payload: bytes,
        timeout_s: float,
        name: str,
        base: int,
    ) -> None:
        """Send one request and feed replies to ``collector`` until the answer is in."""
        opcode = ident & 0xF
        for _attempt in range(3):
            collector.feed(ident, payload)  # replies are read against the request
            self._send(ident, payload)
            before = (len(collector.rows), collector.counts, collector.units, collector.serial)
            deadline = time.monotonic() + timeout_s
            while time.monotonic() < deadline:
                msg = self._bus.recv(timeout=max(0.0, deadline - time.monotonic()))
                if msg is None:
                    break
                if self.frame_sink is not None:
                    self.frame_sink([msg])
                if not msg.is_error_frame and not msg.is_extended_id:
                    collector.feed(msg.arbitration_id, bytes(msg.data))
                now = (len(collector.rows), collector.counts, collector.units, collector.serial)
                if now != before or (opcode == ati.OP_ACTIVE_CAL and msg.arbitration_id == ident):
                    return
            if opcode in (ati.OP_UNITS, ati.OP_SERIAL):
                return  # older firmware may not answer these; N and N·m are then assumed
        raise CanSourceError(
            self.spec,
            f"ATI sensor `{name}` (base 0x{base:02X}) did not answer request 0x{ident:03X} "
            f"within {timeout_s:g} s (3 tries); check power, wiring, bit rate and `base`, or "
            "give `calibration` in the profile",
        )

    def _poll(self) -> None:
        """Request one sample of every ATI board per period, on a deadline clock.

        A round is not sent before the previous one's replies came (or two periods after it
        was sent, for a board that missed its poll): polls that overrun their replies (a host
        thread that stalled, then caught up) would put two rounds' replies after the second
        poll, and void both samples. So a stall costs samples (counted as lost), never
        whole samples' data.
        """
        period = 1.0 / self.sample_rate_hz
        next_due = time.monotonic()
        while not self._closing.is_set():
            self._round_answered.clear()
            for ident in self._poll_ids:
                try:
                    self._send(ident, b"", poll=True)
                except Exception as err:  # the reader reconnects; keep the rhythm
                    log.debug("poll not sent: %s", err)
                    break
            sent_at = time.monotonic()
            next_due += period
            self._round_answered.wait(max(next_due, sent_at + period) + period - sent_at)
            wait = next_due - time.monotonic()
            if wait > 0:
                self._closing.wait(wait)
            elif wait < -period:
                next_due = time.monotonic()  # fell behind: skip, do not burst

    def _sent_polls(self) -> list[Any]:
        polls = []
        while self._polls:
            polls.append(self._polls.popleft())
        return polls

    # --- reading ------------------------------------------------------------------------

    def read_block(self) -> WrenchBlock | None:
        """The samples completed by the frames that came within ``BLOCK_S``; a lost bus is
        reconnected (what the assembler held is given out first)."""
        import can

        if self._stop_after is not None:  # (the samples before it were given out)
            raise self._stop_after
        if self._quiet_since is None:  # the first read: the quiet clock and the polls start
            self._quiet_since = time.monotonic()
            if self._poll_ids:
                self._poller = threading.Thread(target=self._poll, name="ati-poller", daemon=True)
                self._poller.start()
        try:
            batch = self._gather()
        except (can.CanError, OSError) as err:
            if self._closing.is_set():
                return None
            held = self._give(self.assembler.flush())
            self._reconnect(str(err))
            return held
        polls = self._sent_polls()
        if polls:  # in time order with what came back, for the assembler and the sink
            batch = sorted(batch + polls, key=lambda m: m.timestamp)
        if self.frame_sink is not None and batch:
            self.frame_sink(batch)
        if batch:
            self._quiet_since, self._quiet_told = time.monotonic(), False
            return self._give(self.assembler.push(FrameArray.from_messages(batch)))
        quiet_s = time.monotonic() - self._quiet_since
        if self._quiet_told or quiet_s <= self.config.silent_timeout_s:
            return WrenchBlock.empty()
        return self._quiet()

    def read_rest(self) -> WrenchBlock | None:
        return self._give(self.assembler.flush())  # closed: what is still waiting

    def _gather(self) -> list[Any]:
        """The frames that came within ``BLOCK_S`` (a python-can error if the bus failed)."""
        import can

        batch: list[Any] = []
        deadline = time.monotonic() + BLOCK_S
        while time.monotonic() < deadline and len(batch) < 5000:
            bus = self._bus
            if bus is None:
                raise can.CanOperationError("bus is closed")
            msg = bus.recv(timeout=max(0.0, deadline - time.monotonic()))
            if msg is None:
                break
            if msg.is_error_frame and msg.arbitration_id & CAN_ERR_BUSOFF:
                raise can.CanOperationError("bus-off")
            if msg.arbitration_id == self._round_end_id and len(msg.data):
                self._round_answered.set()
            if not msg.data and msg.arbitration_id in self._poll_id_set:
                # our own poll echoed back (udp_multicast loops them): it is taken from the
                # queue of sent polls, in order; twice would split samples
                continue
            batch.append(msg)
        return batch

    def _quiet(self) -> WrenchBlock:
        """No frame for ``silent_timeout_s``: said once per quiet stretch (or the end, with
        ``silent_sensor: stop``), after what the assembler held."""
        self._quiet_told = True
        held = self._give(self.assembler.flush())
        names = ", ".join(self.sensor_names)
        text = (
            f"no CAN frames on {self.interface}:{self.channel} for "
            f"{self.config.silent_timeout_s:g} s (sensors {names})"
        )
        if self.config.silent_sensor == "stop":
            self._stop_after = self._stop_after or CanSourceError(
                self.spec, text + "; stopping (`silent_sensor: stop`)"
            )
        else:
            self._notice("silent", text)
        return held

    def _give(self, block: AssembledBlock) -> WrenchBlock:
        """The assembled samples as a block; a stop it carries is raised at the next read."""
        self.notices.extend(block.notices)
        if block.stop is not None:
            self._stop_after = block.stop
        return WrenchBlock(block.t, block.wrench, accel=block.accel)

    def release(self) -> None:
        """Stop polling and release the bus."""
        if self._poller is not None and self._poller is not threading.current_thread():
            self._poller.join(timeout=1.0)
        self._shutdown_bus()


def open_can_source(spec: str, profile: DeskProfile, **options: Any) -> CanSource:
    """Open a live CAN source for ``profile``; ``spec`` is ``can:INTERFACE:CHANNEL``,
    ``INTERFACE:CHANNEL`` or ``can`` (the profile's). Options: ``bitrate``, ``bus_options``
    (extra python-can arguments), ``frame_sink`` (called with every list of received and sent
    python-can messages, e.g. a log writer), ``calibration_timeout_s``."""
    return CanSource(spec, profile, **options)
