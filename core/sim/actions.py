"""What happens in a scene: its steps — finger actions, objects put down and lifted, idle time.

A scene's timeline items are *steps* (:class:`Step`), so that *action* means one thing in
hapticdesk: what a layout binding runs (:class:`hapticdesk.runtime.dispatcher.Action`).
``Action`` and ``TouchAction`` remain as the former names of :class:`Step` and
:class:`TouchStep`.

Positions are in metres on a surface, in the surface's (u, v) coordinates (the desk's x, y for
the horizontal top board). Parameters left ``None`` are drawn from the
:class:`~hapticdesk.sim.human.HumanModel` with the scene's seed, so a scene of a hundred
``Tap(point)`` is a hundred slightly different taps, the same ones for the same seed.

Timing: an action starts ``wait_s`` after the previous one ends (``None``: the human's usual
pause; the first action starts right after the scene's quiet period), or at ``start_s`` when
that is given.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hapticdesk.errors import Position

Point = tuple[float, float]


def _point(value: Any) -> Point:
    arr = np.asarray(value, dtype=float).reshape(-1)
    if arr.shape != (2,) or not np.isfinite(arr).all():
        raise ValueError(f"a point must be two finite numbers (u, v), found {value!r}")
    return (float(arr[0]), float(arr[1]))


def _path(value: Any) -> tuple[Point, ...]:
    arr = np.asarray(value, dtype=float)
    if arr.ndim != 2 or arr.shape[1] != 2 or len(arr) < 2 or not np.isfinite(arr).all():
        raise ValueError(
            f"a path must be two or more finite (u, v) points, found shape {arr.shape}"
        )
    if not np.any(np.linalg.norm(np.diff(arr, axis=0), axis=1) > 0):
        raise ValueError("a path needs at least two distinct points")
    return tuple((float(u), float(v)) for u, v in arr)


def _check(
    action: object, *, positive: tuple[str, ...] = (), at_least_0: tuple[str, ...] = ()
) -> None:
    """Optional numbers of an action must be finite and positive (or >= 0) when given."""
    for names, low, sign in ((positive, None, "> 0"), (at_least_0, 0.0, ">= 0")):
        for name in names:
            value = getattr(action, name)
            if value is None:
                continue
            ok = math.isfinite(value) and (value > 0 if low is None else value >= low)
            if not ok:
                raise ValueError(f"{type(action).__name__}.{name} must be {sign}, found {value}")


@dataclass(frozen=True, kw_only=True)
class Step:
    """Common timing of every action (see the module docstring)."""

    start_s: float | None = None
    wait_s: float | None = None
    label: str = ""
    where: Position | None = field(default=None, compare=False, repr=False)

    def __post_init__(self) -> None:
        _check(self, at_least_0=("start_s", "wait_s"))


@dataclass(frozen=True, kw_only=True)
class TouchStep(Step):
    """A finger on a surface (``None``: the scene's surface, else the desk's first)."""

    surface: str | None = None


@dataclass(frozen=True)
class Press(TouchStep):
    """Press and hold: force rises (≈45 N/s at touch), holds at 15–25 N, releases faster."""

    point: Point
    peak_n: float | None = None
    hold_s: float | None = None
    rise_n_per_s: float | None = None
    release_n_per_s: float | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        object.__setattr__(self, "point", _point(self.point))
        _check(self, positive=("peak_n", "rise_n_per_s", "release_n_per_s"), at_least_0=("hold_s",))


@dataclass(frozen=True)
class LongPress(Press):
    """A press held for 2–3 s (or ``hold_s``)."""


@dataclass(frozen=True)
class Tap(TouchStep):
    """A light, short tap: 2–5 N for 80–160 ms."""

    point: Point
    peak_n: float | None = None
    duration_s: float | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        object.__setattr__(self, "point", _point(self.point))
        _check(self, positive=("peak_n", "duration_s"))


@dataclass(frozen=True)
class Ramp(TouchStep):
    """Touch at ``from_n``, raise the force steadily to ``to_n`` over ``duration_s``, release."""

    point: Point
    from_n: float = 3.0
    to_n: float = 25.0
    duration_s: float = 3.0

    def __post_init__(self) -> None:
        super().__post_init__()
        object.__setattr__(self, "point", _point(self.point))
        _check(self, positive=("from_n", "to_n", "duration_s"))


@dataclass(frozen=True)
class Swipe(TouchStep):
    """A quick light slide from one point to another, lifting off while still moving."""

    from_point: Point
    to_point: Point
    force_n: float | None = None
    speed: float | None = None  # m/s

    def __post_init__(self) -> None:
        super().__post_init__()
        _check(self, positive=("force_n", "speed"))
        object.__setattr__(self, "from_point", _point(self.from_point))
        object.__setattr__(self, "to_point", _point(self.to_point))
        if self.from_point == self.to_point:
            raise ValueError("a swipe needs two different points")


@dataclass(frozen=True)
class PathTouch(TouchStep):
    """A finger that moves along ``path`` while it touches (the base of Drag and Stroke)."""

    path: tuple[Point, ...]
    force_n: float | None = None
    speed: float | None = None  # m/s

    def __post_init__(self) -> None:
        super().__post_init__()
        _check(self, positive=("force_n", "speed"))
        object.__setattr__(self, "path", _path(self.path))


@dataclass(frozen=True)
class Drag(PathTouch):
    """Touch, slide along ``path`` with a firm force against friction, stop, release."""


@dataclass(frozen=True)
class Stroke(PathTouch):
    """Trace ``path`` like a pen stroke, at ≈3.4 cm/s (the paper's 3.37 ± 0.64 cm/s).

    ``times`` (seconds, one a point of ``path``, from 0, never decreasing): the finger is at
    each point at its time, as a logged stroke of a real person was drawn (the $1 logs);
    ``speed`` is then not used."""

    times: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.times is None:
            return
        t = np.asarray(self.times, dtype=float)
        if (
            t.shape != (len(self.path),)
            or not np.isfinite(t).all()
            or t[0] != 0.0
            or np.any(np.diff(t) < 0)
            or t[-1] <= 0.0
        ):
            raise ValueError(
                f"Stroke.times must be one finite time a point ({len(self.path)}), from 0 and "
                f"never decreasing, ending after 0; found {t.shape[0] if t.ndim else t} values"
            )
        object.__setattr__(self, "times", tuple(float(x) for x in t))


@dataclass(frozen=True)
class PutObject(Step):
    """Put an object down: its weight comes on over ``duration_s``."""

    name: str
    mass_kg: float
    point: Point
    duration_s: float = 0.3
    surface: str | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        object.__setattr__(self, "point", _point(self.point))
        _check(self, positive=("mass_kg",), at_least_0=("duration_s",))


@dataclass(frozen=True)
class LiftObject(Step):
    """Lift an object put down earlier (or on the desk from the start)."""

    name: str
    duration_s: float = 0.3

    def __post_init__(self) -> None:
        super().__post_init__()
        _check(self, at_least_0=("duration_s",))


@dataclass(frozen=True)
class Idle(Step):
    """Nothing happens for ``duration_s``."""

    duration_s: float

    def __post_init__(self) -> None:
        super().__post_init__()
        _check(self, at_least_0=("duration_s",))


@dataclass(frozen=True)
class DeskObject:
    """An object lying on the desk from the start (part of the tare)."""

    name: str
    mass_kg: float
    point: Point
    surface: str | None = None
    where: Position | None = field(default=None, compare=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "point", _point(self.point))
        if not self.mass_kg > 0:
            raise ValueError(f"an object's mass must be positive, found {self.mass_kg}")


TOUCH_ACTIONS = (Press, Tap, Ramp, Swipe, Drag, Stroke)  # LongPress is a Press


#: the former names (scripts written against them keep working)
Action = Step
TouchAction = TouchStep
