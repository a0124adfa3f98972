"""The desk's ATI boards on a live CAN bus: their calibration asked for at start, then one poll
round per sample period from a thread of its own (the NETCANOEM protocol: ati_netcanoem.py).

The bus itself (opening, sending, reconnecting) is the live source's (source.py): it gives
:class:`AtiBoards` a way to send a poll and to receive the frames waiting. The poller thread
reads the bus itself when a round is due (the source's receive hands each frame to
:meth:`AtiBoards.saw`, which counts the boards' replies, and keeps it for the reader), so it
knows whether the round before was answered with no other thread to wake, and wakes once a
round, not once a frame (at rates under 1 kHz, once more in between, so that replies wait
at most :data:`REPLY_READ_S` to be read).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Mapping
from typing import Any, NamedTuple

from hapticdesk.canbus import ati_netcanoem as ati
from hapticdesk.canbus.bus_spec import CanSourceError
from hapticdesk.canbus.config import AtiSensor

log = logging.getLogger("hapticdesk.canbus.source")

#: a request and where its replies go: ``send(ident, payload)`` sends one request (its frame
#: logged), ``recv(timeout_s)`` the next python-can message or None
SendRequest = Callable[[int, bytes], None]

#: how long the poller waits for a board's reply before the next round (see AtiBoards._poll)
REPLY_TIMEOUT_S = 0.1
#: a reply that has not come this long after its poll is lost: the board is polled again
WRITE_OFF_S = 0.5
#: replies are read at most this long after their round (a slower rate's poller wakes for
#: them before its next round: a round is read at the next one's start otherwise)
REPLY_READ_S = 0.001
#: a poller woken this late (at least a period) polls the rounds it missed back to back, each
#: as soon as the replies before it are in: a host that wakes a thread a millisecond late
#: now and then (as a shared or a small one does) still gets every sample, at its real time;
#: a longer stall's rounds are skipped and counted lost (a burst would flood the bus)
CATCH_UP_S = 0.005
ReceiveFrame = Callable[[float], Any]


class _Request(NamedTuple):
    """One calibration request to a board: its frame, and the board it asks (for errors)."""

    ident: int
    payload: bytes
    name: str
    base: int


class _PollLedger:
    """Per board: the polls sent, the replies heard (``heard``, counted by the receive), the
    replies written off as lost, when it was last polled and whether its reply is waited for
    (see :meth:`AtiBoards._poll`)."""

    def __init__(self, boards: int, heard: list[int], reply_timeout_s: float) -> None:
        self.heard = heard
        self.reply_timeout_s = reply_timeout_s
        self.sent = [0] * boards
        self.written_off = [0] * boards
        self.sent_at = [0.0] * boards
        self.waited = [True] * boards

    def owing(self, b: int) -> int:
        """The replies board ``b`` still owes."""
        debt = self.sent[b] - self.heard[b] - self.written_off[b]
        if debt < 0:  # a reply taken as lost came after all
            self.written_off[b] += debt
            debt = 0
        return debt

    def due(self, now: float) -> list[int]:
        """The boards to poll in this round: those that owe nothing, or whose reply is
        written off (:data:`WRITE_OFF_S`); a board whose reply is late is no longer waited
        for."""
        boards = []
        for b in range(len(self.sent)):
            debt = self.owing(b)
            if debt and now - self.sent_at[b] >= WRITE_OFF_S:
                self.written_off[b] += debt  # its reply is lost
            elif debt:
                self.waited[b] = self.waited[b] and now - self.sent_at[b] < self.reply_timeout_s
                continue  # its reply may still come: not asked again meanwhile
            else:
                self.waited[b] = True
            boards.append(b)
        return boards

    def sent_to(self, b: int, now: float) -> None:
        self.sent[b] += 1
        self.sent_at[b] = now

    def awaited_until(self, now: float) -> list[float]:
        """Until when each reply still waited for may come."""
        return [
            self.sent_at[b] + self.reply_timeout_s
            for b in range(len(self.sent))
            if self.waited[b] and self.owing(b) and now < self.sent_at[b] + self.reply_timeout_s
        ]


class AtiBoards:
    """The ATI boards of a live CAN source: calibration at start, polls while it runs.

    ``spec`` names the source in errors; ``send_poll(ident)`` sends one poll frame (queued for
    the reader first, so a reply is never assembled before its poll); ``closing`` is set when
    the source closes (the poller stops).
    """

    def __init__(
        self,
        sensors: Mapping[str, AtiSensor],
        sample_rate_hz: float,
        *,
        spec: str,
        send_poll: Callable[[int], None],
        receive: Callable[[float], None],
        closing: threading.Event,
    ) -> None:
        self.sensors = dict(sensors)
        self.sample_rate_hz = sample_rate_hz
        self.spec = spec
        self._send_poll = send_poll
        self._receive = receive
        self._closing = closing
        self.poll_ids = [ati.frame_id(s.base, ati.OP_GAUGES_A) for s in self.sensors.values()]
        # each board's last reply frame (its second, 0x1): the reader counts them (saw), so
        # the poller knows which board still owes a reply
        self._reply_ends = {
            ati.frame_id(s.base, ati.OP_GAUGES_B): b for b, s in enumerate(self.sensors.values())
        }
        # replies heard per board: the reader counts, the poller reads (no wake-up between
        # them: a thread woken by one holding the GIL is a convoy, a sixth of the reader's
        # time at 1.2 kHz in py-spy; the poller looks when its round is due)
        self._heard = [0] * len(self.poll_ids)
        self._poll_id_set = frozenset(self.poll_ids)
        self._poller: threading.Thread | None = None
        #: rounds never polled, the poller having woken too late for them (lost samples:
        #: the poller counts, the reader takes them into its stats)
        self.skipped_rounds = 0
        self._skipped_taken = 0

    # --- calibration at start -------------------------------------------------------------

    def read_calibrations(
        self,
        send: SendRequest,
        recv: ReceiveFrame,
        frame_sink: Callable[[list[Any]], None] | None,
        timeout_s: float,
    ) -> dict[str, ati.AtiCalibration]:
        """Each board's calibration from the bus, where the profile does not give it (a
        ``slot`` is selected on the board either way); a board that does not answer is a
        :class:`CanSourceError`."""
        out: dict[str, ati.AtiCalibration] = {}
        for name, sensor in self.sensors.items():
            if sensor.calibration is not None and sensor.slot is None:
                continue
            collector = ati.CalibrationCollector(sensor.base)
            for ident, payload in ati.calibration_requests(sensor.base, sensor.slot):
                request = _Request(ident, payload, name, sensor.base)
                self._ask(collector, request, send, recv, frame_sink, timeout_s)
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
        request: _Request,
        send: SendRequest,
        recv: ReceiveFrame,
        frame_sink: Callable[[list[Any]], None] | None,
        timeout_s: float,
    ) -> None:
        """Send one request and feed replies to ``collector`` until the answer is in."""
        ident, payload = request.ident, request.payload
        opcode = ident & 0xF
        for _attempt in range(3):
            collector.feed(ident, payload)  # replies are read against the request
            send(ident, payload)
            before = (len(collector.rows), collector.counts, collector.units, collector.serial)
            deadline = time.monotonic() + timeout_s
            while time.monotonic() < deadline:
                msg = recv(max(0.0, deadline - time.monotonic()))
                if msg is None:
                    break
                if frame_sink is not None:
                    frame_sink([msg])
                if not msg.is_error_frame and not msg.is_extended_id:
                    collector.feed(msg.arbitration_id, bytes(msg.data))
                now = (len(collector.rows), collector.counts, collector.units, collector.serial)
                if now != before or (opcode == ati.OP_ACTIVE_CAL and msg.arbitration_id == ident):
                    return
            if opcode in (ati.OP_UNITS, ati.OP_SERIAL):
                return  # older firmware may not answer these; N and N·m are then assumed
        raise CanSourceError(
            self.spec,
            f"ATI sensor `{request.name}` (base 0x{request.base:02X}) did not answer request "
            f"0x{ident:03X} within {timeout_s:g} s (3 tries); check power, wiring, bit rate and "
            "`base`, or give `calibration` in the profile",
        )

    def capacity_notice(self, bitrate: float | None, interface: str) -> str | None:
        """What to say at start when the boards cannot be polled at the desk's rate on this
        bus (None when they can, or when the bus has no bit rate to run out of)."""
        if not self.poll_ids or not bitrate or interface in ("virtual", "udp_multicast"):
            return None  # no bit rate to run out of (software buses are bound by the host)
        boards = len(self.poll_ids)
        most = ati.max_poll_rate(boards, float(bitrate))
        if self.sample_rate_hz <= most:
            return None
        return (
            f"{boards} ATI board(s) polled at {self.sample_rate_hz:g} Hz need "
            f"{boards * ati.SAMPLE_BITS * self.sample_rate_hz / 1000:.0f} "
            f"kbit/s (a poll and two replies, {ati.SAMPLE_BITS} bits a board); the bus "
            f"runs at {float(bitrate) / 1000:g} kbit/s and carries at most ~{most:.0f} "
            "samples/s: lower `sample_rate_hz` or raise the bit rate (board opcode 0xE)"
        )

    # --- polling while the source runs ----------------------------------------------------

    def start_polling(self) -> None:
        """Start the poller thread (nothing to poll: none)."""
        if self.poll_ids:
            self._poller = threading.Thread(target=self._poll, name="ati-poller", daemon=True)
            self._poller.start()

    def stop_polling(self) -> None:
        """Wait for the poller to end (the source set ``closing``), at most a second."""
        if self._poller is not None and self._poller is not threading.current_thread():
            self._poller.join(timeout=1.0)

    def take_skipped(self) -> int:
        """The rounds skipped since the last call (read once: the poller writes meanwhile)."""
        skipped = self.skipped_rounds
        new, self._skipped_taken = skipped - self._skipped_taken, skipped
        return new

    def saw(self, msg: Any) -> bool:
        """Tell the poller of a frame the reader read; False for our own poll echoed back
        (udp_multicast loops them: it is taken from the queue of sent polls, in order; twice
        would split samples), which the reader leaves out."""
        ident = msg.arbitration_id
        board = self._reply_ends.get(ident)
        if board is not None and len(msg.data):
            self._heard[board] += 1
        return bool(msg.data) or ident not in self._poll_id_set

    def _poll(self) -> None:
        """Request one sample of every ATI board per period, on a deadline clock.

        A board is never polled while it owes a reply (a reply to one poll that came after
        the next would void both samples, or land in the wrong one): the next round waits
        for the boards' replies, up to :data:`REPLY_TIMEOUT_S` (the way back through a loaded
        host, the reader thread, an emulator sharing the GIL, takes milliseconds at times),
        so a slow reply costs samples (counted lost), not their data. A board whose reply
        did not come in that time is no longer waited for, and is left out of the rounds
        (its samples NaN) until its reply comes, or for :data:`WRITE_OFF_S` (then that reply
        is taken as lost and the board polled again): so a dead board does not slow the
        others, and a late reply still lands in the sample it was asked for (the assembler
        keys each reply by its own board's poll). The clock does not drift: each round is due
        a period after the one before; a poller woken late polls the rounds it missed back to
        back, up to :data:`CATCH_UP_S` of them (paced by the replies), and skips the rest of
        a longer stall (counted in :attr:`skipped_rounds`), keeping the clock's phase.
        """
        period = 1.0 / self.sample_rate_hz
        catch_up_s = max(period, CATCH_UP_S)
        ledger = _PollLedger(len(self.poll_ids), self._heard, max(REPLY_TIMEOUT_S, 2 * period))
        next_due = time.monotonic()
        while not self._closing.is_set():
            now = time.monotonic()
            for b in ledger.due(now):  # the round: every board that owes nothing
                try:
                    self._send_poll(self.poll_ids[b])
                except Exception as err:  # the reader reconnects; keep the rhythm
                    log.debug("poll not sent: %s", err)
                    break
                ledger.sent_to(b, now)
            next_due += period
            # asleep until the next round is due, then what came meanwhile is read at once
            # (one wake-up a round, not one a frame: each costs a thread switch); at rates
            # under 1/REPLY_READ_S, the replies are read once in between too
            if now + REPLY_READ_S < next_due:
                self._closing.wait(now + REPLY_READ_S - time.monotonic())
                self._receive(0.0)
            self._closing.wait(next_due - time.monotonic())
            wait_s = 0.0
            while not self._closing.is_set():
                self._receive(wait_s)
                now = time.monotonic()
                # the replies that may yet come hold the round back (the receive counts them)
                owed = ledger.awaited_until(now)
                if not owed:
                    break
                wait_s = min(owed) - now
            late = time.monotonic() - next_due
            if late > catch_up_s:  # a stall: its rounds are lost, not burst
                missed = int(late / period)
                self.skipped_rounds += missed
                next_due += missed * period
