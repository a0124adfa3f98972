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
        import can

        by_base = {s.base: name for name, s in self.ati.items()}
        index = dict.fromkeys(self.ati, 0)
        names = self.encoder.sensor_names
        k = len(self.t)
        while not self._stop.is_set():
            if not self.loop and min(index.values()) >= k:
                return  # every board has given its last sample
            msg = self.bus.recv(timeout=0.05)
            if msg is None or msg.is_error_frame or msg.is_extended_id:
                continue
            base = msg.arbitration_id >> 4
            name = by_base.get(base)
            if name is None:
                continue
            replies: list[tuple[int, bytes]]
            if msg.arbitration_id & 0xF == ati.OP_GAUGES_A and len(msg.data) == 0:
                i = index[name]
                if i >= k:
                    if not self.loop:
                        continue  # the recording is over: the board stays quiet
                    i = index[name] = 0
                s = names.index(name)
                status = 0 if self.status is None else int(self.status[i, s])
                gauges = self.encoder.calibrations[name].gauges_for(self.wrench[i : i + 1, s])
                a, b = ati.encode_gauge_frames(np.array([status]), gauges)
                replies = [
                    (ati.frame_id(base, ati.OP_GAUGES_A), a[0].tobytes()),
                    (ati.frame_id(base, ati.OP_GAUGES_B), b[0, :6].tobytes()),
                ]
                index[name] = i + 1
                self.stats.polls += 1
                self.stats.samples = max(self.stats.samples, i + 1)
            else:
                replies = ati.replies(
                    base, msg.arbitration_id, bytes(msg.data), self.encoder.calibrations[name]
                )
            for ident, data in replies:
                try:
                    self.bus.send(
                        can.Message(
                            timestamp=time.time(),
                            arbitration_id=ident,
                            data=data,
                            is_extended_id=False,
                        )
                    )
                    self.stats.frames += 1
                except can.CanError as err:
                    log.warning("emulator: could not send a reply: %s", err)
