"""Reading typed settings out of a marked YAML mapping, every fault at its place: a mapping
(:func:`require_mapping`) with known keys (:func:`check_keys`), a bounded finite
:func:`number`, a :func:`flag`, a :func:`vector` of numbers, a :func:`place` within reach of
the desk, a :func:`choice` among words. Shared by profiles, layouts, scenes and plugins'
options; nothing here parses YAML."""

from __future__ import annotations

from typing import Any

from hapticdesk.errors import ConfigError, Position
from hapticdesk.files.marked_values import MarkedDict, MarkedList, as_flag, as_number

#: how far from P_o a sensor, an accelerometer, the centre of mass, a surface (or a layout's
#: region) may lie, metres: a room, not a desk, is 100 m across (a sensor at 1e300 m made the
#: wrench map's moments infinite, and the estimator crashed on its covariances)
MAX_REACH_M = 100.0
#: the largest force a threshold or a force setting may name, newtons: a desk's sensors are
#: rated to a few hundred, a force plate's to 10 kN under a jump; beyond it no desk is meant
#: (a `contact_force_n` of 1e300 was taken, and no touch could ever start)
MAX_SETTING_FORCE_N = 1e4


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
    value = as_number(mapping[key])
    where = mapping.where(key)
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ConfigError(
            where,
            f"`{key}` in {what} must be a number, found {_describe(value)}{_number_hint(value)}",
        )
    value = float(value)
    if value != value or value in (float("inf"), float("-inf")):
        raise ConfigError(where, f"`{key}` in {what} must be finite, found {value}")
    op = ">" if exclusive_minimum else ">="
    # (with both bounds, the message ends with the whole range expected)
    span = (
        ""
        if minimum is None or maximum is None
        else f"; expected {op} {minimum:g} and <= {maximum:g}"
    )
    if minimum is not None and (value < minimum or (exclusive_minimum and value == minimum)):
        raise ConfigError(
            where, f"`{key}` in {what} must be {op} {minimum:g}, found {value:g}{span}"
        )
    if maximum is not None and value > maximum:
        raise ConfigError(where, f"`{key}` in {what} must be <= {maximum:g}, found {value:g}{span}")
    return value


def flag(mapping: MarkedDict, key: str, what: str, *, default: bool) -> bool:
    """Read ``true`` or ``false`` at ``key``."""
    if key not in mapping:
        return default
    value = as_flag(mapping[key])
    if not isinstance(value, bool):
        raise ConfigError(
            mapping.where(key), f"`{key}` in {what} must be true or false, found {_describe(value)}"
        )
    return value


def flag_or_auto(mapping: MarkedDict, key: str, what: str) -> bool | None:
    """Read ``true``, ``false`` or ``auto`` at ``key``; ``auto`` or no key is None (the
    program decides)."""
    if key not in mapping or mapping[key] == "auto":
        return None
    value = as_flag(mapping[key])
    if not isinstance(value, bool):
        raise ConfigError(
            mapping.where(key),
            f"`{key}` in {what} must be true, false or auto, found {_describe(value)}",
        )
    return value


def vector(value: Any, where: Position | str, what: str, length: int | None = None) -> list[float]:
    """A list of finite numbers (of ``length`` items when given)."""
    shape = f"{length} numbers" if length else "a list of numbers"
    if not isinstance(value, list):
        raise ConfigError(where, f"{what} must be {shape}, found {_describe(value)}")
    items = [as_number(v) for v in value]
    for i, v in enumerate(items):
        if isinstance(v, bool) or not isinstance(v, int | float):
            item_where = value.where(i) if isinstance(value, MarkedList) else where
            raise ConfigError(
                item_where,
                f"{what} must be {shape}; item {i + 1} is {_describe(v)}{_number_hint(v)}",
            )
    if length is not None and len(value) != length:
        raise ConfigError(where, f"{what} must have {length} numbers, found {len(value)}")
    out = [float(v) for v in items]
    if any(v != v or abs(v) == float("inf") for v in out):
        raise ConfigError(where, f"{what} must be finite numbers, found {value}")
    return out


def place(value: Any, where: Any, what: str, length: int, origin: str = "P_o") -> list[float]:
    """A point of ``length`` coordinates (metres), none farther than :data:`MAX_REACH_M`
    from ``origin``."""
    out = vector(value, where, what, length)
    far = max(abs(v) for v in out)
    if far > MAX_REACH_M:
        raise ConfigError(
            where,
            f"{what} has a coordinate of {far:g} m from {origin}; a desk's parts lie within "
            f"{MAX_REACH_M:g} m of it",
        )
    return out


def whole_number(
    m: MarkedDict, key: str, what: str, minimum: int = 0, maximum: int | None = None
) -> int:
    """A whole number at ``key`` from ``minimum`` (to ``maximum``: shown in hex too)."""
    value = m[key]
    if isinstance(value, bool) or not isinstance(value, int):
        raise ConfigError(
            m.where(key), f"`{key}` in {what} must be a whole number, found {value!r}"
        )
    if value < minimum or (maximum is not None and value > maximum):
        bound = f"{minimum}…{maximum} (0x{minimum:X}…0x{maximum:X})" if maximum else f">= {minimum}"
        raise ConfigError(m.where(key), f"`{key}` in {what} must be {bound}, found {value}")
    return value


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


def _number_hint(value: Any) -> str:
    """A hint when ``value`` is text that reads as a number (it was quoted)."""
    if not isinstance(value, str):
        return ""
    try:
        float(value.replace("_", ""))
    except ValueError:
        return ""
    return "; write the number without quotes"


def _describe(value: Any) -> str:
    if isinstance(value, dict):
        return "a mapping"
    if isinstance(value, list):
        return f"a list of {len(value)}"
    if value is None:
        return "nothing"
    return f"{type(value).__name__} {value!r}"
