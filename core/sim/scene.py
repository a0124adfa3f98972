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
from typing import NamedTuple

from hapticdesk.errors import ConfigError, Position
from hapticdesk.files.marked_values import MarkedDict
from hapticdesk.files.validators import check_keys, choice, number, require_mapping
from hapticdesk.files.yamlfile import load_marked_yaml
from hapticdesk.sim.actions import DeskObject, Step
from hapticdesk.sim.human import HumanModel
from hapticdesk.sim.scene_fields import (
    field_human,
    field_integer,
    field_list,
    field_point,
    field_text,
)
from hapticdesk.sim.scene_limits import (
    MAX_ACTIONS,
    MAX_OBJECT_KG,
    MAX_SCENE_S,
    MIN_QUIET_S,
    UNITS,
)
from hapticdesk.sim.scene_steps import timeline_steps


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
    times = _scene_times(doc)
    surface = field_text(doc, "surface", what, default="") or None
    human = field_human(doc["human"], doc.where("human")) if "human" in doc else HumanModel()
    objects = _objects(doc, unit)
    return Scene(
        _timeline(doc, unit, path),
        **times._asdict(),
        surface=surface,
        objects=objects,
        human=human,
        seed=seed,
        desk=desk,
        name=name,
        path=path,
        where=doc.where(),
    )


class _SceneTimes(NamedTuple):
    """A scene's times, as :class:`Scene` names them."""

    quiet_s: float
    tail_s: float
    duration_s: float | None


def _scene_times(doc: MarkedDict) -> _SceneTimes:
    """The quiet time first, the tail after the last action and the whole run if given."""
    what = "the scene"
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
    return _SceneTimes(quiet, tail, duration)


def _objects(doc: MarkedDict, unit: float) -> list[DeskObject]:
    """The objects on the desk from the start."""
    objects: list[DeskObject] = []
    if "objects" not in doc:
        return objects
    raw = field_list(doc, "objects", "the scene")
    for i, item in enumerate(raw):
        what = f"object {i + 1}"
        m = require_mapping(item, raw.where(i), what)
        check_keys(m, {"name", "mass_kg", "point", "surface"}, what, {"name", "mass_kg", "point"})
        name = field_text(m, "name", what)
        mass = number(
            m, "mass_kg", what, minimum=0.0, exclusive_minimum=True, maximum=MAX_OBJECT_KG
        )
        objects.append(
            DeskObject(
                name,
                mass,
                field_point(m, "point", what, unit),
                field_text(m, "surface", what, default="") or None,
                where=m.where(),
            )
        )
    return objects


def _timeline(doc: MarkedDict, unit: float, path: Path) -> list[Step]:
    """Every step of the timeline, each item's ``repeat`` expanded, at most MAX_ACTIONS."""
    timeline = field_list(doc, "timeline", "the scene")
    if not timeline:
        raise ConfigError(doc.where("timeline"), "`timeline` must list at least one action")
    actions: list[Step] = []
    for i, item in enumerate(timeline):
        actions.extend(timeline_steps(item, timeline.where(i), i, unit, path))
        if len(actions) > MAX_ACTIONS:
            raise ConfigError(
                timeline.where(i),
                f"the timeline expands to more than {MAX_ACTIONS} actions by here "
                "(with their `repeat`)",
            )
    return actions
