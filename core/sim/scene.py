"""Scenes: a timeline of what a person does on the desk, from YAML or built in Python.

A scene file (every key is checked; errors name file:line:column and what was expected)::

    name: paper-experiment
    desk: kitamura2017          # optional: the desk to use when none is given
    units: m                    # m | cm | mm for positions, sizes and speeds
    seed: 0                     # default seed (`hapticdesk simulate --seed` overrides)
    quiet_s: 2.0                # nobody touches the desk at first (>= 1.5 s: the tare)
    tail_s: 1.0                 # quiet time after the last action
    surface: top                # default surface of touches
    human: {rise_n_per_s: 45}   # overrides of the human model (HumanModel fields)
    objects:                    # on the desk from the start
      - {name: monitor, mass_kg: 5.0, point: [0.0, 0.2]}
    timeline:
      - press: {point: [-0.3, 0.2], repeat: 3, label: p1}
      - tap: {point: [0.1, 0.0], wait_s: 0.15}
      - long_press: {point: [0, 0], hold_s: 2.5}
      - ramp: {point: [0, 0], from_n: 3, to_n: 25, duration_s: 3}
      - swipe: {from: [-0.1, 0], to: [0.1, 0]}
      - drag: {from: [-0.3, 0.15], to: [0.3, 0.15]}      # or path: [[u, v], ...]
      - stroke: {path: [[0, 0], [0.1, 0.1]]}              # or shape:, text:, file:
      - stroke: {shape: circle, center: [0, 0], size: 0.1, clockwise: false}
      - stroke: {text: 北, center: [0, 0], size: 0.3}
      - put: {object: cup, mass_kg: 0.3, point: [0.2, 0.1]}
      - lift: {object: cup}
      - idle: {duration_s: 2}                              # or idle: 2

Every action also takes ``start_s`` (absolute start), ``wait_s`` (pause before it),
``repeat`` (how many times) and ``label``; touches take ``surface``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hapticdesk.errors import ConfigError, Position
from hapticdesk.files.marked_values import MarkedDict, MarkedList, as_number
from hapticdesk.files.strokefile import read_stroke
from hapticdesk.files.validators import check_keys, choice, flag, number, require_mapping, vector
from hapticdesk.files.yamlfile import load_marked_yaml
from hapticdesk.sim.actions import (
    DeskObject,
    Drag,
    Idle,
    LiftObject,
    LongPress,
    Press,
    PutObject,
    Ramp,
    Step,
    Stroke,
    Swipe,
    Tap,
)
from hapticdesk.sim.human import HumanModel
from hapticdesk.sim.paths import SHAPES, shape_path, text_paths
from hapticdesk.sim.scene_fields import (
    field_human,
    field_integer,
    field_list,
    field_point,
    field_surface,
    field_text,
    path_or_ends,
)

MIN_QUIET_S = 1.5  # the estimator tares over the first second; leave it a margin
#: the longest time a scene may give (quiet_s, tail_s, duration_s, start_s, wait_s, hold_s,
#: an action's duration_s …): a day. What a run may hold in memory is bounded by samples, in
#: the timeline (one touch's track) and in `simulate` (the whole recording).
MAX_SCENE_S = 86_400.0
#: the most times an action may repeat, and the most actions a timeline may expand to
MAX_REPEAT = 10_000
MAX_ACTIONS = 100_000
#: the hardest a scene's finger presses (N: a person leaning their whole weight on it) and
#: the fastest its force may change (N/s): beyond, a typing mistake (a tap of 1e300 N
#: saturated every simulated sensor and no contact was seen)
MAX_FORCE_N = 1_000.0
MAX_FORCE_RATE_N_S = 100_000.0
#: a finger's speed, m/s: slower is a hold, faster no hand moves (a speed of 1e-300 was
#: refused as a swipe of 10^300 samples, written out digit by digit)
MIN_SPEED_M_S, MAX_SPEED_M_S = 0.001, 10.0
#: the heaviest object a scene puts on the desk, kg (its weight at most MAX_FORCE_N: a mass
#: of 1e300 kg saturated every sensor)
MAX_OBJECT_KG = 100.0
UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001}


@dataclass
class Scene:
    """A timeline of actions plus the conditions of the run (see the module docstring)."""

    actions: list[Step]
    quiet_s: float = 2.0
    tail_s: float = 1.0
    duration_s: float | None = None
    surface: str | None = None
    objects: list[DeskObject] = field(default_factory=list)
    human: HumanModel = field(default_factory=HumanModel)
    seed: int = 0
    desk: str | None = None
    name: str = ""
    path: Path | None = None
    where: Position | None = field(default=None, compare=False, repr=False)

    def __post_init__(self) -> None:
        if not self.quiet_s >= 0 or not self.tail_s >= 0:
            raise ValueError("quiet_s and tail_s must be >= 0")
        self.actions = list(self.actions)
        self.objects = list(self.objects)


# --- YAML ------------------------------------------------------------------------------------

_TOP = {
    "name",
    "desk",
    "seed",
    "units",
    "quiet_s",
    "tail_s",
    "duration_s",
    "surface",
    "human",
    "objects",
    "timeline",
}
_COMMON = {"start_s", "wait_s", "repeat", "label"}
_ACTION_KEYS: dict[str, set[str]] = {
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


def load_scene(path: str | Path) -> Scene:
    """Load and validate a scene file; raises :class:`ConfigError` with the position."""
    path = Path(path)
    doc = require_mapping(load_marked_yaml(path), str(path), "a scene")
    return scene_from_mapping(doc, path)


def scene_from_mapping(doc: MarkedDict, path: Path) -> Scene:
    """Validate an already loaded scene mapping (``path`` resolves relative files)."""
    check_keys(doc, _TOP, "the scene", required={"timeline"})
    what = "the scene"
    name = field_text(doc, "name", what, default=path.stem)
    desk = field_text(doc, "desk", what, default="") or None
    seed = field_integer(doc, "seed", what, default=0, minimum=0)
    unit = UNITS[choice(doc, "units", tuple(UNITS), what, default="m")]
    quiet = number(doc, "quiet_s", what, default=2.0, maximum=MAX_SCENE_S)
    if quiet < MIN_QUIET_S:
        raise ConfigError(
            doc.where("quiet_s"),
            f"`quiet_s` must be >= {MIN_QUIET_S:g} s: the estimator tares over the first "
            f"second of a quiet desk; found {quiet:g}",
        )
    tail = number(doc, "tail_s", what, default=1.0, minimum=0.0, maximum=MAX_SCENE_S)
    duration = None
    if "duration_s" in doc:
        duration = number(
            doc, "duration_s", what, minimum=0.0, exclusive_minimum=True, maximum=MAX_SCENE_S
        )
        if duration <= quiet:
            raise ConfigError(
                doc.where("duration_s"), f"`duration_s` must exceed quiet_s ({quiet:g})"
            )
    surface = field_text(doc, "surface", what, default="") or None
    human = field_human(doc["human"], doc.where("human")) if "human" in doc else HumanModel()

    objects: list[DeskObject] = []
    if "objects" in doc:
        raw = field_list(doc, "objects", what)
        for i, item in enumerate(raw):
            m = require_mapping(item, raw.where(i), f"object {i + 1}")
            check_keys(
                m,
                {"name", "mass_kg", "point", "surface"},
                f"object {i + 1}",
                {"name", "mass_kg", "point"},
            )
            objects.append(
                DeskObject(
                    field_text(m, "name", f"object {i + 1}"),
                    number(
                        m,
                        "mass_kg",
                        f"object {i + 1}",
                        minimum=0.0,
                        exclusive_minimum=True,
                        maximum=MAX_OBJECT_KG,
                    ),
                    field_point(m, "point", f"object {i + 1}", unit),
                    field_text(m, "surface", f"object {i + 1}", default="") or None,
                    where=m.where(),
                )
            )

    timeline = field_list(doc, "timeline", what)
    if not timeline:
        raise ConfigError(doc.where("timeline"), "`timeline` must list at least one action")
    actions: list[Step] = []
    for i, item in enumerate(timeline):
        actions.extend(_timeline_item(item, timeline.where(i), i, unit, path))
        if len(actions) > MAX_ACTIONS:
            raise ConfigError(
                timeline.where(i),
                f"the timeline expands to more than {MAX_ACTIONS} actions by here "
                "(with their `repeat`)",
            )
    return Scene(
        actions,
        quiet_s=quiet,
        tail_s=tail,
        duration_s=duration,
        surface=surface,
        objects=objects,
        human=human,
        seed=seed,
        desk=desk,
        name=name,
        path=path,
        where=doc.where(),
    )


def _timeline_item(item: Any, where: Position, index: int, unit: float, path: Path) -> list[Step]:
    what = f"timeline item {index + 1}"
    m = require_mapping(item, where, what)
    if len(m) != 1:
        raise ConfigError(
            where,
            f"{what} must be one action (a single key, one of {', '.join(_ACTION_KEYS)}), "
            f"found {len(m)} keys: {', '.join(m) or 'none'}",
        )
    kind = next(iter(m))
    if kind not in _ACTION_KEYS:
        raise ConfigError(
            m.where(kind, of_key=True),
            f"unknown action `{kind}` in {what}; one of {', '.join(_ACTION_KEYS)}",
        )
    value = as_number(m[kind])
    if kind == "idle" and isinstance(value, int | float) and not isinstance(value, bool):
        shorthand = MarkedDict({"duration_s": value})
        shorthand.position = m.where(kind)
        shorthand.key_positions = {"duration_s": m.where(kind)}
        shorthand.value_positions = {"duration_s": m.where(kind)}
        value = shorthand
    p = require_mapping(value, m.where(kind), f"`{kind}` ({what})")
    what = f"`{kind}` ({what})"
    check_keys(p, _ACTION_KEYS[kind] | _COMMON, what, _REQUIRED.get(kind, set()))
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
    try:
        first = _build(kind, p, what, unit, path, timing)
    except ValueError as err:
        if isinstance(err, ConfigError):
            raise
        raise ConfigError(p.where(), f"{what}: {err}") from None
    out = list(first)
    for _ in range(repeat - 1):
        again = dict(timing, start_s=None)
        out.extend(_build(kind, p, what, unit, path, again))
    return out


def _build(
    kind: str, p: MarkedDict, what: str, unit: float, path: Path, timing: dict[str, Any]
) -> list[Step]:
    def opt(key: str, *, positive: bool = True) -> float | None:
        if key not in p:
            return None
        # a time (`hold_s`, `duration_s`) at most a day; a force and its rate (above)
        largest = {"_n_per_s": MAX_FORCE_RATE_N_S, "_s": MAX_SCENE_S, "_n": MAX_FORCE_N}
        longest = next((v for end, v in largest.items() if key.endswith(end)), None)
        return number(p, key, what, minimum=0.0, exclusive_minimum=positive, maximum=longest)

    def speed() -> float | None:
        if "speed" not in p:
            return None
        lo, hi = MIN_SPEED_M_S / unit, MAX_SPEED_M_S / unit  # in the scene's units
        return number(p, "speed", what, minimum=lo, maximum=hi) * unit

    if kind in ("press", "long_press"):
        cls = LongPress if kind == "long_press" else Press
        return [
            cls(
                field_point(p, "point", what, unit),
                peak_n=opt("peak_n"),
                hold_s=opt("hold_s", positive=False),
                rise_n_per_s=opt("rise_n_per_s"),
                release_n_per_s=opt("release_n_per_s"),
                surface=field_surface(p, what),
                **timing,
            )
        ]
    if kind == "tap":
        return [
            Tap(
                field_point(p, "point", what, unit),
                peak_n=opt("peak_n"),
                duration_s=opt("duration_s"),
                surface=field_surface(p, what),
                **timing,
            )
        ]
    if kind == "ramp":
        from_n, to_n = (
            number(
                p, key, what, default=d, minimum=0.0, exclusive_minimum=True, maximum=MAX_FORCE_N
            )
            for key, d in (("from_n", 3.0), ("to_n", 25.0))
        )
        return [
            Ramp(
                field_point(p, "point", what, unit),
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
                surface=field_surface(p, what),
                **timing,
            )
        ]
    if kind == "swipe":
        a, b = field_point(p, "from", what, unit), field_point(p, "to", what, unit)
        if a == b:
            raise ConfigError(p.where("to"), f"`to` of {what} must differ from `from`")
        return [
            Swipe(
                a,
                b,
                force_n=opt("force_n"),
                speed=speed(),
                surface=field_surface(p, what),
                **timing,
            )
        ]
    if kind == "drag":
        pts = path_or_ends(p, what, unit)
        return [
            Drag(
                pts, force_n=opt("force_n"), speed=speed(), surface=field_surface(p, what), **timing
            )
        ]
    if kind == "stroke":
        return _strokes(p, what, unit, path, timing, speed())
    if kind == "put":
        return [
            PutObject(
                name=field_text(p, "object", what),
                mass_kg=number(
                    p, "mass_kg", what, minimum=0.0, exclusive_minimum=True, maximum=MAX_OBJECT_KG
                ),
                point=field_point(p, "point", what, unit),
                duration_s=number(
                    p, "duration_s", what, default=0.3, minimum=0.0, maximum=MAX_SCENE_S
                ),
                surface=field_surface(p, what),
                **timing,
            )
        ]
    if kind == "lift":
        return [
            LiftObject(
                name=field_text(p, "object", what),
                duration_s=number(
                    p, "duration_s", what, default=0.3, minimum=0.0, maximum=MAX_SCENE_S
                ),
                **timing,
            )
        ]
    return [
        Idle(duration_s=number(p, "duration_s", what, minimum=0.0, maximum=MAX_SCENE_S), **timing)
    ]


def _strokes(
    p: MarkedDict,
    what: str,
    unit: float,
    path: Path,
    timing: dict[str, Any],
    speed: float | None,
) -> list[Step]:
    # in file order, so a second source is reported where it stands
    sources = sorted(
        (k for k in ("path", "shape", "text", "file") if k in p),
        key=lambda k: (p.where(k, of_key=True).line, p.where(k, of_key=True).column),
    )
    if len(sources) != 1:
        raise ConfigError(
            p.where(sources[1], of_key=True) if len(sources) > 1 else p.where(),
            f"{what} needs exactly one of `path`, `shape`, `text` or `file`, found "
            f"{', '.join(f'`{s}`' for s in sources) or 'none'}",
        )
    source = sources[0]
    center = (
        tuple(np.array(vector(p["center"], p.where("center"), f"`center` of {what}", 2)) * unit)
        if "center" in p
        else None
    )
    size = (
        number(p, "size", what, minimum=0.0, exclusive_minimum=True) * unit if "size" in p else None
    )
    rotation = number(p, "rotation_deg", what, default=0.0)
    clockwise = flag(p, "clockwise", what, default=False)
    if "clockwise" in p and source != "shape":
        raise ConfigError(
            p.where("clockwise", of_key=True), f"`clockwise` in {what} applies to `shape` only"
        )
    if "pen_up_s" in p and source != "text":
        raise ConfigError(
            p.where("pen_up_s", of_key=True), f"`pen_up_s` in {what} applies to `text` only"
        )
    force = (
        number(p, "force_n", what, minimum=0.0, exclusive_minimum=True, maximum=MAX_FORCE_N)
        if "force_n" in p
        else None
    )
    surface = field_surface(p, what)
    c = (float(center[0]), float(center[1])) if center is not None else (0.0, 0.0)

    paths: list[np.ndarray]
    if source == "shape":
        name = p["shape"]
        if not isinstance(name, str) or name not in SHAPES:
            raise ConfigError(
                p.where("shape"),
                f"unknown shape {name!r} in {what}; one of {', '.join(sorted(SHAPES))}",
            )
        paths = [shape_path(name, c, size if size is not None else 0.15, rotation, clockwise)]
    elif source == "text":
        text = p["text"]
        if not isinstance(text, str) or not text.strip():
            raise ConfigError(p.where("text"), f"`text` of {what} must be non-empty text")
        try:
            paths = text_paths(text, c, size if size is not None else 0.2, rotation)
        except KeyError as err:
            raise ConfigError(p.where("text"), str(err.args[0])) from None
    else:
        if source == "path":
            raw = p["path"]
            if not isinstance(raw, MarkedList) or len(raw) < 2:
                raise ConfigError(
                    p.where("path"), f"`path` of {what} must list two or more [u, v] points"
                )
            pts = (
                np.array(
                    [
                        vector(q, raw.where(i), f"point {i + 1} of `path`", 2)
                        for i, q in enumerate(raw)
                    ]
                )
                * unit
            )
        else:
            file = p["file"]
            if not isinstance(file, str):
                raise ConfigError(p.where("file"), f"`file` of {what} must be a path")
            target = Path(file) if Path(file).is_absolute() else path.parent / file
            try:
                pts = read_stroke(target)  # metres, as the stroke file format says
            except ConfigError as err:
                raise ConfigError(p.where("file"), f"{what}: {err}") from None
        if size is not None or center is not None:
            # fit the path's bounding box into `size` (keeping its proportions) at `center`
            lo, hi = pts.min(axis=0), pts.max(axis=0)
            extent = float(np.max(hi - lo))
            mid = (lo + hi) / 2.0
            scale = (size / extent) if size is not None and extent > 0 else 1.0
            pts = np.array(c if center is not None else mid) + (pts - mid) * scale
        if rotation:
            a = np.radians(rotation)
            rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
            mid = (pts.min(axis=0) + pts.max(axis=0)) / 2.0
            pts = mid + (pts - mid) @ rot.T
        if not np.any(np.linalg.norm(np.diff(pts, axis=0), axis=1) > 0):
            raise ConfigError(p.where(source), f"`{source}` of {what} needs two distinct points")
        paths = [pts]
    pen_up = number(p, "pen_up_s", what, default=0.45, minimum=0.0, maximum=MAX_SCENE_S)
    label = timing["label"] or (str(p["text"]) if source == "text" else str(p.get("shape", "")))
    out: list[Step] = []
    for i, pts in enumerate(paths):
        t = dict(timing)
        if i > 0:
            t.update(start_s=None, wait_s=pen_up)
        t["label"] = f"{label}#{i + 1}" if len(paths) > 1 else label
        out.append(Stroke(pts, force_n=force, speed=speed, surface=surface, **t))
    return out


# --- small readers ---------------------------------------------------------------------------
