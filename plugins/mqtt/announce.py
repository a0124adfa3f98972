"""Telling Home Assistant what the desk is, in an order it accepts, at the start and after
every layout switch or reload.

Home Assistant refuses a device trigger whose type and subtype another trigger of the device
still holds ("conflicts with existing device trigger"), so the configs that go come first:
:func:`plan` turns what the broker retains for this desk (``<prefix>/+/<node>/+/config`` and
``<prefix>/device/<node>/config``) and what the running layout wants into *steps*;
:func:`publish_steps` sends each step on a short connection of its own and waits for the
broker's acknowledgement of all of it (and :data:`STEP_PAUSE_S` for Home Assistant) before the
next, so a trigger is cleared before its successor arrives (they had gone out 70 ms the other
way round, and the long press fired nothing until the next start).

Two shapes of discovery (``discovery: entity`` or ``device`` in the layout's ``mqtt:``):

- entity: one retained config per trigger and entity (``<prefix>/<component>/<node>/<id>/
  config``); any Home Assistant with MQTT discovery;
- device: one retained config for the whole desk (``<prefix>/device/<node>/config``, its
  ``components`` keyed by the same ids); Home Assistant 2024.11 or later.

Moving between them keeps every entity, its history and its automations (Home Assistant's
"migration from single component to device-based discovery"): a ``{"migrate_discovery":
true}`` to each config of the old shape (Home Assistant unloads the entity and keeps it in
its registries), then an empty payload to each of them (nothing left for a restart to
rediscover), then the configs of the new shape under the same ids (the entities come back by
their ``unique_id``). A component that left a device config is first sent as ``{"platform":
...}`` alone (Home Assistant removes it), then left out.

Back from the device config to one config each, Home Assistant (2025.4.4, checked) warns of
either order of clearing the device config: emptied before the new configs, "No device
components to cleanup"; after them (as its log advises), "Received a conflicting MQTT
discovery message" for every entity, as the emptied device config names them all. So on an
MQTT 5 broker the migration message is itself the clearing: retained with an expiry of
:data:`MIGRATE_EXPIRY_S`, Home Assistant gets it at once and the broker then drops it, and no
empty payload is sent. On MQTT 3.1.1 it is emptied before the new configs (one warning).

:class:`Announcer` runs this on its own thread at the start and whenever the contact sink
sees another layout in the run's context; the link keeps the last configs to send again when
it reconnects or Home Assistant comes back (``homeassistant/status``).
"""

from __future__ import annotations

import json
import logging
import ssl
import threading
import time
from collections.abc import Callable, Sequence
from typing import Any

from hapticdesk.plugins.mqtt.oneshot import RetainedSweep
from hapticdesk.plugins.mqtt.paho_clients import message_expiry, new_client
from hapticdesk.plugins.mqtt.settings import MqttSettings

log = logging.getLogger(__name__)

SWEEP_TIMEOUT_S = 5.0
#: after a step that clears or migrates, Home Assistant gets this long before the next one
STEP_PAUSE_S = 0.5
MODES = ("entity", "device")
MIGRATE = json.dumps({"migrate_discovery": True}).encode()
#: how long the broker keeps a migration message (MQTT 5): Home Assistant gets it at once;
#: a Home Assistant that restarts later must not find it beside the new configs
MIGRATE_EXPIRY_S = 5

Step = list[tuple[str, bytes]]  # (topic, payload) published retained, acknowledged together


def device_topic(prefix: str, node: str) -> str:
    """The desk's one config in device-based discovery."""
    return f"{prefix}/device/{node}/config"


def device_payload(configs: Sequence[Any], *, prefix: str, node: str) -> dict[str, Any]:
    """Per-entity configs (``topic``, ``config``) as one device-based discovery payload: the
    ``device`` and ``origin`` once, each config under ``components`` by its object id with
    its ``platform`` (the component in its topic)."""
    components: dict[str, Any] = {}
    root: dict[str, Any] = {}
    for c in configs:
        _, component, _node, object_id, _ = c.topic.rsplit("/", 4)
        config = dict(c.config)
        root["device"] = config.pop("device")
        root["origin"] = config.pop("origin")
        components[object_id] = {"platform": component, **config}
    return {**root, "components": components}


