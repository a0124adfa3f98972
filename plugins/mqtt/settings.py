"""The MQTT plugin's settings: the layout's ``mqtt:`` section checked into :class:`MqttSettings`
(broker URL, login from the environment or a file, TLS, QoS, topics, queue, protocol), and the
desk's own topics (:class:`DeskTopics`). No connection is made here: clients are made by
:mod:`.paho_clients`, the desk's connection is :mod:`.link`.
"""

from __future__ import annotations

import os
import urllib.parse
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hapticdesk.errors import ConfigError, Position
from hapticdesk.files.file_safety import check_confined
from hapticdesk.files.marked_values import MarkedDict, as_flag
from hapticdesk.files.validators import check_keys, number, require_mapping

DEFAULT_QUEUE_SIZE = 1000
#: topics under ``<base_topic>/<desk>`` by default; a desk keeps its Home Assistant node id
#: from its name alone there (see ``ha_node``)
DEFAULT_BASE_TOPIC = "hapticdesk"
#: the most messages a queue may hold (each a few hundred bytes: about 100 MB at most)
MAX_QUEUE_SIZE = 1_000_000
_MQTT_KEYS = {
    "broker",
    "username",
    "password_env",
    "password_file",
    "tls",
    "client_id",
    "keepalive",
    "qos",
    "retain",
    "discovery",
    "discovery_prefix",
    "base_topic",
    "prefix",
    "queue_size",
    "protocol",
    "expiry_s",
    # read by the plugin's __init__ (plugins/mqtt/z2m.py: style_from_section)
    "action_style",
    "zigbee2mqtt_slide",
}
#: ``protocol:`` values: MQTT 5 where the broker speaks it (else 3.1.1), or one of them
PROTOCOLS = ("auto", "5", "3.1.1")
DEFAULT_EXPIRY_S = 60


@dataclass(frozen=True)
class MqttSettings:
    """The layout's ``mqtt:`` section, checked. ``password`` is never shown."""

    host: str = "localhost"
    port: int = 1883
    tls: bool = False
    username: str | None = None
    password: str | None = field(default=None, repr=False)
    ca: Path | None = None
    cert: Path | None = None
    key: Path | None = None
    client_id: str = "hapticdesk"
    keepalive: int = 60
    qos: int = 2
    retain: bool = False
    discovery: bool = False
    #: how the desk is announced with ``discovery``: ``entity`` (one config per trigger and
    #: entity, any Home Assistant) or ``device`` (one config, Home Assistant 2024.11 or later)
    discovery_mode: str = "entity"
    discovery_prefix: str = "homeassistant"
    base_topic: str = DEFAULT_BASE_TOPIC
    #: the desk's whole topic prefix when given (``hapticdesk/site1/floor2/study``); else
    #: ``<base_topic>/<desk>``
    prefix: str | None = None
    queue_size: int = DEFAULT_QUEUE_SIZE
    protocol: str = "auto"
    #: MQTT 5: a command the broker could not deliver within this many seconds is dropped
    #: (a TOGGLE must not switch a lamp an hour late); 0 keeps it until delivered
    expiry_s: int = DEFAULT_EXPIRY_S

    def desk_prefix(self, desk: str) -> str:
        """The topic prefix of this desk's own topics (``action``, ``event``, ``set`` …)."""
        return self.prefix if self.prefix is not None else f"{self.base_topic}/{desk}"

    def topics(self, desk: str) -> DeskTopics:
        """The desk's own topics."""
        return DeskTopics(self.desk_prefix(desk))

    @property
    def url(self) -> str:
        """The broker as a URL, without any secret."""
        user = f"{self.username}@" if self.username else ""
        return f"{'mqtts' if self.tls else 'mqtt'}://{user}{self.host}:{self.port}"


@dataclass(frozen=True)
class DeskTopics:
    """The desk's own topics (docs/reference/mqtt.md)."""

    prefix: str  # <base>/<desk>: the state JSON

    @property
    def action(self) -> str:
        return f"{self.prefix}/action"

    @property
    def event(self) -> str:
        return f"{self.prefix}/event"

    @property
    def availability(self) -> str:
        return f"{self.prefix}/availability"

    @property
    def set(self) -> str:
        """Commands for the running desk (:mod:`.control`)."""
        return f"{self.prefix}/set"


