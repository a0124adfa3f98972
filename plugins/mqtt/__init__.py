"""The ``mqtt`` action, and the desk as a device on the network.

    mqtt:                                   # optional; defaults shown
      broker: mqtt://localhost:1883         # mqtts:// for TLS
      username: desk
      password_env: DESK_MQTT_PASSWORD      # or password_file: secrets/mqtt.txt
      tls: {ca: ca.crt, cert: desk.crt, key: desk.key}
      client_id: hapticdesk-<desk>            # the desk prefix with - for /
      keepalive: 60
      qos: 2                                # 2: a TOGGLE is delivered exactly once
      retain: false
      discovery: false                      # Home Assistant: true (= entity) or device
      base_topic: hapticdesk                # topics under <base_topic>/<desk>
      prefix: hapticdesk/site1/floor2/study # or the desk's whole prefix (not with base_topic)
      protocol: auto                        # MQTT 5 where the broker speaks it, else 3.1.1
      expiry_s: 60                          # MQTT 5: a command undelivered this long is dropped
      action_style: hapticdesk              # or zigbee2mqtt: lamp_single, brightness_move_up
      zigbee2mqtt_slide: step               # or move (brightness_move_*/brightness_stop)
    desk_name: study                        # in topics; default: the profile's name
    bindings:
      - gesture: tap
        region: lamp
        do: {mqtt: {topic: zigbee2mqtt/desk_lamp/set, payload: {state: TOGGLE}}}

The plugin claims the layout's ``mqtt:`` section (``register_layout_sections``: checked
while the layout loads, so ``hapticdesk check`` refuses what ``run`` would) and provides
``hapticdesk demo`` (``register_commands``). When a run uses MQTT (an ``mqtt`` action, an
``mqtt:`` section or ``--mqtt``), its ``event_sink`` publishes every gesture to
``<prefix>/action`` (by default ``hapticdesk/<desk>``) as a Zigbee2MQTT-style string
(``lamp_tap``) and in full to ``<prefix>/event`` (JSON), with the retained availability
``<prefix>/availability`` (``online``; ``offline`` as last will), and the desk's state JSON
(with ``action``) on ``<prefix>`` itself; a desk whose availability is already ``online``
(another process of the same name) is refused at start. ``discovery: true`` (or ``entity``, or
``device`` for one config per desk) announces the desk to Home Assistant (:mod:`.homeassistant`),
at the start and after every layout switch (:mod:`.announce`); ``action_style: zigbee2mqtt``
sends the actions
Zigbee2MQTT's remotes send (:mod:`.z2m`). Its ``control_channel`` listens on ``<prefix>/set``
(:mod:`.control`).
paho is imported only when the connection is opened.
"""

from __future__ import annotations

import contextlib
from pathlib import Path
from typing import Any

from hapticdesk.errors import ConfigError, Position
from hapticdesk.files.marked_values import as_flag
from hapticdesk.gestures.event import GestureEvent
from hapticdesk.hookspecs import hookimpl
from hapticdesk.plugins.action_options import options_mapping, text, where
from hapticdesk.plugins.mqtt.link import MqttLink
from hapticdesk.plugins.mqtt.message import Message
from hapticdesk.plugins.mqtt.settings import (
    DEFAULT_BASE_TOPIC,
    MqttSettings,
    qos_of,
    settings_from_layout,
)
from hapticdesk.plugins.mqtt.z2m import Zigbee2MqttActions, style_from_section
from hapticdesk.plugins.templating import (
    CHECK_EVENTS,
    Template,
    TemplatedValue,
    compile_template,
    compile_value,
    event_variables,
)
from hapticdesk.runtime.dispatcher import ActionContext

LINK = "mqtt"  # the ActionContext.shared key of the run's connection


SECTION = "mqtt"  # the layout's top-level section this plugin claims


def broker_override(context: ActionContext) -> str | None:
    """``--mqtt URL``: the broker the command line puts over the layout's."""
    url = context.overrides.get(SECTION, {}).get("broker")
    return None if url is None else str(url)


def uses_mqtt(raw: Any, bindings: Any, broker_url: str | None) -> bool:
    """Whether a run needs a broker: an ``mqtt`` action, an ``mqtt:`` section or ``--mqtt``."""
    if broker_url is not None or (raw is not None and SECTION in raw):
        return True
    return any(use.name == "mqtt" for b in bindings for use in b.actions)


