"""YAML loading that remembers where every key and value stood, for errors users can act on.

Profiles, layouts and scenes are written by hand. When one is wrong the user must be told the
file, line and column and what was expected (STYLE.md 9), never shown a traceback. This module
loads YAML into ordinary dicts and lists that also carry the position of each key and item.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

# YAML 1.1 reads these bare words as booleans; as keys they are almost always a mistake.
_YAML11_BOOL_WORDS = {"on", "off", "yes", "no", "y", "n", "true", "false"}


@dataclass(frozen=True)
class Position:
    """A place in a file: 1-based line and column."""

    file: str
    line: int
    column: int

    def __str__(self) -> str:
        return f"{self.file}:{self.line}:{self.column}"


class ConfigError(ValueError):
    """A user-written file is wrong. ``str(err)`` is ``file:line:column: what was expected``."""

    def __init__(self, where: Position | str | None, message: str) -> None:
        self.where = where
        self.message = message
        super().__init__(f"{where}: {message}" if where is not None else message)


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


def _pos(file: str, node: yaml.Node) -> Position:
    return Position(file, node.start_mark.line + 1, node.start_mark.column + 1)


def _construct(node: yaml.Node, file: str, loader: yaml.SafeLoader) -> Any:
    if isinstance(node, yaml.MappingNode):
        loader.flatten_mapping(node)
        out = MarkedDict()
        out.position = _pos(file, node)
        out.key_positions = {}
        out.value_positions = {}
        for key_node, value_node in node.value:
            key = loader.construct_object(key_node, deep=True)
            if not isinstance(key, str):
                raw = key_node.value if isinstance(key_node, yaml.ScalarNode) else key
                hint = ""
                if isinstance(raw, str) and raw.lower() in _YAML11_BOOL_WORDS:
                    hint = f"; YAML reads a bare `{raw}` as a boolean, write it in quotes"
                raise ConfigError(_pos(file, key_node), f"keys must be text, found {raw!r}{hint}")
            if key in out:
                raise ConfigError(_pos(file, key_node), f"key `{key}` appears twice")
            out[key] = _construct(value_node, file, loader)
            out.key_positions[key] = _pos(file, key_node)
            out.value_positions[key] = _pos(file, value_node)
        return out
    if isinstance(node, yaml.SequenceNode):
        seq = MarkedList(_construct(item, file, loader) for item in node.value)
        seq.position = _pos(file, node)
        seq.item_positions = [_pos(file, item) for item in node.value]
        return seq
    return loader.construct_object(node, deep=True)


def load_marked_yaml(path: str | Path, text: str | None = None) -> Any:
    """Load one YAML document from ``path`` (or from ``text``, naming it ``path``).

    Raises :class:`ConfigError` with the position for syntax errors too.
    """
    file = str(path)
    if text is None:
        try:
            text = Path(path).read_text(encoding="utf-8")
        except OSError as err:
            raise ConfigError(file, f"cannot read the file: {err.strerror or err}") from None
    loader = yaml.SafeLoader(text)
    try:
        node = loader.get_single_node()
        if node is None:
            raise ConfigError(Position(file, 1, 1), "the file is empty, expected a mapping")
        return _construct(node, file, loader)
    except yaml.MarkedYAMLError as err:
        mark = err.problem_mark or err.context_mark
        where = Position(file, mark.line + 1, mark.column + 1) if mark else file
        raise ConfigError(where, f"not valid YAML: {err.problem or err}") from None
    finally:
        loader.dispose()


# --- small validation helpers shared by profiles, layouts and scenes -------------------------


def require_mapping(value: Any, where: Position | str, what: str) -> MarkedDict:
    """``value`` must be a mapping; otherwise a ConfigError naming ``what``."""
    if not isinstance(value, MarkedDict):
        raise ConfigError(where, f"{what} must be a mapping, found {_describe(value)}")
    return value


def check_keys(
    mapping: MarkedDict,
    allowed: set[str] | frozenset[str],
    what: str,
    required: set[str] | frozenset[str] = frozenset(),
) -> None:
    """Reject unknown keys (naming the allowed ones) and missing required keys."""
    for key in mapping:
        if key not in allowed:
            raise ConfigError(
                mapping.where(key, of_key=True),
                f"unknown key `{key}` in {what}; allowed: {', '.join(sorted(allowed))}",
            )
    for key in sorted(required):
        if key not in mapping:
            raise ConfigError(mapping.where(), f"{what} is missing `{key}`")


def number(
    mapping: MarkedDict,
    key: str,
    what: str,
    *,
    default: float | None = None,
    minimum: float | None = None,
    maximum: float | None = None,
    exclusive_minimum: bool = False,
) -> float:
    """Read a finite number at ``key`` with optional bounds."""
    if key not in mapping:
        if default is None:
            raise ConfigError(mapping.where(), f"{what} is missing `{key}` (a number)")
        return default
    value = mapping[key]
    where = mapping.where(key)
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ConfigError(where, f"`{key}` in {what} must be a number, found {_describe(value)}")
    value = float(value)
    if value != value or value in (float("inf"), float("-inf")):
        raise ConfigError(where, f"`{key}` in {what} must be finite, found {value}")
    if minimum is not None and (value < minimum or (exclusive_minimum and value == minimum)):
        op = ">" if exclusive_minimum else ">="
        raise ConfigError(where, f"`{key}` in {what} must be {op} {minimum:g}, found {value:g}")
    if maximum is not None and value > maximum:
        raise ConfigError(where, f"`{key}` in {what} must be <= {maximum:g}, found {value:g}")
    return value


def vector(value: Any, where: Position | str, what: str, length: int | None = None) -> list[float]:
    """A list of finite numbers (of ``length`` items when given)."""
    if not isinstance(value, list) or any(
        isinstance(v, bool) or not isinstance(v, int | float) for v in value
    ):
        shape = f"{length} numbers" if length else "a list of numbers"
        raise ConfigError(where, f"{what} must be {shape}, found {_describe(value)}")
    if length is not None and len(value) != length:
        raise ConfigError(where, f"{what} must have {length} numbers, found {len(value)}")
    out = [float(v) for v in value]
    if any(v != v or abs(v) == float("inf") for v in out):
        raise ConfigError(where, f"{what} must be finite numbers, found {value}")
    return out


def choice(
    mapping: MarkedDict, key: str, allowed: tuple[str, ...], what: str, default: str | None = None
) -> str:
    """A string from ``allowed``."""
    if key not in mapping:
        if default is None:
            raise ConfigError(
                mapping.where(), f"{what} is missing `{key}`; one of {', '.join(allowed)}"
            )
        return default
    value = mapping[key]
    if value not in allowed:
        raise ConfigError(
            mapping.where(key),
            f"`{key}` in {what} must be one of {', '.join(allowed)}, found {_describe(value)}",
        )
    return str(value)


def _describe(value: Any) -> str:
    if isinstance(value, dict):
        return "a mapping"
    if isinstance(value, list):
        return f"a list of {len(value)}"
    if value is None:
        return "nothing"
    return f"{type(value).__name__} {value!r}"
