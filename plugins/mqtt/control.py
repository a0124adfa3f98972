"""The desk's ``<prefix>/set`` topic, and its controls as Home Assistant entities.

``<prefix>/set`` takes JSON commands (:mod:`hapticdesk.runtime.control`)::

    mosquitto_pub -t hapticdesk/study/set -m '{"command": "tare"}'
    mosquitto_pub -t hapticdesk/study/set -m '{"layout": "evening"}'

Each is handed to the run's control queue (the ``control_channel`` hook) and applied by the
sensing thread between two blocks. The topic is subscribed when the desk's connection opens,
before the desk says it is ``online`` (Home Assistant sends as soon as it sees that); a
command that comes before the run has begun waits for it. What was done, or why not, is
published (not retained) to ``<prefix>/set/result`` as ``{"command": ..., "ok": bool,
"message": ...}``, so a script or Home Assistant can see a refused layout name.

With ``discovery`` the controls appear in Home Assistant beside the gestures: a
*button* per command (Re-tare, Pause, Resume, Reload layout) and, when the layout names
``layouts:``, a *select* of them; both publish to ``<prefix>/set``. The select shows the
layout the desk runs, from ``layout`` in the desk's state JSON (``<prefix>``), whoever
switched it (the select, ``/set``, SIGHUP, the page) and after a restart.
"""

from __future__ import annotations

import json
import logging
import math
import re
import threading
import time
from collections.abc import Callable
from concurrent.futures import Future
from dataclasses import dataclass
from typing import Any

from hapticdesk.runtime.control import ControlCommand, ControlError, ControlQueue, parse_command

log = logging.getLogger(__name__)

#: Home Assistant buttons: command -> (object id, name, icon)
BUTTONS = {
    "tare": ("tare", "Re-tare", "mdi:scale-balance"),
    "pause": ("pause", "Pause gestures", "mdi:pause"),
    "resume": ("resume", "Resume gestures", "mdi:play"),
    "reload": ("reload", "Reload layout", "mdi:reload"),
}
_OBJECT_ID = re.compile(r"[^A-Za-z0-9_-]")
#: commands on ``<prefix>/set`` taken a second, and at once: a person or an automation sends
#: a few; more is a fault or a flood
SET_RATE = 20
SET_BURST = 50
#: a flood is said at most this often
LOG_EVERY_S = 10.0


class SetTopic:
    """Turns messages on ``<prefix>/set`` into control requests; answers on ``…/set/result``.

    ``publish(topic, payload)`` sends the answer (the run's MQTT link). ``control``: the run's
    queue, or None until :meth:`attach` gives it (the topic is subscribed before the run
    begins): commands that come before are held, at most :data:`SET_BURST`, and queued then."""

    def __init__(
        self, control: ControlQueue | None, publish: Callable[[str, Any], None], topic: str
    ):
        self.control = control
        self.publish = publish
        self.topic = topic
        self._held: list[ControlCommand] = []
        self._lock = threading.Lock()  # paho's thread and the run's, around control and _held
        self.result_topic = f"{topic}/result"
        self._budget = float(SET_BURST)  # commands that may come at once (a token bucket)
        self._refilled = time.monotonic()
        self._dropped = 0
        self._dropped_said = -math.inf

    def __call__(self, payload: bytes) -> None:
        """One message (on paho's thread: only parses and queues, never waits)."""
        if not self._take():
            return
        try:
            command = parse_command(payload)
        except ControlError as err:
            log.warning("MQTT: %s: %s", self.topic, err)
            self._answer(None, False, str(err))
            return
        with self._lock:
            if self.control is not None:
                self._request(self.control, command)
            elif len(self._held) < SET_BURST:
                self._held.append(command)
            else:
                self._answer(
                    str(command), False, f"the desk is starting; {SET_BURST} commands wait"
                )

    def attach(self, control: ControlQueue) -> None:
        """The run's queue: the commands held so far go to it, in the order they came."""
        with self._lock:
            self.control = control
            held, self._held = self._held, []
            for command in held:
                self._request(control, command)

    def _request(self, control: ControlQueue, command: ControlCommand) -> None:
        future = control.request(command)  # never blocks
        future.add_done_callback(lambda f: self._done(str(command), f))

    def _take(self) -> bool:
        """Whether this message is within SET_RATE a second (SET_BURST at once). Beyond, it is
        dropped unread and unanswered, said once in LOG_EVERY_S: a flood of 10,000 was read,
        logged and answered one by one, and its answers stopped the desk's own messages."""
        now = time.monotonic()
        self._budget = min(SET_BURST, self._budget + (now - self._refilled) * SET_RATE)
        self._refilled = now
        if self._budget >= 1.0:
            self._budget -= 1.0
            return True
        self._dropped += 1
        if now - self._dropped_said >= LOG_EVERY_S:
            self._dropped_said = now
            log.warning(
                "MQTT: %s: more than %d commands a second; %d dropped so far, unanswered",
                self.topic,
                SET_RATE,
                self._dropped,
            )
        return False

    def _done(self, command: str, future: Future[str]) -> None:
        error = future.exception()
        self._answer(command, error is None, str(error) if error else future.result())

    def _answer(self, command: str | None, ok: bool, message: str) -> None:
        self.publish(self.result_topic, {"command": command, "ok": ok, "message": message})


@dataclass(frozen=True)
class ControlEntity:
    """One Home Assistant discovery config for a control (button or select)."""

    topic: str
    config: dict[str, Any]

    @property
    def payload(self) -> bytes:
        return json.dumps(self.config, sort_keys=True).encode("utf-8")


def control_entities(
    *,
    desk: str,
    set_topic: str,
    availability_topic: str,
    layouts: list[str],
    state_topic: str | None = None,
    device: dict[str, Any],
    prefix: str = "homeassistant",
    node: str | None = None,
    origin: dict[str, Any] | None = None,
) -> list[ControlEntity]:
    """Discovery configs of the desk's controls: a button per command, a select of layouts
    (``node``: as for the desk's other configs; default from its name) that reads the running
    one from ``state_topic`` (without it the select only says what it sent)."""
    node = node or _OBJECT_ID.sub("_", desk)
    common: dict[str, Any] = {"command_topic": set_topic, "availability_topic": availability_topic}
    if origin is not None:  # Home Assistant's `origin`: this software, on every config
        common["origin"] = origin
    out = []
    for command, (object_id, name, icon) in BUTTONS.items():
        out.append(
            ControlEntity(
                f"{prefix}/button/{node}/{object_id}/config",
                {
                    **common,
                    "name": name,
                    "icon": icon,
                    "unique_id": f"hapticdesk_{node}_{object_id}",
                    "payload_press": json.dumps({"command": command}),
                    "device": device,
                },
            )
        )
    if len(layouts) > 1:
        out.append(
            ControlEntity(
                f"{prefix}/select/{node}/layout/config",
                {
                    **common,
                    "name": "Layout",
                    "icon": "mdi:view-dashboard-edit",
                    "unique_id": f"hapticdesk_{node}_layout",
                    "options": layouts,
                    "command_template": '{"command": "layout", "layout": "{{ value }}"}',
                    "device": device,
                    **(
                        {
                            "state_topic": state_topic,
                            # a state message without it (none so far) changes nothing
                            "value_template": "{{ value_json.layout if value_json.layout is"
                            " defined else '' }}",
                        }
                        if state_topic
                        else {}
                    ),
                },
            )
        )
    return out
