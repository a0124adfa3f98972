"""What the desk says about itself on the broker: every gesture on its own topics and, with
``discovery``, its announcement to Home Assistant.

Every gesture goes to ``<prefix>/action`` as a Zigbee2MQTT-style string (``lamp_tap``, or the
actions Zigbee2MQTT's remotes send with ``action_style: zigbee2mqtt``: :mod:`.z2m`), in full
to ``<prefix>/event`` (JSON), and with the desk's state to ``<prefix>`` itself. With
``discovery`` an :class:`~.announce.Announcer` tells Home Assistant what the desk is, at the
start and after every layout switch.
"""

from __future__ import annotations

import contextlib
from pathlib import Path
from typing import Any

from hapticdesk.gestures.event import GestureEvent
from hapticdesk.plugins.mqtt.announce import Announcer
from hapticdesk.plugins.mqtt.desk_link import desk_state, link_for, section_of
from hapticdesk.plugins.mqtt.homeassistant import discovery_for, ha_node, layout_names
from hapticdesk.plugins.mqtt.link import MqttLink
from hapticdesk.plugins.mqtt.message import Message
from hapticdesk.plugins.mqtt.sensors import DeskState
from hapticdesk.plugins.mqtt.z2m import Zigbee2MqttActions, style_from_section
from hapticdesk.runtime.dispatcher import ActionContext

ANNOUNCER = "mqtt-announcer"  # the ActionContext.shared key of the run's announcer


class DeskPublisher:
    """Publishes every gesture to the desk's ``action``, ``event`` and state topics (a
    dispatcher sink), each message with the run's count of events ``seq`` (two identical
    taps in a row are two messages that differ: Home Assistant drops a state equal to the
    last), and with ``discovery`` announces the desk to Home Assistant."""

    timeout_s = 2.0

    def __init__(self, context: ActionContext) -> None:
        self.link = link_for(context)
        topics = self.link.settings.topics(context.desk_name)
        self.state_topic = topics.prefix
        self.action_topic = topics.action
        self.event_topic = topics.event
        style, slide = style_from_section(section_of(context))
        self.z2m = Zigbee2MqttActions(slide) if style == "zigbee2mqtt" else None
        self.state = desk_state(context)
        self.seq = 0
        if self.link.settings.discovery:
            announcer_for(context)

    def __call__(self, event: GestureEvent) -> None:
        action = event.action_name
        self.seq += 1
        whole = {**event.to_dict(), "action": action, "seq": self.seq}
        payloads = [whole] if self.z2m is None else self.z2m(event)
        for payload in payloads:
            self.link.publish(self.action_topic, payload["action"], retain=False)
            self.link.publish(
                self.state_topic,
                {**self.state.snapshot(), **payload, "seq": self.seq},
                retain=False,
            )
        self.link.publish(self.event_topic, whole, retain=False)


def announcer_for(context: ActionContext) -> Announcer:
    """The run's :class:`~.announce.Announcer` (with ``discovery``), started on first use."""
    # (the link and the state first: ``shared`` holds its lock while it creates a resource)
    link, state = link_for(context), desk_state(context)
    announcer: Announcer = context.shared(ANNOUNCER, lambda: start_announcer(context, link, state))
    return announcer


def start_announcer(context: ActionContext, link: MqttLink, state: DeskState) -> Announcer:
    """An announcer of the run's layouts on ``link``, the desk's state saying which runs."""
    settings = link.settings
    state_topic = settings.desk_prefix(context.desk_name)
    # the select's options and their files are those the run started with (as the runtime's)
    names = layout_names(context.layout)
    paths = {
        name: _resolved(path)
        for name, path in {"default": context.layout_path, **_named(context.layout)}.items()
    }

    def current_layout() -> str | None:
        here = _resolved(context.layout_path)
        return next((name for name, path in paths.items() if path == here), None)

    def keep(step: list[tuple[str, bytes]]) -> None:
        link.keep_announcing([Message(t, p, 1, True, command=False) for t, p in step if p])

    def announced() -> None:
        # the select reads the layout from the desk's state (and the sensors read theirs)
        state.update(layout=current_layout())
        with contextlib.suppress(RuntimeError):  # the link closed under a late announcement
            link.publish(state_topic, state.snapshot(), qos=0, retain=False)

    state.update(layout=current_layout())
    return Announcer(
        settings,
        node=ha_node(settings, context.desk_name),
        mode=settings.discovery_mode,
        configs=lambda: discovery_for(context, settings, names),
        keep=keep,
        announced=announced,
        ready=link.wait_ready,
        mqtt5=lambda: link.mqtt5,
    ).start()


def _named(layout: Any) -> dict[str, Any]:
    return dict(getattr(layout, "named_layouts", {}) or {})


def _resolved(path: Any) -> Path | None:
    return None if path is None else Path(path).resolve()
