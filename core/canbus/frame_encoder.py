"""A desk's sensors as CAN frames: :class:`FrameEncoder` turns samples (``t``, ``wrench``
(k, S, 6)) into the frames the desk's ``can:`` section decodes, the inverse of
:mod:`.decoding`: database messages (vectorised bit insertion, checked against cantools'
``encode`` in the tests) or ATI NETCANOEM replies, with the host's polls and the boards'
calibration exchange as a capture has them. :mod:`.emulator` sends them onto a bus."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from hapticdesk.canbus import ati_netcanoem as ati
from hapticdesk.canbus.config import AtiSensor, CanConfig, SignalSensor
from hapticdesk.canbus.dbc_signals import SignalLayout, words_to_frames
from hapticdesk.canbus.frames import EXTENDED, SENT, FrameArray
from hapticdesk.errors import ConfigError
from hapticdesk.files.profile import AXES, DeskProfile


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
            wrench, status = self._with_accelerometers(wrench, status, accel)
        # each (k,) frames of one kind, interleaved at the end; a host polls every board, then
        # they answer
        per_sample = [
            self._message_frames(m, t, wrench, status, first_index) for m in self.messages
        ]
        poll_frames: list[FrameArray] = []
        for s, name in enumerate(self.sensor_names):
            sensor = self.config.sensors[name]
            if isinstance(sensor, AtiSensor):
                polled, replies = self._ati_frames(name, sensor, t, wrench[:, s], status[:, s])
                poll_frames += [polled] if polls else []
                per_sample += replies
        return _interleave(poll_frames + per_sample)

    def _with_accelerometers(
        self, wrench: np.ndarray, status: np.ndarray, accel: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray]:
        """``wrench`` and ``status`` with the accelerometers' groups after the sensors' (their
        x, y, z in a group's first channels; NaN, no frame, without ``accel``)."""
        k, n = len(wrench), len(self.accel_channels)
        groups = np.full((k, n, 6), np.nan if accel is None else 0.0)
        if accel is not None:
            first = 0
            for i, channels in enumerate(self.accel_channels):
                groups[:, i, channels] = accel[:, first : first + len(channels)]
                first += len(channels)
        wrench = np.concatenate([wrench, groups], axis=1)
        status = np.concatenate([status, np.zeros((k, n), np.int64)], axis=1)
        return wrench, status

    def _message_frames(
        self,
        msg: _Message,
        t: np.ndarray,
        wrench: np.ndarray,
        status: np.ndarray,
        first_index: int,
    ) -> FrameArray:
        """One database message per sample: its signals' bits placed, counters from
        ``first_index``; a sample with a NaN signal marked not to send."""
        k = len(t)
        little = np.zeros(k, dtype=np.uint64)
        big = np.zeros(k, dtype=np.uint64)
        ok = np.ones(k, dtype=bool)
        for layout, s, axis in msg.axis_signals:
            values = wrench[:, s, axis]
            ok &= np.isfinite(values)
            little, big = _place(layout, layout.encode(np.nan_to_num(values)), little, big)
        for layout in msg.counters:
            little, big = _place(layout, layout.encode_raw(first_index + np.arange(k)), little, big)
        for layout, s in msg.statuses:
            little, big = _place(layout, layout.encode_raw(status[:, s]), little, big)
        frames = FrameArray(
            t.copy(),
            np.full(k, msg.ident, np.uint32),
            np.full(k, msg.length, np.uint8),
            words_to_frames(little, big),
            np.zeros(k, np.uint8),
        )
        return _drop(frames, ok)

    def _ati_frames(
        self, name: str, sensor: AtiSensor, t: np.ndarray, w: np.ndarray, status: np.ndarray
    ) -> tuple[FrameArray, list[FrameArray]]:
        """An ATI board's poll requests (marked as sent) and its two reply frames per sample
        of its wrench ``w`` (k, 6); a sample with a NaN channel marked not to send."""
        k = len(t)
        ok = np.isfinite(w).all(axis=1)
        gauges = self.calibrations[name].gauges_for(np.nan_to_num(w))
        a, b = ati.encode_gauge_frames(status, gauges)
        polls = FrameArray(
            t.copy(),
            np.full(k, ati.frame_id(sensor.base, ati.OP_GAUGES_A), np.uint32),
            np.zeros(k, np.uint8),
            np.zeros((k, 8), np.uint8),
            np.full(k, SENT, np.uint8),
        )
        replies = []
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
            replies.append(_drop(frames, ok))
        return polls, replies

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


def encoder_for(
    profile: DeskProfile, config: CanConfig | None, encoding: str | None
) -> tuple[FrameEncoder, CanConfig]:
    """The encoder for ``encoding`` (dbc | ati | None: as the profile says).

    ``ati`` on a profile whose sensors are not ATI boards gives them bases 0x20, 0x21, … with
    example calibrations (the returned config says so, to decode the frames with).
    """
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
