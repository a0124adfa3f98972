"""Values read from YAML that remember where they stood: :class:`MarkedDict` and
:class:`MarkedList` know the position of themselves and of each key and item, so a check
made long after loading can still say ``file:line:column``.

Also the plain scalars YAML 1.1 and 1.2 read differently, kept as the text written
(:class:`NumberText` ``1e6``, :class:`FlagText` ``on``) and read through :func:`as_number`
and :func:`as_flag`. Nothing here parses YAML (:mod:`.yamlfile` does), so a plugin that
only checks its options never imports the YAML library.
"""

from __future__ import annotations

from typing import Any

from hapticdesk.errors import Position


class MarkedDict(dict[str, Any]):
    """A mapping from YAML that knows the position of itself, each key and each value."""

    position: Position
    key_positions: dict[str, Position]
    value_positions: dict[str, Position]

    def where(self, key: str | None = None, *, of_key: bool = False) -> Position:
        """Position of ``key``'s value (or of the key itself), or of the mapping."""
        if key is None:
            return self.position
        table = self.key_positions if of_key else self.value_positions
        return table.get(key, self.position)


class MarkedList(list[Any]):
    """A sequence from YAML that knows the position of itself and of each item."""

    position: Position
    item_positions: list[Position]

    def where(self, index: int | None = None) -> Position:
        """Position of item ``index``, or of the sequence."""
        if index is None or index >= len(self.item_positions):
            return self.position
        return self.item_positions[index]


class NumberText(str):
    """A plain YAML scalar that YAML 1.2 reads as a float and YAML 1.1 as text (``1e6``)."""


class FlagText(str):
    """A plain YAML scalar that YAML 1.1 (PyYAML) reads as a boolean and YAML 1.2 (and ruamel,
    which the browser UI edits with) as text: ``on``, ``off``, ``yes``, ``no`` in any case.
    Kept as the text written, so that a Zigbee2MQTT payload's ``state: ON`` is sent as "ON"
    (it went out as ``true``); a setting that is true or false reads it through
    :func:`as_flag`, as before."""


_FLAG_TRUE = {"on", "yes"}


def as_flag(value: Any) -> Any:
    """``value``, or the boolean a :class:`FlagText` says."""
    return value.lower() in _FLAG_TRUE if isinstance(value, FlagText) else value


def as_number(value: Any) -> Any:
    """``value``, or the float a :class:`NumberText` writes."""
    return float(value.replace("_", "")) if isinstance(value, NumberText) else value