def settings_for(context: ActionContext) -> MqttSettings:
    """The run's MQTT settings from the layout's ``mqtt:`` and ``--mqtt``."""
    raw = context.settings
    return settings_from_layout(
        raw.get(SECTION),
        desk=context.desk_name,
        url_override=broker_override(context),
        relative_to=context.layout_path.parent if context.layout_path else None,
        where=raw.where(SECTION) if hasattr(raw, "where") and SECTION in raw else "the layout",
    )


def validate_section(value: Any, position: Position, layout_path: Path) -> None:
    """The layout's ``mqtt:`` section, checked as a run would read it (ConfigError if wrong)."""
    # the client id's default holds the desk name; any valid one checks the same
    settings_from_layout(value, desk="desk", relative_to=Path(layout_path).parent, where=position)
    style_from_section(value)


def desk_topic(settings: MqttSettings, desk: str, leaf: str) -> str:
    """One of the desk's own topics: ``<prefix>/<leaf>`` (see ``prefix`` and ``base_topic``)."""
    return f"{settings.desk_prefix(desk)}/{leaf}"


def ha_node(settings: MqttSettings, desk: str) -> str:
    """The desk's node id in Home Assistant (discovery topics, device identifier).

    From the desk's name under the default ``hapticdesk/<desk>`` topics, as always; from the
    desk's whole topic prefix when ``prefix`` or another ``base_topic`` is set, so two desks
    of one name on two floors (``hapticdesk/site1/floor2/study``, ``…/floor3/study``, given
    either way) are two devices, not one."""
    from hapticdesk.plugins.mqtt.discovery import object_id

    if settings.prefix is None and settings.base_topic == DEFAULT_BASE_TOPIC:
        return object_id(desk)
    return object_id(settings.desk_prefix(desk))


def _section(context: Any) -> Any:
    """The layout's ``mqtt:`` section as written (None without one)."""
    settings = getattr(context, "settings", None)
    return settings.get(SECTION) if settings is not None else None


def layout_names(layout: Any) -> list[str]:
    """The names a run can switch among (``default`` and the layout's ``layouts:``), or none."""
    named = getattr(layout, "named_layouts", {}) or {}
    return ["default", *named] if named else []


def discovery_for(
    context: ActionContext, settings: MqttSettings, layouts: list[str] | None = None
) -> list[Any]:
    """The run's Home Assistant discovery configs, one per trigger and entity: the gestures,
    sensors and connectivity (:mod:`.homeassistant`) and the desk's controls
    (:mod:`.control`); each has ``topic``, ``config`` and ``payload``. ``layouts``: the
    select's options (default: the current layout's names; a run keeps those it started
    with, as the runtime does)."""
    from hapticdesk.plugins.mqtt.control import control_entities
    from hapticdesk.plugins.mqtt.homeassistant import (
        ORIGIN,
        DeskTopics,
        device_info,
        discovery_configs,
    )

    desk = context.desk_name
    node = ha_node(settings, desk)
    model = f"hapticdesk on {getattr(context.profile, 'name', 'a desk')}"
    topics = DeskTopics(settings.desk_prefix(desk))
    configs: list[Any] = discovery_configs(
        getattr(context.layout, "bindings", []),
        desk=desk,
        model=model,
        topics=topics,
        prefix=settings.discovery_prefix,
        qos=min(settings.qos, 1),
        node=node,
    )
    controls = control_entities(
        desk=desk,
        set_topic=desk_topic(settings, desk, "set"),
        state_topic=topics.prefix,
        availability_topic=topics.availability,
        layouts=layout_names(context.layout) if layouts is None else layouts,
        device=device_info(desk, model, node),
        prefix=settings.discovery_prefix,
        node=node,
        origin=ORIGIN,
    )
    return configs + controls


def link_for(context: ActionContext) -> MqttLink:
    """The run's one MQTT connection, opened on first use."""
    return context.shared(LINK, lambda: open_link(context))