def plan(
    found: dict[str, bytes],
    configs: Sequence[Any],
    *,
    mode: str,
    prefix: str,
    node: str,
    mqtt5: bool = False,
) -> list[Step]:
    """The steps that take what the broker retains for this desk (``found``: topic ->
    payload) to ``configs`` (per-entity ``topic``/``payload``/``config``) in ``mode``.
    ``mqtt5``: migration messages expire (:func:`publish_steps` with ``mqtt5``), so the
    device config is not emptied after its migration message."""
    own_device = device_topic(prefix, node)
    entity_found = sorted(t for t in found if t != own_device)
    steps: list[Step] = []
    if mode == "entity":
        wanted = {c.topic: c.payload for c in configs}
        if own_device in found:  # from device-based discovery back to one config each
            steps.append([(own_device, MIGRATE)])
            if not mqtt5:  # (Home Assistant warns; see the module docstring)
                steps.append([(own_device, b"")])
        stale = [t for t in entity_found if t not in wanted]
        if stale:
            steps.append([(t, b"") for t in stale])
        steps.append(sorted(wanted.items()))
        return steps
    new = device_payload(configs, prefix=prefix, node=node)
    if entity_found:  # from one config each to one device config
        steps += [[(t, MIGRATE) for t in entity_found], [(t, b"") for t in entity_found]]
    old = _components(found.get(own_device))
    gone = {k: v for k, v in old.items() if k not in new["components"]}
    if gone:
        emptied = {**old, **{k: {"platform": v.get("platform")} for k, v in gone.items()}}
        previous = json.loads(found[own_device])
        steps.append([(own_device, _json({**previous, "components": emptied}))])
    steps.append([(own_device, _json(new))])
    return steps


def _components(payload: bytes | None) -> dict[str, Any]:
    try:
        components = json.loads(payload or b"{}").get("components", {})
    except (ValueError, AttributeError):
        return {}
    return components if isinstance(components, dict) else {}


def _json(value: Any) -> bytes:
    return json.dumps(value, sort_keys=True).encode("utf-8")


def publish_steps(
    settings: MqttSettings,
    prefix: str,
    node: str,
    make_steps: Callable[[dict[str, bytes]], list[Step]],
    *,
    mqtt5: bool = False,
) -> list[Step] | None:
    """Read what the broker retains for this desk, and publish ``make_steps(found)`` one step
    after another (each acknowledged, then :data:`STEP_PAUSE_S` when another follows); the
    steps sent, or None when the broker could not be reached or did not answer (said in the
    log: the run goes on, and the link announces its configs when it connects). ``mqtt5``:
    in MQTT 5, a migration message retained for :data:`MIGRATE_EXPIRY_S` only."""
    sweep = RetainedSweep([f"{prefix}/+/{node}/+/config", device_topic(prefix, node)], node)
    client = _sweep_client(settings, mqtt5, sweep)
    try:
        client.connect(settings.host, settings.port, settings.keepalive)
    except (OSError, ssl.SSLError, ValueError) as err:
        log.warning("MQTT: Home Assistant discovery not announced (%s)", err)
        return None
    client.loop_start()
    try:
        if not sweep.done.wait(SWEEP_TIMEOUT_S):
            log.warning("MQTT: Home Assistant discovery not announced (no answer in time)")
            return None
        client.unsubscribe(sweep.patterns)  # our own messages must not come back as found
        steps = make_steps(dict(sweep.found))
        _publish(client, steps, message_expiry(MIGRATE_EXPIRY_S) if mqtt5 else None)
        cleared = [t for step in steps for t, p in step if not p]
        if cleared:
            log.info("MQTT: cleared %d old discovery config(s): %s", len(cleared), cleared)
        return steps
    finally:
        client.disconnect()
        client.loop_stop()


def _sweep_client(settings: MqttSettings, mqtt5: bool, sweep: RetainedSweep) -> Any:
    """A paho client of its own for the announcement, with ``sweep``'s callbacks."""
    client = new_client(  # (MQTT 5: a clean start, connect's default)
        settings, mqtt5=mqtt5, clean_session=True, client_id=f"{settings.client_id}-discovery"[:128]
    )
    client.on_connect = sweep.on_connect
    client.on_subscribe = sweep.on_subscribe
    client.on_message = sweep.on_message
    return client


