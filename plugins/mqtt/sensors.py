"""The desk's sensor values on its state topic ``<base>/<desk>``: force, touch position,
resting load, occupancy; throttled, from the runtime's ``contact_sink``.

The sink runs on the sensing thread, so it only compares numbers and, at most
:data:`RATE_HZ` times a second of sample time (and at once when occupancy changes), queues a
message on the run's link (:meth:`MqttLink.publish` never blocks). Home Assistant's sensors
read these keys (:mod:`.homeassistant`); the gesture publisher adds them to the state JSON it
sends with each ``action``, as Zigbee2MQTT keeps a device's whole state in one JSON.
"""

from __future__ import annotations

import threading
from typing import Any

from hapticdesk.runtime.observe import ContactSummary

RATE_HZ = 2.0  # sensor updates per second of sample time at most
OCCUPANCY_HOLD_S = 30.0  # the desk counts as in use this long after the last touch


class DeskState:
    """The latest sensor values of the desk (shared by the sensor and gesture publishers)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._values: dict[str, Any] = {
            "force_n": 0.0,
            "x": None,
            "y": None,
            "resting_load_n": 0.0,
            "occupancy": False,
            "paused": False,  # gestures not sent (a pause from `set`): said, not hidden
            "layout": None,  # the running layout's name (the select of layouts reads it)
        }

    def update(self, **values: Any) -> None:
        with self._lock:
            self._values.update(values)

    def snapshot(self) -> dict[str, Any]:
        with self._lock:
            return dict(self._values)


class SensorPublisher:
    """A ``contact_sink``: throttles the contact state into state-JSON messages."""

    def __init__(self, state: DeskState, publish: Any, sensors: bool = True) -> None:
        """``publish(payload)`` queues one state JSON (a dict); ``sensors`` False: only when
        the desk is paused or resumed (a desk without Home Assistant discovery)."""
        self.state = state
        self.publish = publish
        self.sensors = sensors
        self._paused = False
        self._next_t = float("-inf")
        self._last_touch_t: float | None = None
        self._occupied = False
        self._first_zero: float | None = None

    def __call__(self, s: ContactSummary) -> None:
        if s.paused != self._paused:  # at once, whatever the rate
            self._paused = s.paused
            self.state.update(paused=s.paused)
            self.publish(self.state.snapshot())
        if not self.sensors:
            return
        if s.in_contact:
            self._last_touch_t = s.t
        occupied = self._last_touch_t is not None and s.t - self._last_touch_t < OCCUPANCY_HOLD_S
        if s.zero_force_n is not None and self._first_zero is None:
            self._first_zero = s.zero_force_n
        changed = occupied != self._occupied
        self._occupied = occupied
        if not changed and s.t < self._next_t:
            return
        self._next_t = s.t + 1.0 / RATE_HZ
        values: dict[str, Any] = {"force_n": round(s.force_n, 3), "occupancy": occupied}
        if s.x is not None and s.y is not None:
            values.update(x=round(s.x, 4), y=round(s.y, 4))
        if s.zero_force_n is not None and self._first_zero is not None:
            # what came to rest on the desk since the tare (the zero absorbs still loads)
            values["resting_load_n"] = round(s.zero_force_n - self._first_zero, 2)
        self.state.update(**values)
        self.publish(self.state.snapshot())