def open_link(context: ActionContext) -> MqttLink:
    settings = settings_for(context)
    availability = desk_topic(settings, context.desk_name, "availability")
    refuse_a_second_desk(settings, context.desk_name, availability)
    birth = [Message(availability, b"online", 1, True, command=False)]
    birth_again_on = None
    if settings.discovery:
        # the discovery configs join the birth once announced (:mod:`.announce`); Home
        # Assistant forgets non-retained state when it restarts, and says so here
        birth_again_on = (f"{settings.discovery_prefix}/status", b"online")
    link = MqttLink(
        settings,
        will=Message(availability, b"offline", 1, True, command=False),
        birth=birth,
        birth_again_on=birth_again_on,
    )
    # `set` before the link connects: it is granted before the desk says `online` (Home
    # Assistant's select sends at once; subscribed when the run began, a second later, the
    # desk had missed it). The run's control queue joins in the control_channel hook.
    from hapticdesk.plugins.mqtt.control import SetTopic

    topic = desk_topic(settings, context.desk_name, "set")
    link.subscribe(topic, SetTopic(None, link.announce, topic))
    return link.start()


def refuse_a_second_desk(settings: MqttSettings, desk: str, availability: str) -> None:
    """ConfigError when another desk of this name is online on this broker: two processes
    with one client id knock each other off the broker, and one identity in Home Assistant
    would merge both desks."""
    from hapticdesk.plugins.mqtt.oneshot import retained_payload

    if retained_payload(settings, availability) != b"online":
        return
    raise ConfigError(
        "mqtt",
        f"another desk named `{desk}` is online at {settings.url} ({availability} is "
        "`online`); give this desk its own name (`desk_name:` in its layout) or its own topic "
        "(`prefix:` in the layout's `mqtt:`). If no such desk runs, the last one was cut off "
        f"without its last will; clear it with: mosquitto_pub -h {settings.host} -p "
        f"{settings.port} -r -n -t {availability}",
    )


# --- the action -------------------------------------------------------------------------------


def parse_options(
    options: Any, position: Position | str
) -> tuple[Template, TemplatedValue | None, int | None, bool | None]:
    m = options_mapping(
        options, position, "`mqtt`", {"topic", "payload", "qos", "retain"}, {"topic"}
    )
    topic = text(m, "topic", "`mqtt`")
    compiled = compile_template(topic, m.where("topic"), "`topic` of `mqtt`")
    if compiled.compiled is None:
        _check_topic(topic, m.where("topic"))
    payload = (
        compile_value(m["payload"], m.where("payload"), "`payload` of `mqtt`")
        if "payload" in m
        else None
    )
    qos = qos_of(m, "`mqtt`", -1)
    retain = as_flag(m.get("retain"))
    if "retain" in m and not isinstance(retain, bool):
        raise ConfigError(m.where("retain"), "`retain` of `mqtt` must be true or false")
    return compiled, payload, None if qos < 0 else qos, retain


def validate(options: Any, position: Position | str) -> None:
    parse_options(options, position)


def _check_topic(topic: str, where: Position | str) -> None:
    if not topic or any(c in topic for c in "+#\0"):
        raise ConfigError(
            where, f"an MQTT topic to publish to must not be empty or hold + or #, found {topic!r}"
        )


class MqttAction:
    """Publishes the rendered payload to the rendered topic on the run's connection."""

    timeout_s = 2.0  # publishing only queues; it never waits for the broker

    def __init__(self, options: Any, context: ActionContext) -> None:
        self.topic, self.payload, self.qos, self.retain = parse_options(
            options, where(options, "`mqtt`")
        )
        self.desk = context.desk_name
        self.link = link_for(context)

    def __call__(self, event: GestureEvent) -> None:
        variables = event_variables(event, self.desk)
        topic = self.topic.render(variables)
        _check_topic(topic, f"topic template {self.topic.text!r}")
        if self.payload is None:
            payload: Any = {**event.to_dict(), "action": event.action_name}
        else:
            payload = self.payload.render(variables)
        self.link.publish(topic, payload, qos=self.qos, retain=self.retain)


def announcer_for(context: ActionContext) -> Any:
    """The run's :class:`~.announce.Announcer` (with ``discovery``), started on first use."""
    # (the link and the state first: ``shared`` holds its lock while it creates a resource)
    link, state = link_for(context), desk_state(context)
    return context.shared("mqtt-announcer", lambda: start_announcer(context, link, state))


def start_announcer(context: ActionContext, link: MqttLink, state: Any) -> Any:
    from hapticdesk.plugins.mqtt.announce import Announcer

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


