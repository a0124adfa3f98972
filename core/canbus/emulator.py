"""A desk's sensors as CAN frames: encode samples, and send them onto a bus like the real thing.

:class:`FrameEncoder` turns samples (``t``, ``wrench`` (k, S, 6)) into the frames the desk's
``can:`` section decodes: database messages (vectorised bit insertion, checked against
cantools' ``encode`` in the tests) or ATI NETCANOEM replies. :class:`CanEmulator` puts them on
a python-can bus: a database desk streams its frames paced by the sample times; ATI boards
answer polls, one sample per poll, and answer calibration requests, so the poller sets the
pace as on a real bus.
"""

from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from hapticdesk.canbus import ati_netcanoem as ati
from hapticdesk.canbus.config import AtiSensor, CanConfig, SignalSensor
from hapticdesk.canbus.dbc_signals import SignalLayout, words_to_frames
from hapticdesk.canbus.frames import EXTENDED, SENT, FrameArray
from hapticdesk.files.profile import AXES, DeskProfile

log = logging.getLogger("hapticdesk.canbus.emulator")


@dataclass
class _Message:
    ident: int
    length: int
    axis_signals: list[tuple[SignalLayout, int, int]]  # layout, sensor, axis
    counters: list[SignalLayout]
    statuses: list[tuple[SignalLayout, int]]  # layout, sensor


class FrameEncoder:
    """Samples -> frames for a desk's ``can:`` section (the inverse of the decoding)."""

    def __init__(
        self,
        config: CanConfig,
        profile: DeskProfile,
        calibrations: dict[str, ati.AtiCalibration] | None = None,
    ) -> None:
        self.config = config
        self.sensor_names = profile.sensor_names
        self.calibrations: dict[str, ati.AtiCalibration] = {}
        # the accelerometers (when on the bus) are the groups after the sensors: the x, y, z
        # of each are its group's channels 0, 1, 2
        specs = profile.accelerometers if config.accelerometers else ()
        self.accel_channels = [[("x", "y", "z").index(a) for a in spec.axes] for spec in specs]
        messages: dict[str, _Message] = {}
        for s, (name, sensor) in enumerate(config.groups()):
            if isinstance(sensor, AtiSensor):
                cal = sensor.calibration or (calibrations or {}).get(name)
                self.calibrations[name] = cal or ati.example_calibration(s)
                continue
            assert isinstance(sensor, SignalSensor)
            for axis, ref in sensor.axes.items():
                msg = self._message(messages, ref.message)
                msg.axis_signals.append((self._layout(ref), s, AXES.index(axis)))
            for ref in sensor.counters:
                self._message(messages, ref.message).counters.append(self._layout(ref))
            for ref in sensor.status:
                self._message(messages, ref.message).statuses.append((self._layout(ref), s))
        self.messages = list(messages.values())

    def _message(self, messages: dict[str, _Message], name: str) -> _Message:
        if name not in messages:
            m = self.config.database.get_message_by_name(name)
            ident = int(m.frame_id) | (int(EXTENDED) if m.is_extended_frame else 0)
            messages[name] = _Message(ident, int(m.length), [], [], [])
        return messages[name]

    def _layout(self, ref: Any) -> SignalLayout:
        m = self.config.database.get_message_by_name(ref.message)
        return SignalLayout.from_cantools(m, m.get_signal_by_name(ref.signal))

    def encode(
        self,
        t: np.ndarray,
        wrench: np.ndarray,
        *,
        first_index: int = 0,
        status: np.ndarray | None = None,
        polls: bool = False,
        accel: np.ndarray | None = None,
    ) -> FrameArray:
        """Frames of samples ``first_index …`` in sample order.

        ``status`` (k, S) integers go into status signals or ATI status words. A sample with
        a NaN channel sends no frame carrying it (as a lost frame). ``polls`` adds the host's
        ATI poll requests (marked as sent) before each sample's replies, as a capture has them.
        ``accel`` (k, A): the accelerometers' readings, one after the other, for a desk with
        some on the bus (none given: their frames are not sent, as silent boards).
        """
        t = np.asarray(t, dtype=float)
        k = len(t)
        status = np.zeros((k, len(self.sensor_names)), dtype=np.int64) if status is None else status
        if self.accel_channels:  # more groups: the accelerometers'
            n = len(self.accel_channels)
            groups = np.full((k, n, 6), np.nan if accel is None else 0.0)
            if accel is not None:
                first = 0
                for i, channels in enumerate(self.accel_channels):
                    groups[:, i, channels] = accel[:, first : first + len(channels)]
                    first += len(channels)
            wrench = np.concatenate([wrench, groups], axis=1)
            status = np.concatenate([status, np.zeros((k, n), np.int64)], axis=1)
        per_sample: list[FrameArray] = []  # each (k,) frames of one kind, interleaved below
        for msg in self.messages:
            little = np.zeros(k, dtype=np.uint64)
            big = np.zeros(k, dtype=np.uint64)
            ok = np.ones(k, dtype=bool)
            for layout, s, axis in msg.axis_signals:
                values = wrench[:, s, axis]
                ok &= np.isfinite(values)
                bits = layout.encode(np.nan_to_num(values))
                little, big = _place(layout, bits, little, big)
            for layout in msg.counters:
                little, big = _place(
                    layout, layout.encode_raw(first_index + np.arange(k)), little, big
                )
            for layout, s in msg.statuses:
                little, big = _place(layout, layout.encode_raw(status[:, s]), little, big)
            data = words_to_frames(little, big)
            frames = FrameArray(
                t.copy(),
                np.full(k, msg.ident, np.uint32),
                np.full(k, msg.length, np.uint8),
                data,
                np.zeros(k, np.uint8),
            )
            per_sample.append(_drop(frames, ok))
        poll_frames: list[FrameArray] = []  # a host polls every board, then they answer
        for s, name in enumerate(self.sensor_names):
            sensor = self.config.sensors[name]
            if not isinstance(sensor, AtiSensor):
                continue
            w = wrench[:, s]
            ok = np.isfinite(w).all(axis=1)
            gauges = self.calibrations[name].gauges_for(np.nan_to_num(w))
            a, b = ati.encode_gauge_frames(status[:, s], gauges)
            if polls:
                poll_frames.append(
                    FrameArray(
                        t.copy(),
                        np.full(k, ati.frame_id(sensor.base, ati.OP_GAUGES_A), np.uint32),
                        np.zeros(k, np.uint8),
                        np.zeros((k, 8), np.uint8),
                        np.full(k, SENT, np.uint8),
                    )
                )
            for ident, data, length in (
                (ati.frame_id(sensor.base, ati.OP_GAUGES_A), a, ati.GAUGES_A_LENGTH),
                (ati.frame_id(sensor.base, ati.OP_GAUGES_B), b, ati.GAUGES_B_LENGTH),
            ):
                frames = FrameArray(
                    t.copy(),
                    np.full(k, ident, np.uint32),
                    np.full(k, length, np.uint8),
                    data,
                    np.zeros(k, np.uint8),
                )
                per_sample.append(_drop(frames, ok))
        per_sample = poll_frames + per_sample
        return _interleave(per_sample)

    def calibration_frames(self, t: float = 0.0) -> FrameArray:
        """The calibration exchange of every ATI board (requests and replies), as at start-up."""
        idents: list[int] = []
        datas: list[bytes] = []
        flags: list[int] = []
        for name in self.sensor_names:
            sensor = self.config.sensors[name]
            if not isinstance(sensor, AtiSensor):
                continue
            for ident, payload in ati.calibration_requests(sensor.base):
                idents.append(ident)
                datas.append(payload)
                flags.append(SENT)
                for r_ident, r_data in ati.replies(
                    sensor.base, ident, payload, self.calibrations[name]
                ):
                    idents.append(r_ident)
                    datas.append(r_data)
                    flags.append(0)
        return FrameArray.build(np.full(len(datas), t), idents, datas, flags=np.array(flags))