def parse_broker_url(url: str, where: Position | str) -> tuple[bool, str, int, str | None]:
    """``mqtt://[user@]host[:port]`` or ``mqtts://…`` -> (tls, host, port, username)."""
    try:
        parts = urllib.parse.urlsplit(url if "://" in url else f"mqtt://{url}")
    except ValueError as err:  # "Invalid IPv6 URL" for mqtt://[::1
        raise ConfigError(where, f"broker URL {url!r} cannot be read: {err}") from None
    if parts.scheme not in ("mqtt", "mqtts"):
        raise ConfigError(
            where, f"broker must be mqtt://host[:port] or mqtts://host[:port], found {url!r}"
        )
    if parts.password is not None:
        raise ConfigError(
            where,
            "do not put a password in the broker URL (it would be logged and shown in `ps`); "
            "use `password_env: VARIABLE` or `password_file: PATH` in the layout's `mqtt:`",
        )
    if not parts.hostname:
        raise ConfigError(where, f"broker URL {url!r} has no host")
    try:
        port = parts.port
    except ValueError:
        raise ConfigError(where, f"broker URL {url!r} has an invalid port") from None
    if port == 0:  # (``or`` below would take it for no port at all)
        raise ConfigError(where, f"broker URL {url!r} has port 0; expected 1 to 65535")
    tls = parts.scheme == "mqtts"
    return tls, parts.hostname, port or (8883 if tls else 1883), parts.username


def settings_from_layout(
    section: Any,
    *,
    desk: str,
    url_override: str | None = None,
    protocol_override: str | None = None,
    relative_to: Path | None = None,
    where: Position | str = "the layout",
) -> MqttSettings:
    """Check the ``mqtt:`` section (may be None) and apply ``--mqtt URL``; a
    ``protocol_override`` (one of :data:`PROTOCOLS`, from a program that knows its broker,
    such as the demo's embedded one) goes over the section's ``protocol:``."""
    m = _section(section, where)
    tls, host, port, username = _broker(m, url_override)
    password = _password(m, relative_to)
    ca, cert, key = _tls_files(m, relative_to)
    _check_topics(m)
    client_id = _client_id(m, desk)
    retain = as_flag(m.get("retain", False))
    if not isinstance(retain, bool):
        raise ConfigError(m.where("retain"), "`retain` of `mqtt` must be true or false")
    discovery, discovery_mode = _discovery(m)
    return MqttSettings(
        host=host,
        port=port,
        tls=tls or "tls" in m,
        username=username,
        password=password,
        ca=ca,
        cert=cert,
        key=key,
        client_id=client_id,
        keepalive=int(number(m, "keepalive", "`mqtt`", default=60, minimum=5, maximum=65535)),
        qos=qos_of(m, "`mqtt`", 2),
        retain=retain,
        discovery=discovery,
        discovery_mode=discovery_mode,
        discovery_prefix=str(m.get("discovery_prefix", "homeassistant")).strip("/"),
        base_topic=str(m.get("base_topic", DEFAULT_BASE_TOPIC)).strip("/"),
        prefix=str(m["prefix"]).strip("/") if "prefix" in m else None,
        queue_size=int(
            number(
                m,
                "queue_size",
                "`mqtt`",
                default=DEFAULT_QUEUE_SIZE,
                minimum=1,
                maximum=MAX_QUEUE_SIZE,
            )
        ),
        protocol=_protocol(m) if protocol_override is None else _known_protocol(protocol_override),
        expiry_s=int(
            number(m, "expiry_s", "`mqtt`", default=DEFAULT_EXPIRY_S, minimum=0, maximum=2**32 - 1)
        ),
    )


def _section(section: Any, where: Position | str) -> MarkedDict:
    """The ``mqtt:`` section as a checked mapping (an empty one where there is none)."""
    if section is None:
        section = MarkedDict()
        section.position = where if isinstance(where, Position) else Position(str(where), 0, 0)
        section.key_positions, section.value_positions = {}, {}
    m = require_mapping(section, where, "`mqtt`")
    check_keys(m, _MQTT_KEYS, "`mqtt`")
    return m


def _broker(m: MarkedDict, url_override: str | None) -> tuple[bool, str, int, str | None]:
    """(tls, host, port, username) of ``broker:``, or of ``--mqtt URL`` over it (which may
    not drop the layout's TLS), with the layout's ``username:`` over the URL's."""
    url = str(m.get("broker", "mqtt://localhost:1883"))
    tls, host, port, username = parse_broker_url(url, m.where("broker"))
    if url_override is not None:
        layout_tls = tls or "tls" in m
        tls, host, port, url_user = parse_broker_url(url_override, "--mqtt")
        username = url_user or username
        if layout_tls and not tls:  # never downgrade: the password would go in plaintext
            raise ConfigError(
                "--mqtt",
                f"{url_override!r} is plain MQTT but the layout's `mqtt:` ({_where_text(m)}) "
                "uses TLS; give an mqtts:// URL (the layout's `tls:` files are kept)",
            )
    if "username" in m:
        if not isinstance(m["username"], str):
            raise ConfigError(m.where("username"), "`username` of `mqtt` must be text")
        username = m["username"]
    return tls, host, port, username


def _tls_files(m: MarkedDict, relative_to: Path | None) -> tuple[Path | None, ...]:
    """(ca, cert, key) of ``tls:`` (each None when not given; all None without ``tls:``)."""
    if "tls" not in m:
        return None, None, None
    t = require_mapping(m["tls"], m.where("tls"), "`tls` of `mqtt`")
    check_keys(t, {"ca", "cert", "key"}, "`tls` of `mqtt`")
    ca, cert, key = (_file(t, name, relative_to) for name in ("ca", "cert", "key"))
    if (cert is None) != (key is None):
        raise ConfigError(t.where(), "`tls` needs both `cert` and `key` for a client certificate")
    return ca, cert, key


