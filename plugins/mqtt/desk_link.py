"""The run's one MQTT connection, and the desk's place on the broker.

A run that uses MQTT at all (an ``mqtt`` action, an ``mqtt:`` section or ``--mqtt``) shares
one :class:`~.link.MqttLink`, opened on first use with the layout's settings (``--mqtt``
over its broker): its birth ``online`` and last will ``offline`` on
``<prefix>/availability``, ``<prefix>/set`` subscribed before it says it is online. A second
desk of the same name on the same broker is refused before it connects.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from hapticdesk.errors import ConfigError, Position
from hapticdesk.plugins.mqtt.control import SetTopic
from hapticdesk.plugins.mqtt.link import MqttLink
from hapticdesk.plugins.mqtt.message import Message
from hapticdesk.plugins.mqtt.oneshot import retained_payload
from hapticdesk.plugins.mqtt.sensors import DeskState
from hapticdesk.plugins.mqtt.settings import MqttSettings, settings_from_layout
from hapticdesk.plugins.mqtt.z2m import style_from_section
from hapticdesk.runtime.dispatcher import ActionContext

if TYPE_CHECKING:
    from hapticdesk.gestures.layout import Binding

SECTION = "mqtt"  # the layout's top-level section this plugin claims
LINK = "mqtt"  # the ActionContext.shared key of the run's connection


def broker_override(context: ActionContext) -> str | None:
    """``--mqtt URL``: the broker the command line puts over the layout's."""
    url = context.overrides.get(SECTION, {}).get("broker")
    return None if url is None else str(url)


def protocol_override(context: ActionContext) -> str | None:
    """The MQTT version a program that started the broker itself knows it speaks (the
    demo's embedded broker: "3.1.1"), over the layout's ``protocol:``; None otherwise."""
    protocol = context.overrides.get(SECTION, {}).get("protocol")
    return None if protocol is None else str(protocol)


def uses_mqtt(
    raw: Mapping[str, Any] | None, bindings: list[Binding], broker_url: str | None
) -> bool:
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
        protocol_override=protocol_override(context),
        relative_to=context.layout_path.parent if context.layout_path else None,
        where=raw.where(SECTION) if hasattr(raw, "where") and SECTION in raw else "the layout",
    )


def validate_section(value: Any, position: Position, layout_path: Path) -> None:
    """The layout's ``mqtt:`` section, checked as a run would read it (ConfigError if wrong)."""
    # the client id's default holds the desk name; any valid one checks the same
    settings_from_layout(value, desk="desk", relative_to=Path(layout_path).parent, where=position)
    style_from_section(value)


def section_of(context: ActionContext) -> Any:
    """The layout's ``mqtt:`` section as written (None without one)."""
    settings = getattr(context, "settings", None)
    return settings.get(SECTION) if settings is not None else None


def link_for(context: ActionContext) -> MqttLink:
    """The run's one MQTT connection, opened on first use."""
    link: MqttLink = context.shared(LINK, lambda: open_link(context))
    return link


def open_link(context: ActionContext) -> MqttLink:
    """A connection for the run (see the module docstring), started."""
    settings = settings_for(context)
    topics = settings.topics(context.desk_name)
    availability = topics.availability
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
    link.subscribe(topics.set, SetTopic(None, link.announce, topics.set))
    return link.start()


def refuse_a_second_desk(settings: MqttSettings, desk: str, availability: str) -> None:
    """ConfigError when another desk of this name is online on this broker: two processes
    with one client id knock each other off the broker, and one identity in Home Assistant
    would merge both desks."""
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


def desk_state(context: ActionContext) -> DeskState:
    """The run's latest sensor values (shared by the sensor and gesture publishers)."""
    state: DeskState = context.shared("mqtt-desk-state", DeskState)
    return state