def _place(
    layout: SignalLayout, bits: np.ndarray, little: np.ndarray, big: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    if layout.big_endian:
        return little, big | bits
    return little | bits, big


def _drop(frames: FrameArray, keep: np.ndarray) -> FrameArray:
    """Mark frames not to send (kept in place so that interleaving stays per sample)."""
    frames.flags = np.where(keep, frames.flags, np.uint8(255)).astype(np.uint8)
    return frames


def _interleave(per_kind: list[FrameArray]) -> FrameArray:
    """(kinds × k) frames -> sample-major order, without the dropped ones."""
    if not per_kind:
        return FrameArray.empty()
    k = len(per_kind[0])
    order = np.arange(k * len(per_kind)).reshape(len(per_kind), k).T.ravel()
    merged = FrameArray.concat(per_kind).take(order)
    return merged.take(merged.flags != 255)


# --- sending onto a bus -----------------------------------------------------------------------


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


def encoder_for(
    profile: DeskProfile, config: CanConfig | None, encoding: str | None
) -> tuple[FrameEncoder, CanConfig]:
    """The encoder for ``encoding`` (dbc | ati | None: as the profile says).

    ``ati`` on a profile whose sensors are not ATI boards gives them bases 0x20, 0x21, … with
    example calibrations (the returned config says so, to decode the frames with).
    """
    from hapticdesk.errors import ConfigError

    where = str(profile.path) if profile.path else profile.name
    if encoding == "ati" and (
        config is None or not all(isinstance(s, AtiSensor) for s in config.sensors.values())
    ):
        sensors: dict[str, SignalSensor | AtiSensor] = {
            n: AtiSensor(base=ati.DEFAULT_BASE + i) for i, n in enumerate(profile.sensor_names)
        }
        config = (
            replace(config, sensors=sensors, assemble="time", accelerometers=())
            if config
            else CanConfig(sensors=sensors, where=where)
        )
    elif config is None:
        raise ConfigError(
            where,
            f"desk `{profile.name}` has no `can:` section to encode its frames with; use "
            "`--encoding ati` or a profile with one (e.g. kitamura2017-can)",
        )
    elif encoding == "dbc" and not all(
        isinstance(s, SignalSensor) for s in config.sensors.values()
    ):
        raise ConfigError(
            config.where,
            "`--encoding dbc` needs every sensor mapped to database signals in `can.sensors`",
        )
    return FrameEncoder(config, profile), config
