"""The live CAN source: a python-can bus in, wrench blocks out.

``open_can_source("can:virtual:desk", profile)`` opens any interface python-can offers
(socketcan, pcan, kvaser, slcan, virtual, udp_multicast, …); the profile's ``can:`` section
gives the defaults (interface, channel, bitrate, ``bus_options``) and the decoding. At start it
reads each ATI board's calibration from the bus (unless the profile gives it) and then polls
the boards at the profile's sample rate from a thread of its own, which also reads the bus
(ati_bus.py): the reader takes what it sent and read every ``BLOCK_S``. Database desks just
stream, read on the reader's thread. Which bus a spec names, and the error a lost bus
raises: bus_spec.py.

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

from hapticdesk.canbus.assembler import NOTICES_KEPT, AssembledBlock, FrameAssembler
from hapticdesk.canbus.ati_bus import AtiBoards
from hapticdesk.canbus.bus_spec import CanSourceError, bus_cannot_open, parse_spec
from hapticdesk.canbus.config import CanConfig
from hapticdesk.canbus.config_reader import can_config
from hapticdesk.canbus.decoding import DeskDecoding, build_decoding
from hapticdesk.canbus.frames import FrameArray
from hapticdesk.canbus.outgoing import OutgoingMessage
from hapticdesk.canbus.stats import CanNotice, CanStats
from hapticdesk.files.profile import DeskProfile
from hapticdesk.runtime.source import Source, WrenchBlock

log = logging.getLogger("hapticdesk.canbus.source")

RECONNECT_INTERVAL_S = 0.2
BLOCK_S = 0.01  # gather frames this long before assembling them
MAX_BLOCK_FRAMES = 5000  # at most this many frames a block (a bus flooding faster waits)
CAN_ERR_BUSOFF = 0x40  # SocketCAN error class bit in an error frame's identifier


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
        self.bus_kwargs = _bus_arguments(self.config, bitrate, bus_options)
        self.frame_sink = frame_sink
        self._bus_factory = bus_factory
        # the most recent ones: a bus that keeps failing must not grow this for the whole run
        self.notices: collections.deque[CanNotice] = collections.deque(maxlen=NOTICES_KEPT)
        self.reconnects = 0
        self._lock = threading.Lock()  # guards self._bus between the poller and the reader
        # with ATI boards, the poller thread receives too: the polls it sent and the frames
        # it read, in the order they happened, wait here for the reader
        self._inbox: collections.deque[Any] = collections.deque()
        self._failure: tuple[Any, BaseException] | None = None  # (bus, error) the poller met
        # (the base last: nothing to close when the spec or the section is wrong)
        super().__init__(
            profile.sensor_names, profile.sample_rate_hz, channel_count=profile.channel_count
        )
        self._bus: Any = None
        self._stop_after: BaseException | None = None  # a stop, raised after its samples
        self._quiet_since: float | None = None  # since when no frame came (None: not reading)
        self._quiet_told = False
        self._block_due = 0.0  # when the block being gathered ends (monotonic)
        self.ati_boards = AtiBoards(
            self.config.ati_sensors,
            self.sample_rate_hz,
            spec=spec,
            send_poll=lambda ident: self._send(ident, b"", poll=True),
            receive=self._receive,
            closing=self._closing,
        )
        try:
            decoding = self._open_and_calibrate(calibration_timeout_s)
        except BaseException:
            self.close()
            raise
        self.assembler = self._assembler(decoding)
        capacity = self.ati_boards.capacity_notice(self.bus_kwargs.get("bitrate"), self.interface)
        if capacity is not None:
            self._notice("capacity", capacity)

    def _open_and_calibrate(self, timeout_s: float) -> DeskDecoding:
        """Open the bus and read the ATI boards' calibrations: the desk's decoding."""
        self._bus = self._open_bus()
        self.calibrations = self.ati_boards.read_calibrations(
            self._send,
            lambda wait_s: self._bus.recv(timeout=wait_s),
            self.frame_sink,
            timeout_s,
        )
        return build_decoding(self.config, self.profile, self.calibrations)

    def _assembler(self, decoding: DeskDecoding) -> FrameAssembler:
        return FrameAssembler(
            decoding,
            self.profile.sample_rate_hz,
            assemble=self.config.assemble,
            frame_gap_s=self.config.frame_gap_s,
            silent_timeout_s=self.config.silent_timeout_s,
            silent_sensor=self.config.silent_sensor,
            where=self.spec,
            count_lost=not self.ati_boards.poll_ids,  # the poller counts its skipped rounds
        )

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

        # (cheap to deep-copy: the virtual bus copies every message it sends)
        msg = OutgoingMessage(arbitration_id=ident, data=data, is_extended_id=False)
        with self._lock:
            if self._bus is None:
                raise can.CanOperationError("bus is closed")
            msg.timestamp, msg.is_rx = time.time(), False
            if poll:
                self._inbox.append(msg)
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

    def _notice(self, kind: str, message: str) -> None:
        log.warning("%s", message)
        t = self.assembler.last_sample_time if hasattr(self, "assembler") else None
        self.notices.append(CanNotice(t or 0.0, kind, message))

    # --- reading ------------------------------------------------------------------------

    def _receive(self, timeout_s: float) -> None:
        """The poller's read: the frames waiting on the bus into the inbox, waiting up to
        ``timeout_s`` for the first (the poller counts its boards' replies as they come, with
        no other thread to wake); a failed bus is left to the reader to reconnect. It reads
        for a sample period at most: a bus flooded faster than it reads still gets its polls
        (the rest waits for the next read)."""
        import can

        bus = self._bus
        if bus is None or self._failure is not None:
            self._closing.wait(min(timeout_s, RECONNECT_INTERVAL_S))  # being reconnected
            return
        saw, inbox, monotonic = self.ati_boards.saw, self._inbox, time.monotonic
        try:
            msg = bus.recv(timeout=max(0.0, timeout_s))
            until = monotonic() + 1.0 / self.sample_rate_hz
            while msg is not None:  # (then what else waits: one wake-up for them all)
                if msg.is_error_frame and msg.arbitration_id & CAN_ERR_BUSOFF:
                    raise can.CanOperationError("bus-off")
                if saw(msg):  # (not our own poll echoed back)
                    inbox.append(msg)
                msg = bus.recv(timeout=0.0) if monotonic() < until else None
        except Exception as err:  # raised by the reader: a python-can error reconnects
            if self._bus is bus and not self._closing.is_set():
                self._failure = (bus, err)

    def _taken_from_inbox(self) -> list[Any]:
        """What the poller thread sent and read since the last block, in order; its bus's
        failure raised (as :meth:`_gather` raises it)."""
        self._closing.wait(max(0.0, self._block_due - time.monotonic()))
        self._block_due = max(self._block_due + BLOCK_S, time.monotonic())
        batch: list[Any] = []
        while self._inbox and len(batch) < MAX_BLOCK_FRAMES:
            batch.append(self._inbox.popleft())
        failure, self._failure = self._failure, None
        if failure is not None and failure[0] is self._bus:
            self._inbox.extendleft(reversed(batch))  # (given out after the reconnection)
            raise failure[1]
        return batch

    def read_block(self) -> WrenchBlock | None:
        """The samples completed by the frames that came within ``BLOCK_S``; a lost bus is
        reconnected (what the assembler held is given out first)."""
        import can

        if self._stop_after is not None:  # (the samples before it were given out)
            raise self._stop_after
        if self._quiet_since is None:  # the first read: the quiet clock and the polls start
            self._quiet_since = self._block_due = time.monotonic()
            self.ati_boards.start_polling()
        try:
            batch = self._taken_from_inbox() if self.ati_boards.poll_ids else self._gather()
        except (can.CanError, OSError) as err:
            if self._closing.is_set():
                return None
            held = self._give(self.assembler.flush())
            self._reconnect(str(err))
            return held
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
        """The frames that came within ``BLOCK_S`` (a python-can error if the bus failed);
        a desk that streams (no ATI boards to poll) is read here, on the reader's thread."""
        import can

        batch: list[Any] = []
        deadline = time.monotonic() + BLOCK_S
        while time.monotonic() < deadline and len(batch) < MAX_BLOCK_FRAMES:
            bus = self._bus
            if bus is None:
                raise can.CanOperationError("bus is closed")
            msg = bus.recv(timeout=max(0.0, deadline - time.monotonic()))
            if msg is None:
                break
            if msg.is_error_frame and msg.arbitration_id & CAN_ERR_BUSOFF:
                raise can.CanOperationError("bus-off")
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
        """The assembled samples as a block; a stop it carries is raised at the next read.
        The rounds the poller skipped meanwhile join the stats here, on every way out (the
        last block, a reconnection's, a quiet one's too)."""
        self.stats.lost_samples += self.ati_boards.take_skipped()
        self.notices.extend(block.notices)
        if block.stop is not None:
            self._stop_after = block.stop
        return WrenchBlock(block.t, block.wrench, accel=block.accel)

    def release(self) -> None:
        """Stop polling and release the bus."""
        self.ati_boards.stop_polling()
        self._shutdown_bus()


def _bus_arguments(
    config: CanConfig, bitrate: int | None, bus_options: dict[str, Any] | None
) -> dict[str, Any]:
    """python-can's arguments for the bus: the profile's ``bus_options`` and bit rate, under
    those given to the source."""
    out: dict[str, Any] = dict(config.bus_options)
    if bitrate or config.bitrate:
        out["bitrate"] = bitrate or config.bitrate
    out.update(bus_options or {})
    return out


def open_can_source(spec: str, profile: DeskProfile, **options: Any) -> CanSource:
    """Open a live CAN source for ``profile``; ``spec`` is ``can:INTERFACE:CHANNEL``,
    ``INTERFACE:CHANNEL`` or ``can`` (the profile's). Options: ``bitrate``, ``bus_options``
    (extra python-can arguments), ``frame_sink`` (called with every list of received and sent
    python-can messages, e.g. a log writer), ``calibration_timeout_s``."""
    return CanSource(spec, profile, **options)
