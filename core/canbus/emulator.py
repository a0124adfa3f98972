"""A desk's sensors on a CAN bus, like the real thing: :class:`CanEmulator` puts the frames of
a :class:`~hapticdesk.canbus.frame_encoder.FrameEncoder` on a python-can bus. A database desk
streams its frames paced by the sample times; ATI boards answer polls, one sample per poll,
and answer calibration requests, so the poller sets the pace as on a real bus.
"""

from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from hapticdesk.canbus import ati_netcanoem as ati
from hapticdesk.canbus.config import AtiSensor
from hapticdesk.canbus.frame_encoder import FrameEncoder
from hapticdesk.canbus.outgoing import OutgoingMessage

log = logging.getLogger("hapticdesk.canbus.emulator")


@dataclass
class EmulatorStats:
    samples: int = 0
    frames: int = 0
    polls: int = 0


class CanEmulator:
    """Sends a recording's samples onto ``bus`` as the desk's sensors would.

    ``speed`` 1 paces database frames in real time, 0 sends as fast as possible; ATI boards
    answer polls (one sample each) whatever the speed. ``loop`` starts over at the end.
    """

    def __init__(
        self,
        encoder: FrameEncoder,
        t: np.ndarray,
        wrench: np.ndarray,
        bus: Any,
        *,
        speed: float = 1.0,
        loop: bool = False,
        status: np.ndarray | None = None,
        accel: np.ndarray | None = None,
    ) -> None:
        if loop and len(t) < 2:  # (one sample has no spacing: looped, it was sent unpaced)
            raise ValueError("an emulator that loops needs two samples or more")
        self.encoder = encoder
        self.t = np.asarray(t, dtype=float)
        self.wrench = wrench
        self.status = status
        self.accel = accel  # (k, A) the accelerometer's readings, if the desk sends them
        self.bus = bus
        self.speed = speed
        self.loop = loop
        self.stats = EmulatorStats()
        self._stop = threading.Event()
        self.ati = {
            name: s for name, s in encoder.config.sensors.items() if isinstance(s, AtiSensor)
        }

    def stop(self) -> None:
        self._stop.set()

    def run(self) -> EmulatorStats:
        """Send until the samples end (and not ``loop``) or :meth:`stop`."""
        if self.ati:
            self._answer_polls()
        else:
            self._stream()
        return self.stats

    def start(self) -> threading.Thread:
        """Run in a daemon thread; ``stop()`` and ``join()`` it when done."""
        thread = threading.Thread(target=self.run, name="can-emulator", daemon=True)
        thread.start()
        return thread

    def _stream(self) -> None:
        """Frames in sample order, each stamped with its sample time on the emulated clock
        (kept by buses that keep senders' stamps, e.g. ``virtual`` with
        ``preserve_timestamps=True``: then even ``speed`` 0 carries the sensor clock)."""
        import can

        k = len(self.t)
        chunk = max(1, int(round(0.005 * k / max(self.t[-1] - self.t[0], 1e-9)))) if k > 1 else 1
        start = time.monotonic()
        clock = time.time() - self.t[0]
        offset = 0.0
        index = 0
        while not self._stop.is_set():
            if index >= k:
                if not self.loop:
                    return
                offset += self.t[-1] - self.t[0] + (self.t[1] - self.t[0] if k > 1 else 0.0)
                index = 0
                continue
            stop = min(index + chunk, k)
            due = (self.t[index] - self.t[0] + offset) / self.speed if self.speed > 0 else 0.0
            wait = start + due - time.monotonic()
            if wait > 0:
                self._stop.wait(wait)
            status = None if self.status is None else self.status[index:stop]
            frames = self.encoder.encode(
                self.t[index:stop],
                self.wrench[index:stop],
                first_index=self.stats.samples,
                status=status,
                accel=None if self.accel is None else self.accel[index:stop],
            )
            for msg in frames.to_messages(t0=clock + offset):
                try:
                    self.bus.send(msg)
                except can.CanError as err:
                    log.warning("emulator: could not send a frame: %s", err)
            self.stats.frames += len(frames)
            self.stats.samples += stop - index
            index = stop

    def _answer_polls(self) -> None:
        """Answer polls as the boards would: every poll waiting on the bus is answered at each
        wake-up (one sample each, in the order they came), with replies encoded once for the
        whole recording, so a 1.2 kHz desk of four boards costs this thread little more than
        the bus's own sends (the replies were encoded per poll before: 40 % of its time)."""
        import can

        by_base = {s.base: name for name, s in self.ati.items()}
        replies_of = {name: self._gauge_replies(name) for name in self.ati}
        index = dict.fromkeys(self.ati, 0)
        k = len(self.t)
        while not self._stop.is_set():
            if not self.loop and min(index.values()) >= k:
                return  # every board has given its last sample
            msg = self.bus.recv(timeout=0.05)
            waiting = []
            while msg is not None:
                waiting.append(msg)
                msg = self.bus.recv(timeout=0.0)
            for msg in waiting:
                if msg.is_error_frame or msg.is_extended_id:
                    continue
                name = by_base.get(msg.arbitration_id >> 4)
                if name is None:
                    continue
                if msg.arbitration_id & 0xF == ati.OP_GAUGES_A and len(msg.data) == 0:
                    i = index[name]
                    if i >= k:
                        if not self.loop:
                            continue  # the recording is over: the board stays quiet
                        i = 0
                    index[name] = i + 1
                    self.stats.polls += 1
                    self.stats.samples = max(self.stats.samples, i + 1)
                    replies = replies_of[name].reply(i)
                else:
                    base = msg.arbitration_id >> 4
                    cal = self.encoder.calibrations[name]
                    replies = ati.replies(base, msg.arbitration_id, bytes(msg.data), cal)
                for ident, data in replies:
                    try:
                        self.bus.send(
                            OutgoingMessage(
                                timestamp=time.time(),
                                arbitration_id=ident,
                                data=data,
                                is_extended_id=False,
                            )
                        )
                        self.stats.frames += 1
                    except can.CanError as err:
                        log.warning("emulator: could not send a reply: %s", err)

    def _gauge_replies(self, name: str) -> _GaugeReplies:
        """Board ``name``'s reply frames for every sample of the recording, encoded at once."""
        s = self.encoder.sensor_names.index(name)
        base = self.ati[name].base
        w = np.asarray(self.wrench[:, s], dtype=float)
        status = np.zeros(len(w), np.int64) if self.status is None else self.status[:, s]
        gauges = self.encoder.calibrations[name].gauges_for(np.nan_to_num(w))
        a, b = ati.encode_gauge_frames(np.asarray(status), gauges)
        return _GaugeReplies(
            ati.frame_id(base, ati.OP_GAUGES_A),
            ati.frame_id(base, ati.OP_GAUGES_B),
            a,
            b[:, :6].copy(),
            np.isfinite(w).all(axis=1),
        )


@dataclass
class _GaugeReplies:
    """One board's two reply frames for each sample of the recording: ``a`` (k, 8) and
    ``b`` (k, 6) bytes; a sample with a NaN channel (``ok`` False) gets no reply, as the
    frame encoder leaves such a sample's frames out (a lost reply)."""

    id_a: int
    id_b: int
    a: np.ndarray
    b: np.ndarray
    ok: np.ndarray

    def reply(self, i: int) -> list[tuple[int, bytes]]:
        if not self.ok[i]:
            return []
        return [(self.id_a, self.a[i].tobytes()), (self.id_b, self.b[i].tobytes())]
