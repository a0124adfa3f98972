"""Gesture options: their built-in defaults, kinds and bounds, and how a value is read.

Like fusuma's thresholds, a gesture's settings are looked up at three levels: the built-in
default here, the layout-wide ``settings: {<gesture>: {...}}``, and the binding itself.
Options have one of two roles:

- ``recognize`` options tune the recognizer (how long a tap may last, how far a swipe must
  go). One recognizer judges every touch in a region, so within a region they must agree.
- ``match`` options pick which of the recognised events a binding reacts to (the stroke's
  ``shape``, the swipe's ``direction``, the press ``level``, the long-press ``hold_s`` tier).

Lengths are in the layout's ``units`` and stored in metres; times in seconds; forces in
newtons. This module is data and parsing only, so loading a layout imports no recognizer.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

from hapticdesk.errors import ConfigError, Position
from hapticdesk.files.marked_values import MarkedDict, as_flag
from hapticdesk.files.validators import MAX_REACH_M, MAX_SETTING_FORCE_N, number

Kind = Literal[
    "seconds", "length", "newtons", "fraction", "degrees", "choice", "bool", "names", "levels"
]
Role = Literal["recognize", "match"]

PHASES = ("begin", "update", "end", "cancel")
DIRECTIONS_4 = ("right", "up", "left", "down")
DIRECTIONS_8 = (
    "right",
    "up_right",
    "up",
    "up_left",
    "left",
    "down_left",
    "down",
    "down_right",
)


@dataclass(frozen=True)
class OptionSpec:
    """One gesture option: its kind, default, role and bounds, and a line of help."""

    kind: Kind
    default: Any
    role: Role
    help: str
    minimum: float | None = None
    maximum: float | None = None
    choices: tuple[Any, ...] = ()


def _s(default: float, help: str, maximum: float = 60.0, minimum: float = 0.0) -> OptionSpec:
    return OptionSpec("seconds", default, "recognize", help, minimum, maximum)


#: the shortest time between two events of one held touch (long-press repeats, slide and force
#: updates): each can be a command to a light, and a light on Zigbee takes a few a second;
#: 1e-300 had made an event of every sample (1,200 a second)
MIN_EVENT_INTERVAL_S = 0.02


def _m(default: float, help: str) -> OptionSpec:
    # (metres: stored so, read in the layout's units; no length on a desk is beyond the room)
    return OptionSpec("length", default, "recognize", help, 0.0, MAX_REACH_M)


def _n(default: float, help: str) -> OptionSpec:
    return OptionSpec("newtons", default, "recognize", help, 0.0, MAX_SETTING_FORCE_N)


def _phase_filter() -> OptionSpec:
    return OptionSpec(
        "names",
        None,
        "match",
        "which phases to react to (begin, update, end, cancel); all by default",
    )


def _leave() -> OptionSpec:
    return OptionSpec(
        "choice",
        "clip",
        "recognize",
        "a finger that leaves the region: clip (the gesture goes on, a slider's value held at"
        " 0 or 1) or cancel (it ends there with phase cancel)",
        choices=("clip", "cancel"),
    )


_TAP_DURATION = "longest touch that still counts as a tap"
_TAP_MOVE = "how far the finger may move during the touch"
_TAP_SNAP = "a tap outside every bound region goes to the nearest one this close"

#: gesture name -> option name -> spec. Built-in gestures only; plugin recognizers may carry
#: their own table as a class attribute ``option_specs``.
GESTURE_OPTIONS: dict[str, dict[str, OptionSpec]] = {
    "tap": {
        "max_duration_s": _s(0.5, _TAP_DURATION, 5.0),
        "max_move": _m(0.015, _TAP_MOVE),
        "snap": _m(0.012, _TAP_SNAP),
    },
    "double_tap": {
        "interval_s": _s(0.3, "longest pause between the first release and the second touch", 2.0),
        "max_distance": _m(0.03, "how far apart the two taps may be"),
        "max_duration_s": _s(0.5, _TAP_DURATION, 5.0),
        "max_move": _m(0.015, _TAP_MOVE),
        "snap": _m(0.012, _TAP_SNAP),
    },
    "two_finger_tap": {
        "max_duration_s": _s(1.5, "longest two-finger touch, first finger down to release", 5.0),
        "max_move": _m(0.015, "how far the first finger may move before the second lands"),
        "snap": _m(0.012, _TAP_SNAP),
    },
    "long_press": {
        "max_move": _m(0.015, "how far the finger may move before the hold is cancelled"),
        "hold_s": OptionSpec(
            "seconds", 0.8, "match", "the hold tier this binding fires at", 0.0, 600.0
        ),
        "release": OptionSpec(
            "bool", False, "match", "fire on the release after the tier instead of at it"
        ),
        "repeat": OptionSpec(
            "bool",
            False,
            "match",
            "after the tier, fire again every `interval_s` while the finger stays (hold to dim)",
        ),
        "interval_s": _s(
            0.25, "time between two repeats of a held long press", 10.0, MIN_EVENT_INTERVAL_S
        ),
    },
    "press": {
        "levels": OptionSpec(
            "levels",
            {"light": 4.0, "firm": 10.0, "hard": 20.0},
            "recognize",
            "named force levels in newtons; each fires when the force rises past it",
        ),
        "hysteresis_n": _n(1.0, "a level re-arms when the force drops this far below it"),
        "level": OptionSpec("names", None, "match", "which level(s) to react to; all by default"),
    },
    "force": {
        "min_n": _n(2.0, "force at value 0"),
        "max_n": _n(20.0, "force at value 1"),
        "interval_s": _s(0.05, "shortest time between two updates", 10.0, MIN_EVENT_INTERVAL_S),
        "step": OptionSpec(
            "fraction", 0.01, "recognize", "smallest change worth an update", 0.0, 1.0
        ),
        "leave": _leave(),
        "phase": _phase_filter(),
    },
    "swipe": {
        "directions": OptionSpec(
            "choice",
            4,
            "recognize",
            "4 (right, up, left, down) or 8 (also diagonals)",
            choices=(4, 8),
        ),
        "min_distance": _m(0.05, "shortest swipe"),
        "max_duration_s": _s(0.8, "longest swipe, touch to release", 10.0),
        "max_deviation": OptionSpec(
            "fraction",
            0.35,
            "recognize",
            "how far the path may bow away from the straight line, as a fraction of its length",
            0.0,
            1.0,
        ),
        "direction": OptionSpec(
            "names", None, "match", "which direction(s) to react to; all by default"
        ),
    },
    "slide": {
        "interval_s": _s(0.05, "shortest time between two updates", 10.0, MIN_EVENT_INTERVAL_S),
        "step": OptionSpec(
            "fraction", 0.01, "recognize", "smallest change worth an update", 0.0, 1.0
        ),
        "leave": _leave(),
        "phase": _phase_filter(),
    },
    "stroke": {
        "min_size": _m(0.04, "smallest stroke: the diagonal of the box around it"),
        "max_duration_s": _s(15.0, "longest stroke, touch to release", 120.0),
        "min_score": OptionSpec(
            "fraction",
            0.8,
            "recognize",
            "similarity (0..1) a stroke needs to be recognised; below it the shape is null"
            " (a shape with several recorded templates may ask more: their own agreement)",
            0.0,
            1.0,
        ),
        "max_rotation_deg": OptionSpec(
            "degrees",
            30.0,
            "recognize",
            "how far a stroke may be turned from its template",
            0.0,
            180.0,
        ),
        "shape": OptionSpec("names", None, "match", "which shape(s) to react to; any by default"),
    },
}

#: gestures whose bindings may leave out `region` (they happen anywhere on the desk)
ANYWHERE_GESTURES = frozenset({"stroke", "swipe"})

_UNIT_SYMBOL = {"seconds": "s", "newtons": "N", "degrees": "deg"}
#: the largest value of a kind, where an option (a plugin's among them) sets none: a time
#: beyond an hour is a typing mistake, a force beyond 10 kN no desk's, a length beyond the
#: room, a fraction beyond the whole
KIND_MAXIMUM = {
    "seconds": 3600.0,
    "newtons": MAX_SETTING_FORCE_N,
    "length": MAX_REACH_M,
    "fraction": 1.0,
    "degrees": 360.0,
}


def defaults(specs: dict[str, OptionSpec]) -> dict[str, Any]:
    """The built-in value of every option (lengths in metres)."""
    return {name: spec.default for name, spec in specs.items()}


def read_option(
    spec: OptionSpec, mapping: MarkedDict, key: str, what: str, metres_per_unit: float
) -> Any:
    """Read option ``key`` from ``mapping`` (where it is present) per its spec.

    Lengths are converted from the layout's units to metres; names become a tuple.
    """
    where = mapping.where(key)
    value = mapping[key]
    label = f"`{key}` of {what}"
    if spec.kind in ("seconds", "newtons", "fraction", "degrees"):
        strict = spec.kind == "seconds" and not spec.minimum  # (a time of 0 is no time)
        return number(
            mapping,
            key,
            what,
            minimum=spec.minimum,
            maximum=spec.maximum if spec.maximum is not None else KIND_MAXIMUM[spec.kind],
            exclusive_minimum=strict,
        )
    if spec.kind == "length":
        value_units = number(
            mapping,
            key,
            what,
            minimum=0.0,
            exclusive_minimum=True,
            maximum=(spec.maximum or KIND_MAXIMUM["length"]) / metres_per_unit,  # (its units)
        )
        return value_units * metres_per_unit
    if spec.kind == "choice":
        if value not in spec.choices or isinstance(value, bool):
            allowed = ", ".join(str(c) for c in spec.choices)
            raise ConfigError(where, f"{label} must be one of {allowed}, found {value!r}")
        return value
    if spec.kind == "bool":
        value = as_flag(value)
        if not isinstance(value, bool):
            raise ConfigError(where, f"{label} must be true or false, found {value!r}")
        return value
    if spec.kind == "names":
        return read_names(value, where, label)
    if spec.kind == "levels":
        return _read_levels(value, where, label)
    raise AssertionError(f"unknown option kind {spec.kind}")  # pragma: no cover


def read_names(value: Any, where: Position, label: str) -> tuple[str, ...]:
    """A name or a list of names, as a tuple."""
    items = value if isinstance(value, list) else [value]
    if not items or any(not isinstance(v, str) or not v for v in items):
        raise ConfigError(where, f"{label} must be a name or a list of names, found {value!r}")
    return tuple(items)


def _read_levels(value: Any, where: Position, label: str) -> dict[str, float]:
    if not isinstance(value, MarkedDict) or not value:
        raise ConfigError(
            where, f"{label} must map level names to forces in newtons, e.g. {{light: 4, firm: 10}}"
        )
    levels: dict[str, float] = {}
    for name in value:
        if not name.replace("_", "").isalnum():
            raise ConfigError(
                value.where(name, of_key=True),
                f"level names must be letters, digits and _, found {name!r}",
            )
        levels[name] = number(
            value, name, label, minimum=0.0, exclusive_minimum=True, maximum=MAX_SETTING_FORCE_N
        )
    forces = list(levels.values())
    if len(set(forces)) != len(forces):
        raise ConfigError(where, f"{label}: two levels have the same force {forces}")
    return dict(sorted(levels.items(), key=lambda item: item[1]))


def describe_value(spec: OptionSpec, value: Any, units: str, metres_per_unit: float) -> str:
    """A value as the user would write it in the layout (for ``hapticdesk check``)."""
    if spec.kind == "length":
        return f"{value / metres_per_unit:g} {units}"
    if spec.kind in _UNIT_SYMBOL:
        return f"{value:g} {_UNIT_SYMBOL[spec.kind]}"
    if spec.kind == "names":
        return "any" if value is None else ", ".join(value)
    if spec.kind == "levels":
        return ", ".join(f"{k} {v:g} N" for k, v in value.items())
    return str(value).lower() if isinstance(value, bool) else str(value)
