"""A scene's timeline items read into steps: which actions exist, the keys each takes, and one
builder an action (a stroke's is :mod:`.scene_strokes`). Errors name file:line:column."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from hapticdesk.errors import ConfigError, Position
from hapticdesk.files.marked_values import MarkedDict, as_number
from hapticdesk.files.validators import check_keys, number, require_mapping
from hapticdesk.sim.actions import (
    Drag,
    Idle,
    LiftObject,
    LongPress,
    Press,
    PutObject,
    Ramp,
    Step,
    Swipe,
    Tap,
)
from hapticdesk.sim.scene_fields import ActionFields, field_integer, field_text, path_or_ends
from hapticdesk.sim.scene_limits import MAX_FORCE_N, MAX_OBJECT_KG, MAX_REPEAT, MAX_SCENE_S
from hapticdesk.sim.scene_strokes import stroke_steps

_COMMON = {"start_s", "wait_s", "repeat", "label"}
ACTION_KEYS: dict[str, set[str]] = {
    "press": {"point", "peak_n", "hold_s", "rise_n_per_s", "release_n_per_s", "surface"},
    "long_press": {"point", "peak_n", "hold_s", "rise_n_per_s", "release_n_per_s", "surface"},
    "tap": {"point", "peak_n", "duration_s", "surface"},
    "ramp": {"point", "from_n", "to_n", "duration_s", "surface"},
    "swipe": {"from", "to", "force_n", "speed", "surface"},
    "drag": {"from", "to", "path", "force_n", "speed", "surface"},
    "stroke": {
        "path",
        "shape",
        "text",
        "file",
        "center",
        "size",
        "rotation_deg",
        "clockwise",
        "pen_up_s",
        "force_n",
        "speed",
        "surface",
    },
    "put": {"object", "mass_kg", "point", "duration_s", "surface"},
    "lift": {"object", "duration_s"},
    "idle": {"duration_s"},
}
_REQUIRED: dict[str, set[str]] = {
    "press": {"point"},
    "long_press": {"point"},
    "tap": {"point"},
    "ramp": {"point"},
    "swipe": {"from", "to"},
    "put": {"object", "mass_kg", "point"},
    "lift": {"object"},
    "idle": {"duration_s"},
}


def timeline_steps(item: Any, where: Position, index: int, unit: float, path: Path) -> list[Step]:
    """The steps of timeline item ``index`` (at ``where``), its ``repeat`` expanded."""
    what = f"timeline item {index + 1}"
    m = require_mapping(item, where, what)
    if len(m) != 1:
        raise ConfigError(
            where,
            f"{what} must be one action (a single key, one of {', '.join(ACTION_KEYS)}), "
            f"found {len(m)} keys: {', '.join(m) or 'none'}",
        )
    kind = next(iter(m))
    if kind not in ACTION_KEYS:
        raise ConfigError(
            m.where(kind, of_key=True),
            f"unknown action `{kind}` in {what}; one of {', '.join(ACTION_KEYS)}",
        )
    p = require_mapping(_idle_shorthand(m, kind), m.where(kind), f"`{kind}` ({what})")
    what = f"`{kind}` ({what})"
    check_keys(p, ACTION_KEYS[kind] | _COMMON, what, _REQUIRED.get(kind, set()))
    timing: dict[str, Any] = {
        "start_s": (
            number(p, "start_s", what, minimum=0.0, maximum=MAX_SCENE_S) if "start_s" in p else None
        ),
        "wait_s": (
            number(p, "wait_s", what, minimum=0.0, maximum=MAX_SCENE_S) if "wait_s" in p else None
        ),
        "label": field_text(p, "label", what, default=""),
        "where": p.where(),
    }
    repeat = field_integer(p, "repeat", what, default=1, minimum=1, maximum=MAX_REPEAT)
    fields = ActionFields(p, what, unit, path)
    build = _BUILDERS[kind]
    try:
        first = build(kind, fields, timing)
    except ValueError as err:
        if isinstance(err, ConfigError):
            raise
        raise ConfigError(p.where(), f"{what}: {err}") from None
    out = list(first)
    for _ in range(repeat - 1):
        again = dict(timing, start_s=None)
        out.extend(build(kind, fields, again))
    return out


def _idle_shorthand(m: MarkedDict, kind: str) -> Any:
    """``idle: 2`` read as ``idle: {duration_s: 2}``; any other value as written."""
    value = as_number(m[kind])
    if kind == "idle" and isinstance(value, int | float) and not isinstance(value, bool):
        shorthand = MarkedDict({"duration_s": value})
        shorthand.position = m.where(kind)
        shorthand.key_positions = {"duration_s": m.where(kind)}
        shorthand.value_positions = {"duration_s": m.where(kind)}
        return shorthand
    return value


def _press(kind: str, f: ActionFields, timing: dict[str, Any]) -> list[Step]:
    cls = LongPress if kind == "long_press" else Press
    return [
        cls(
            f.point("point"),
            peak_n=f.optional("peak_n"),
            hold_s=f.optional("hold_s", positive=False),
            rise_n_per_s=f.optional("rise_n_per_s"),
            release_n_per_s=f.optional("release_n_per_s"),
            surface=f.surface(),
            **timing,
        )
    ]


def _tap(kind: str, f: ActionFields, timing: dict[str, Any]) -> list[Step]:
    return [
        Tap(
            f.point("point"),
            peak_n=f.optional("peak_n"),
            duration_s=f.optional("duration_s"),
            surface=f.surface(),
            **timing,
        )
    ]


def _ramp(kind: str, f: ActionFields, timing: dict[str, Any]) -> list[Step]:
    p, what = f.p, f.what
    from_n, to_n = (
        number(p, key, what, default=d, minimum=0.0, exclusive_minimum=True, maximum=MAX_FORCE_N)
        for key, d in (("from_n", 3.0), ("to_n", 25.0))
    )
    return [
        Ramp(
            f.point("point"),
            from_n=from_n,
            to_n=to_n,
            duration_s=number(
                p,
                "duration_s",
                what,
                default=3.0,
                minimum=0.0,
                exclusive_minimum=True,
                maximum=MAX_SCENE_S,
            ),
            surface=f.surface(),
            **timing,
        )
    ]


def _swipe(kind: str, f: ActionFields, timing: dict[str, Any]) -> list[Step]:
    a, b = f.point("from"), f.point("to")
    if a == b:
        raise ConfigError(f.p.where("to"), f"`to` of {f.what} must differ from `from`")
    return [
        Swipe(a, b, force_n=f.optional("force_n"), speed=f.speed(), surface=f.surface(), **timing)
    ]


def _drag(kind: str, f: ActionFields, timing: dict[str, Any]) -> list[Step]:
    pts = path_or_ends(f.p, f.what, f.unit)
    return [
        Drag(pts, force_n=f.optional("force_n"), speed=f.speed(), surface=f.surface(), **timing)
    ]


def _stroke(kind: str, f: ActionFields, timing: dict[str, Any]) -> list[Step]:
    return stroke_steps(f, timing, f.speed())


def _put(kind: str, f: ActionFields, timing: dict[str, Any]) -> list[Step]:
    p, what = f.p, f.what
    return [
        PutObject(
            name=field_text(p, "object", what),
            mass_kg=number(
                p, "mass_kg", what, minimum=0.0, exclusive_minimum=True, maximum=MAX_OBJECT_KG
            ),
            point=f.point("point"),
            duration_s=number(p, "duration_s", what, default=0.3, minimum=0.0, maximum=MAX_SCENE_S),
            surface=f.surface(),
            **timing,
        )
    ]


def _lift(kind: str, f: ActionFields, timing: dict[str, Any]) -> list[Step]:
    p, what = f.p, f.what
    return [
        LiftObject(
            name=field_text(p, "object", what),
            duration_s=number(p, "duration_s", what, default=0.3, minimum=0.0, maximum=MAX_SCENE_S),
            **timing,
        )
    ]


def _idle(kind: str, f: ActionFields, timing: dict[str, Any]) -> list[Step]:
    duration = number(f.p, "duration_s", f.what, minimum=0.0, maximum=MAX_SCENE_S)
    return [Idle(duration_s=duration, **timing)]


_BUILDERS: dict[str, Callable[[str, ActionFields, dict[str, Any]], list[Step]]] = {
    "press": _press,
    "long_press": _press,
    "tap": _tap,
    "ramp": _ramp,
    "swipe": _swipe,
    "drag": _drag,
    "stroke": _stroke,
    "put": _put,
    "lift": _lift,
    "idle": _idle,
}
