"""Reading a scene's fields with their place (file:line:column in every error): lists, texts,
whole numbers, flags, points and paths in the scene's unit, the human model's overrides, and
one action's fields (:class:`ActionFields`). Used by :mod:`.scene`, :mod:`.scene_steps` and
:mod:`.scene_strokes`."""

from __future__ import annotations

from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np

from hapticdesk.errors import ConfigError, Position
from hapticdesk.files.marked_values import MarkedDict, MarkedList, as_number
from hapticdesk.files.validators import check_keys, number, require_mapping, vector
from hapticdesk.sim.human import HumanModel
from hapticdesk.sim.scene_limits import (
    MAX_FORCE_N,
    MAX_FORCE_RATE_N_S,
    MAX_SCENE_S,
    MAX_SPEED_M_S,
    MIN_SPEED_M_S,
)


def field_list(m: MarkedDict, key: str, what: str) -> MarkedList:
    value = m[key]
    if not isinstance(value, MarkedList):
        raise ConfigError(m.where(key), f"`{key}` in {what} must be a list")
    return value


def field_text(m: MarkedDict, key: str, what: str, default: str | None = None) -> str:
    if key not in m:
        if default is None:
            raise ConfigError(m.where(), f"{what} is missing `{key}` (a text)")
        return default
    value = m[key]
    if isinstance(value, bool) or not isinstance(value, str | int | float) or str(value) == "":
        raise ConfigError(m.where(key), f"`{key}` in {what} must be a text, found {value!r}")
    return str(value)


def field_integer(
    m: MarkedDict, key: str, what: str, default: int, minimum: int, maximum: int | None = None
) -> int:
    if key not in m:
        return default
    value = m[key]
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise ConfigError(
            m.where(key), f"`{key}` in {what} must be a whole number >= {minimum}, found {value!r}"
        )
    if maximum is not None and value > maximum:
        raise ConfigError(
            m.where(key), f"`{key}` in {what} must be at most {maximum}, found {value}"
        )
    return value


def field_point(m: MarkedDict, key: str, what: str, unit: float) -> tuple[float, float]:
    u, v = vector(m[key], m.where(key), f"`{key}` of {what} ([u, v])", 2)
    return (u * unit, v * unit)


def field_surface(m: MarkedDict, what: str) -> str | None:
    return field_text(m, "surface", what, default="") or None


def path_or_ends(p: MarkedDict, what: str, unit: float) -> np.ndarray:
    if "path" in p:
        if "from" in p or "to" in p:
            raise ConfigError(
                p.where("path", of_key=True), f"{what}: give `path` or `from`/`to`, not both"
            )
        raw = p["path"]
        if not isinstance(raw, MarkedList) or len(raw) < 2:
            raise ConfigError(
                p.where("path"), f"`path` of {what} must list two or more [u, v] points"
            )
        pts = np.array(
            [vector(q, raw.where(i), f"point {i + 1} of `path`", 2) for i, q in enumerate(raw)]
        )
        if not np.any(np.linalg.norm(np.diff(pts, axis=0), axis=1) > 0):
            raise ConfigError(p.where("path"), f"`path` of {what} needs two distinct points")
        return pts * unit
    if "from" not in p or "to" not in p:
        raise ConfigError(p.where(), f"{what} needs `from` and `to` (or a `path`)")
    a, b = field_point(p, "from", what, unit), field_point(p, "to", what, unit)
    if a == b:
        raise ConfigError(p.where("to"), f"`to` of {what} must differ from `from`")
    return np.array([a, b])


def field_human(value: Any, where: Position) -> HumanModel:
    m = require_mapping(value, where, "`human`")
    defaults = HumanModel()
    allowed = {f.name for f in fields(HumanModel)}
    check_keys(m, allowed, "`human`")
    values: dict[str, Any] = {}
    for key in m:
        if isinstance(getattr(defaults, key), tuple):
            raw = as_number(m[key])
            if isinstance(raw, int | float) and not isinstance(raw, bool):
                raw = [raw, raw]
            lo, hi = vector(raw, m.where(key), f"`{key}` in `human` (a number or [low, high])", 2)
            if lo < 0 or lo > hi:
                raise ConfigError(
                    m.where(key),
                    f"`{key}` in `human` must be 0 <= low <= high, found [{lo:g}, {hi:g}]",
                )
            values[key] = (lo, hi)
        else:
            values[key] = number(m, key, "`human`", minimum=0.0)
    return HumanModel(**values)


@dataclass(frozen=True)
class ActionFields:
    """One timeline action's mapping ``p``, named ``what`` in errors, in the scene's ``unit``
    (metres per unit); ``path`` is the scene file (relative files are read beside it)."""

    p: MarkedDict
    what: str
    unit: float
    path: Path

    def optional(self, key: str, *, positive: bool = True) -> float | None:
        """A time, force or force rate if given, bounded by its kind (by the key's ending)."""
        if key not in self.p:
            return None
        # a time (`hold_s`, `duration_s`) at most a day; a force and its rate (above)
        largest = {"_n_per_s": MAX_FORCE_RATE_N_S, "_s": MAX_SCENE_S, "_n": MAX_FORCE_N}
        longest = next((v for end, v in largest.items() if key.endswith(end)), None)
        return number(
            self.p, key, self.what, minimum=0.0, exclusive_minimum=positive, maximum=longest
        )

    def speed(self) -> float | None:
        """The finger's speed if given, in m/s."""
        if "speed" not in self.p:
            return None
        lo, hi = MIN_SPEED_M_S / self.unit, MAX_SPEED_M_S / self.unit  # in the scene's units
        return number(self.p, "speed", self.what, minimum=lo, maximum=hi) * self.unit

    def point(self, key: str) -> tuple[float, float]:
        """A point [u, v] in metres."""
        return field_point(self.p, key, self.what, self.unit)

    def surface(self) -> str | None:
        """The touched surface if given."""
        return field_surface(self.p, self.what)
