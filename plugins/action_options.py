"""Reading an action's options from a layout, with errors that point at the layout.

Options arrive as the :class:`~hapticdesk.files.marked_values.MarkedDict` of the layout (or a
plain dict when a program builds them); both are read the same way here.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from hapticdesk.errors import ConfigError, Position
from hapticdesk.files.marked_values import MarkedDict
from hapticdesk.files.validators import check_keys, number


def options_mapping(
    options: Any,
    position: Position | str,
    what: str,
    allowed: Iterable[str],
    required: Iterable[str] = (),
) -> MarkedDict:
    """``options`` as a MarkedDict with only ``allowed`` keys and every ``required`` one.

    ``None`` (``do: {log: }``) reads as an empty mapping.
    """
    if options is None:
        options = {}
    if not isinstance(options, dict):
        raise ConfigError(
            position, f"the options of {what} must be a mapping, found {type(options).__name__}"
        )
    if not isinstance(options, MarkedDict):
        marked = MarkedDict(options)
        marked.position = (
            position if isinstance(position, Position) else Position(str(position), 0, 0)
        )
        marked.key_positions = {}
        marked.value_positions = {}
        options = marked
    check_keys(options, set(allowed), what, required=set(required))
    return options


def text(m: MarkedDict, key: str, what: str, default: str | None = None) -> str:
    """A non-empty string at ``key``."""
    if key not in m:
        if default is None:
            raise ConfigError(m.where(), f"{what} is missing `{key}` (text)")
        return default
    value = m[key]
    if not isinstance(value, str) or not value:
        raise ConfigError(
            m.where(key), f"`{key}` of {what} must be non-empty text, found {value!r}"
        )
    return value


#: the longest an action may be given, seconds: a gesture's command that may take over an
#: hour is a typing mistake (its thread is waited for that long; 1e300 is no timeout at all)
MAX_ACTION_S = 3600.0


def seconds(m: MarkedDict, key: str, what: str, default: float) -> float:
    """A positive duration in seconds, at most :data:`MAX_ACTION_S`."""
    return number(
        m, key, what, default=default, minimum=0.0, exclusive_minimum=True, maximum=MAX_ACTION_S
    )


def where(options: Any, fallback: str) -> Position | str:
    """The position of an options mapping, for factories re-reading their options."""
    return options.where() if isinstance(options, MarkedDict) else fallback