def _check_topics(m: MarkedDict) -> None:
    """``prefix`` or ``base_topic`` (not both), and topics without wildcards."""
    if "prefix" in m and "base_topic" in m:
        raise ConfigError(
            m.where("prefix", of_key=True),
            "give `prefix` (the desk's whole topic prefix) or `base_topic` (the desk's name is "
            "appended), not both",
        )
    for key_name in ("base_topic", "discovery_prefix", "prefix"):
        value = m.get(key_name, "x")
        if not isinstance(value, str) or not value or any(c in value for c in "+#"):
            raise ConfigError(
                m.where(key_name), f"`{key_name}` must be a topic without + or #, found {value!r}"
            )


def _client_id(m: MarkedDict, desk: str) -> str:
    """``client_id``, by default one per desk prefix (hapticdesk-site1-floor2-study): two
    desks of one name on different floors must not push each other off the broker."""
    own_prefix = (
        str(m["prefix"]) if "prefix" in m else f"{m.get('base_topic', DEFAULT_BASE_TOPIC)}/{desk}"
    )
    client_id = str(m.get("client_id", own_prefix.strip("/").replace("/", "-")))
    if not client_id or len(client_id) > 128:
        raise ConfigError(m.where("client_id"), "`client_id` must be 1 to 128 characters")
    return client_id


#: ``discovery:`` values: off, or the shape of Home Assistant's discovery (``true``: entity)
DISCOVERY_MODES = ("entity", "device")


def _discovery(m: MarkedDict) -> tuple[bool, str]:
    """(``discovery`` on, its mode) from ``discovery: false | true | entity | device``."""
    value = as_flag(m.get("discovery", False))
    if isinstance(value, bool):
        return value, DISCOVERY_MODES[0]
    if value in DISCOVERY_MODES:
        return True, str(value)
    raise ConfigError(
        m.where("discovery"),
        "`discovery` of `mqtt` must be false, true (= entity), entity (one config per "
        "trigger and entity, any Home Assistant) or device (one config for the desk, Home "
        f"Assistant 2024.11 or later), found {value!r}",
    )


def _known_protocol(value: str) -> str:
    if value not in PROTOCOLS:
        raise ValueError(f"protocol override must be one of {PROTOCOLS}, found {value!r}")
    return value


def _protocol(m: MarkedDict) -> str:
    value = m.get("protocol", "auto")
    text = str(value) if isinstance(value, str | int) and not isinstance(value, bool) else None
    if text not in PROTOCOLS:
        raise ConfigError(
            m.where("protocol"),
            f'`protocol` of `mqtt` must be auto, 5 or "3.1.1" (quoted), found {value!r}',
        )
    return text


def _where_text(m: MarkedDict) -> str:
    position = getattr(m, "position", None)
    return str(position) if position is not None else "the layout"


def qos_of(m: MarkedDict, what: str, default: int) -> int:
    """An MQTT QoS (0, 1 or 2) at ``qos``."""
    if "qos" not in m:
        return default
    if m["qos"] not in (0, 1, 2) or isinstance(m["qos"], bool):
        raise ConfigError(m.where("qos"), f"`qos` of {what} must be 0, 1 or 2, found {m['qos']!r}")
    return int(m["qos"])


def _password(m: MarkedDict, relative_to: Path | None) -> str | None:
    if "password_env" in m and "password_file" in m:
        raise ConfigError(
            m.where("password_file", of_key=True),
            "give `password_env` or `password_file`, not both",
        )
    if "password_env" in m:
        var = m["password_env"]
        if not isinstance(var, str) or not var:
            raise ConfigError(
                m.where("password_env"), "`password_env` must name an environment variable"
            )
        if var not in os.environ:
            raise ConfigError(m.where("password_env"), f"the environment variable {var} is not set")
        return os.environ[var]
    if "password_file" in m:
        path = _file(m, "password_file", relative_to)
        assert path is not None
        try:
            return path.read_text(encoding="utf-8").rstrip("\r\n")
        except OSError as err:
            raise ConfigError(
                m.where("password_file"), f"cannot read {path}: {err.strerror}"
            ) from None
        except UnicodeDecodeError:
            raise ConfigError(
                m.where("password_file"), f"{path} is not text (UTF-8): expected the password"
            ) from None
    return None


def _file(m: MarkedDict, key: str, relative_to: Path | None) -> Path | None:
    if key not in m:
        return None
    if not isinstance(m[key], str) or not m[key]:
        raise ConfigError(m.where(key), f"`{key}` must be a file path")
    path = Path(m[key]).expanduser()
    if not path.is_absolute() and relative_to is not None:
        path = relative_to / path
    check_confined(path, f"`{key}`")
    if not path.is_file():
        raise ConfigError(m.where(key), f"`{key}`: no such file {path}")
    return path
