"""The desk simulator: a physical desk on force/torque sensors, a human, and scenes.

    from hapticdesk.sim import load_scene, simulate, SimSource, Scene
    scene = load_scene("examples/scenes/paper-experiment.yaml")   # ConfigError on bad YAML
    rec = simulate(profile, scene, seed=0)                          # a Recording with truth
    src = SimSource(profile, scene, seed=0, block_size=12)          # a Source of blocks

Modules: :mod:`~hapticdesk.sim.desk` (rigid desk on spring legs),
:mod:`~hapticdesk.sim.discrete_desk` (its exact discretisation),
:mod:`~hapticdesk.sim.sensors` (noise, resolution, saturation, drift),
:mod:`~hapticdesk.sim.human` (the person's distributions) and
:mod:`~hapticdesk.sim.touch_track` (force and contact over time), :mod:`~hapticdesk.sim.actions`
and :mod:`~hapticdesk.sim.scene` (what happens when), :mod:`~hapticdesk.sim.paths` (paths),
:mod:`~hapticdesk.sim.timeline` (a scene made concrete), :mod:`~hapticdesk.sim.simulator`.
See docs/simulator.md.
"""

from hapticdesk.sim.actions import (
    Action,
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
    TouchStep,
)
from hapticdesk.sim.desk import DeskModel, DeskParameters
from hapticdesk.sim.human import HumanModel
from hapticdesk.sim.paths import GLYPHS, SHAPES, shape_path, text_paths
from hapticdesk.sim.scene import Scene, load_scene
from hapticdesk.sim.sensors import SensorParameters
from hapticdesk.sim.simulator import SimEffects, SimSource, SimulationRun, simulate
from hapticdesk.sim.timeline import TRUTH_COLUMNS

__all__ = [
    "GLYPHS",
    "SHAPES",
    "TRUTH_COLUMNS",
    "Action",
    "DeskModel",
    "DeskObject",
    "DeskParameters",
    "Drag",
    "HumanModel",
    "Idle",
    "LiftObject",
    "LongPress",
    "Press",
    "PutObject",
    "Ramp",
    "Scene",
    "SensorParameters",
    "SimEffects",
    "SimSource",
    "SimulationRun",
    "Step",
    "Stroke",
    "Swipe",
    "Tap",
    "TouchStep",
    "load_scene",
    "shape_path",
    "simulate",
    "text_paths",
]
