"""Sensors that stop sending, and come back: a sensor none of whose frames came for
``silent_timeout_s`` of sample time is noticed (its channels are NaN meanwhile) and noticed
again when it is back; with ``silent_sensor: stop`` the first silence ends the stream, after
the samples before it. Part of :mod:`.assembler`."""

from __future__ import annotations

import numpy as np

from hapticdesk.canbus.stats import CanNotice, SensorSilentError, silence_message
from hapticdesk.errors import Position


class SilenceWatch:
    """Each sensor's last frame, on the sample clock, from push to push."""

    def __init__(
        self, names: list[str], timeout_s: float, policy: str, where: Position | str
    ) -> None:
        self.names = names
        self.silent_timeout_s = timeout_s
        self.silent_sensor = policy  # continue | stop
        self.where = where
        self._last_seen = np.full(len(names), np.nan)
        self._silent = np.zeros(len(names), dtype=bool)
        #: frames of each sensor that came too late for their sample since it last fit (a
        #: silence message says them: the sensor talks, out of step)
        self.late_frames = np.zeros(len(names), dtype=np.int64)
        #: set at the first silence with ``silent_sensor: stop``
        self.stopped: SensorSilentError | None = None

    def watch(self, t: np.ndarray, talking: np.ndarray) -> tuple[list[CanNotice], int | None]:
        """Notice sensors that stop and come back; stop at the first silence if configured."""
        if self._nothing_changes(t, talking):
            return [], None
        notices: list[CanNotice] = []
        stop_at: int | None = None
        names = self.names
        for s, name in enumerate(names):
            if np.isnan(self._last_seen[s]):
                self._last_seen[s] = t[0]
            seen = np.where(talking[:, s], t, -np.inf)
            last = np.maximum(np.maximum.accumulate(seen), self._last_seen[s])
            silent = ~talking[:, s] & (t - last > self.silent_timeout_s)
            prev = np.concatenate([[self._silent[s]], silent[:-1]])
            for i in np.flatnonzero(silent & ~prev):
                text = silence_message(
                    name, self.silent_timeout_s, float(last[i]), int(self.late_frames[s])
                )
                if self.silent_sensor == "stop":
                    if stop_at is None or i < stop_at:
                        stop_at = int(i)
                        self.stopped = SensorSilentError(
                            self.where, text + "; stopping (`silent_sensor: stop`)"
                        )
                    break
                notices.append(CanNotice(float(t[i]), "silent", text + "; its channels are NaN"))
            for i in np.flatnonzero(talking[:, s] & prev):
                notices.append(
                    CanNotice(
                        float(t[i]), "back", f"sensor {name} is sending again at t={t[i]:.3f} s"
                    )
                )
            if talking[:, s].any():
                self.late_frames[s] = 0
            self._silent[s] = bool(silent[-1]) if len(silent) else self._silent[s]
            self._last_seen[s] = last[-1]
        if stop_at is not None:
            notices = [n for n in notices if n.t < t[stop_at]]
        notices.sort(key=lambda n: n.t)
        return notices, stop_at

    def _nothing_changes(self, t: np.ndarray, talking: np.ndarray) -> bool:
        """The common case, for every sensor at once: no sensor falls silent or comes back in
        these samples; then the state is carried here (False: :meth:`watch` looks sensor by
        sensor, and carries it)."""
        before = np.where(np.isnan(self._last_seen), t[0], self._last_seen)
        seen = np.where(talking, t[:, None], -np.inf)
        last = np.maximum(np.maximum.accumulate(seen, axis=0), before[None, :])
        silent = ~talking & (t[:, None] - last > self.silent_timeout_s)
        prev = np.concatenate([self._silent[None, :], silent[:-1]])
        if (silent & ~prev).any() or (talking & prev).any():
            return False
        self.late_frames[talking.any(axis=0)] = 0
        self._silent = silent[-1].copy()
        self._last_seen = last[-1].copy()
        return True