class DeskPublisher:
    """Publishes every gesture to the desk's ``action``, ``event`` and state topics (a
    dispatcher sink), each message with the run's count of events ``seq`` (two identical
    taps in a row are two messages that differ: Home Assistant drops a state equal to the
    last), and with ``discovery`` announces the desk to Home Assistant."""

    timeout_s = 2.0

    def __init__(self, context: ActionContext) -> None:
        self.link = link_for(context)
        settings = self.link.settings
        self.state_topic = settings.desk_prefix(context.desk_name)
        self.action_topic = desk_topic(settings, context.desk_name, "action")
        self.event_topic = desk_topic(settings, context.desk_name, "event")
        style, slide = style_from_section(_section(context))
        self.z2m = Zigbee2MqttActions(slide) if style == "zigbee2mqtt" else None
        self.state = desk_state(context)
        self.seq = 0
        if settings.discovery:
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


@hookimpl
def event_sink(layout: Any, context: ActionContext) -> DeskPublisher | None:
    """The desk's own topics, when the run uses MQTT at all."""
    if uses_mqtt(layout.raw, layout.bindings, broker_override(context)):
        return DeskPublisher(context)
    return None


def desk_state(context: ActionContext) -> Any:
    """The run's latest sensor values (shared by the sensor and gesture publishers)."""
    from hapticdesk.plugins.mqtt.sensors import DeskState

    return context.shared("mqtt-desk-state", DeskState)


@hookimpl
def contact_sink(layout: Any, context: ActionContext) -> Any:
    """With ``discovery``: force, touch position, resting load and occupancy on the desk's
    state topic, throttled (:mod:`.sensors`), for Home Assistant's sensors, and a look, once
    a block, for another layout in the run (then the desk is announced again); with or
    without it, ``paused`` there when the desk is paused or resumed."""
    if not uses_mqtt(layout.raw, layout.bindings, broker_override(context)):
        return None
    link = link_for(context)
    from hapticdesk.plugins.mqtt.sensors import SensorPublisher

    topic = link.settings.desk_prefix(context.desk_name)
    sensors = SensorPublisher(
        desk_state(context),
        lambda payload: link.publish(topic, payload, qos=0, retain=False),
        sensors=link.settings.discovery,
    )
    if not link.settings.discovery:
        return sensors
    from hapticdesk.plugins.mqtt.announce import LayoutWatch

    watch = LayoutWatch(context, announcer_for(context).layout_changed)

    def sink(summary: Any) -> None:
        watch(summary)
        sensors(summary)

    return sink


@hookimpl
def control_channel(control: Any, layout: Any, context: ActionContext) -> None:
    """``<prefix>/set``: commands for the running desk (see :mod:`.control`)."""
    if not uses_mqtt(layout.raw, layout.bindings, broker_override(context)):
        return
    from hapticdesk.plugins.mqtt.control import SetTopic

    link = link_for(context)
    commands = link.handler(desk_topic(link.settings, context.desk_name, "set"))
    if isinstance(commands, SetTopic):  # subscribed when the link opened (open_link)
        commands.attach(control)


@hookimpl
def register_layout_sections(register: Any) -> None:
    # the broker's address, credentials and TLS files: the operator's alone (a page that
    # could change the broker would send the password there at the next start)
    register(
        SECTION,
        validate_section,
        "the MQTT broker, credentials, TLS, QoS and topics",
        operator_only=True,
    )


@hookimpl
def register_commands(register: Any) -> None:
    register(
        "demo",
        "hapticdesk.plugins.mqtt.demo",
        "the whole path on a simulated desk and a local broker",
    )


@hookimpl
def register_actions(register: Any) -> None:
    register(
        "mqtt",
        MqttAction,
        "publish to an MQTT broker (templated topic and payload, QoS 0/1/2, TLS)",
        validate=validate,
        check_events=CHECK_EVENTS,
        options={
            "topic": {"kind": "text", "required": True, "help": "e.g. zigbee2mqtt/lamp/set"},
            "payload": {"kind": "mapping", "help": 'JSON, e.g. {"state": "TOGGLE"}'},
            "qos": {"kind": "integer", "choices": [0, 1, 2], "help": "the layout's by default"},
            "retain": {"kind": "bool", "choices": [True, False], "help": "keep on the broker"},
        },
    )