def _publish(client: Any, steps: list[Step], expiring: Any) -> None:
    """Each step retained and acknowledged, then :data:`STEP_PAUSE_S` before the next; a
    migration message with ``expiring`` (MQTT 5 properties, or None)."""
    for i, step in enumerate(steps):
        infos = [
            client.publish(topic, payload, qos=1, retain=True,
                           properties=expiring if payload == MIGRATE else None)
            for topic, payload in step
        ]  # fmt: skip
        for info in infos:
            info.wait_for_publish(SWEEP_TIMEOUT_S)
        if i + 1 < len(steps):
            time.sleep(STEP_PAUSE_S)


class Announcer:
    """Announces the desk to Home Assistant on a thread of its own: at :meth:`start`, and
    again after :meth:`layout_changed` (a switch or reload seen by the contact sink).

    ``configs()`` gives the running layout's per-entity configs; ``keep(messages)`` hands the
    final configs to the link to send again on reconnects; ``announced()`` runs after each
    announcement (the desk's state with its layout name); ``ready(timeout)`` says whether the
    desk's link is connected with its ``set`` subscription granted: nothing is announced
    before (Home Assistant would offer controls whose commands reach no one); ``mqtt5()``
    whether the broker speaks MQTT 5 (the link's connection found out)."""

    def __init__(
        self,
        settings: MqttSettings,
        *,
        node: str,
        mode: str,
        configs: Callable[[], Sequence[Any]],
        keep: Callable[[Step], None],
        announced: Callable[[], None] = lambda: None,
        ready: Callable[[float], bool] = lambda timeout: True,
        mqtt5: Callable[[], bool] = lambda: False,
    ) -> None:
        if mode not in MODES:
            raise ValueError(f"mode must be one of {MODES}, found {mode!r}")
        self.settings = settings
        self.node = node
        self.mode = mode
        self._configs = configs
        self._keep = keep
        self._announced = announced
        self._ready = ready
        self._mqtt5 = mqtt5
        self._wake = threading.Event()
        self._pending = False  # an announcement is asked for
        self._closing = False
        self.rounds = 0  # announcements made (for tests)
        self._thread = threading.Thread(target=self._run, name="mqtt discovery", daemon=True)

    def start(self) -> Announcer:
        self.layout_changed()
        self._thread.start()
        return self

    def layout_changed(self) -> None:
        """Announce again (never blocks: the sensing thread calls it)."""
        self._pending = True
        self._wake.set()

    def close(self, timeout: float = 10.0) -> None:
        """Make the announcement asked for or under way (bounded by ``timeout``), then stop:
        a run shorter than its first announcement still tells Home Assistant."""
        self._closing = True
        self._wake.set()
        if self._thread.is_alive():
            self._thread.join(max(timeout, SWEEP_TIMEOUT_S))

    def _run(self) -> None:
        while True:
            self._wake.wait()
            self._wake.clear()
            # `while`, not `if`: a switch seen during an announcement asks for another, which
            # must go out before a close that came meanwhile ends the thread (a short run that
            # switched its layout had left Home Assistant with the old layout's triggers)
            while self._pending and self._wait_ready():
                self._pending = False
                try:
                    self._announce()
                except Exception:  # a broker quirk must not end the run; the next switch retries
                    log.exception("MQTT: announcing the desk to Home Assistant failed")
            if self._closing:
                return

    def _wait_ready(self) -> bool:
        """Wait until the link is ready; when the run closes first, SWEEP_TIMEOUT_S more at
        most (a run that never reached its broker announces nothing)."""
        while not self._ready(0.1):
            if self._closing:
                return self._ready(SWEEP_TIMEOUT_S)
        return True

    def _announce(self) -> None:
        prefix = self.settings.discovery_prefix
        configs = list(self._configs())

        mqtt5 = self._mqtt5()

        def steps(found: dict[str, bytes]) -> list[Step]:
            return plan(found, configs, mode=self.mode, prefix=prefix, node=self.node, mqtt5=mqtt5)

        sent = publish_steps(self.settings, prefix, self.node, steps, mqtt5=mqtt5)
        final = sent[-1] if sent else steps({})[-1]
        self._keep(final)
        self.rounds += 1
        self._announced()


class LayoutWatch:
    """A contact sink (the sensing thread, once per block, O(1)): when the run's context holds
    another layout than before (a switch, a reload, a save from the page: the runtime swaps
    it between two blocks), says so to ``changed``."""

    def __init__(self, context: Any, changed: Callable[[], None]) -> None:
        self.context = context
        self.changed = changed
        self._seen = context.layout

    def __call__(self, summary: Any) -> None:
        layout = self.context.layout
        if layout is not self._seen:
            self._seen = layout
            self.changed()
