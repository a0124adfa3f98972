"""A scene made concrete for one desk and one seed: when each action happens, and the loads
and ground truth it produces, sample by sample.

The human's randomness is drawn here, once per run, from a generator per action (spawned
from the seed), so the loads do not depend on how the run is later cut into blocks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hapticdesk.errors import ConfigError, Position
from hapticdesk.files.profile import DeskProfile, Surface
from hapticdesk.sim.actions import (
    Drag,
    Idle,
    LiftObject,
    Press,
    PutObject,
    Ramp,
    Step,
    Stroke,
    Swipe,
    Tap,
    TouchStep,
)
from hapticdesk.sim.desk import STANDARD_GRAVITY, point_load
from hapticdesk.sim.scene import Scene
from hapticdesk.sim.touch_track import Touch, touch_track

#: the most samples all the touches of a scene may have together (each touch's track is held
#: for the whole run, 40 bytes a sample: 400 MB)
MAX_TRACK_SAMPLES = 10_000_000
STREAM_HUMAN = 1  # SeedSequence spawn keys: one stream per purpose, independent of each other
STREAM_NOISE = 2
STREAM_DRIFT = 3
STREAM_ACCEL = 4  # the accelerometer's noise
STREAM_CLOCKS = 5  # independent converters' clocks (load cells)

TRUTH_COLUMNS = (
    "true_x",
    "true_y",
    "true_z",
    "true_fn",
    "true_fx",
    "true_fy",
    "true_fz",
    "true_surface",
    "true_action",
)


def stream(seed: int, *key: int) -> np.random.Generator:
    """An independent generator for one purpose (and item) of a run with ``seed``."""
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence(seed, spawn_key=key)))


@dataclass
class ObjectLoad:
    """An object's weight at a point, coming on over [on0, on1] and going off over [off0, off1]."""

    name: str
    force: np.ndarray  # (3,) its weight, N
    point: np.ndarray  # (3,) desk frame
    on0: float = -math.inf
    on1: float = -math.inf
    off0: float = math.inf
    off1: float = math.inf

    def factor(self, t: np.ndarray) -> np.ndarray:
        """How much of the weight rests on the desk at times ``t`` (0 … 1, smooth)."""
        return _smooth_step(t, self.on0, self.on1) - _smooth_step(t, self.off0, self.off1)


def _smooth_step(t: np.ndarray, t0: float, t1: float) -> np.ndarray:
    if not math.isfinite(t0):
        return np.full(len(t), 1.0 if t0 < 0 else 0.0)
    if t1 <= t0:
        return (t >= t0).astype(float)
    x = np.clip((t - t0) / (t1 - t0), 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


@dataclass(frozen=True)
class ActionSpan:
    """When action ``index`` of the scene ran."""

    index: int
    kind: str
    label: str
    start_s: float
    end_s: float


class Timeline:
    """Touches and object loads of one run; renders loads and truth for any sample range."""

    def __init__(self, profile: DeskProfile, scene: Scene, seed: int) -> None:
        self.profile = profile
        self.scene = scene
        self.fs = float(profile.sample_rate_hz)
        self.touches: list[Touch] = []
        self.objects: list[ObjectLoad] = []
        self.spans: list[ActionSpan] = []
        self._track_samples = 0
        surfaces = {s.name: i for i, s in enumerate(profile.surfaces)}

        for obj in scene.objects:
            surf = self._surface(obj.surface, obj.where, surfaces, "an object")
            self._check_inside(surf, np.array([obj.point]), obj.where, f"object `{obj.name}`")
            self.objects.append(self._object_load(obj.name, obj.mass_kg, obj.point, surf))

        cursor = scene.quiet_s
        placed: dict[str, ObjectLoad] = {o.name: o for o in self.objects}
        for index, action in enumerate(scene.actions):
            rng = stream(seed, STREAM_HUMAN, index)
            if action.start_s is not None:
                start = action.start_s
            elif action.wait_s is not None:
                start = cursor + action.wait_s
            else:
                start = cursor if index == 0 else cursor + scene.human.pause(rng)
            if start < scene.quiet_s - 1e-9:
                raise ConfigError(
                    action.where,
                    f"{_kind(action)} starts at {start:g} s, inside the scene's quiet start "
                    f"(quiet_s = {scene.quiet_s:g} s, which the estimator's tare needs)",
                )
            duration = self._place(action, index, start, rng, surfaces, placed)
            self.spans.append(
                ActionSpan(index, _kind(action), action.label, start, start + duration)
            )
            cursor = start + duration

        end = max((s.end_s for s in self.spans), default=scene.quiet_s)
        if scene.duration_s is not None:
            if scene.duration_s + 1e-9 < end:
                raise ConfigError(
                    scene.where,
                    f"the timeline runs until {end:.3f} s, beyond the scene's duration_s "
                    f"{scene.duration_s:g} s",
                )
            self.duration_s = scene.duration_s
        else:
            self.duration_s = end + scene.tail_s
        self.n_samples = int(math.floor(self.duration_s * self.fs + 1e-9)) + 1
        # sample spans of the touches, to find the few that overlap a block quickly
        self._touch_from = np.array([t.k0 for t in self.touches], dtype=np.int64)
        self._touch_to = self._touch_from + np.array(
            [len(t.fn) for t in self.touches], dtype=np.int64
        )

    # --- building -----------------------------------------------------------------------------

    def _surface(
        self, name: str | None, where: Position | None, surfaces: dict[str, int], what: str
    ) -> int:
        name = name if name is not None else self.scene.surface
        if not self.profile.surfaces:
            raise ConfigError(where, f"desk `{self.profile.name}` has no surfaces to put {what} on")
        if name is None:
            return 0
        if name not in surfaces:
            raise ConfigError(
                where,
                f"desk `{self.profile.name}` has no surface `{name}`; it has {', '.join(surfaces)}",
            )
        return surfaces[name]

    def _check_inside(
        self, surf: int, points: np.ndarray, where: Position | None, what: str
    ) -> None:
        surface = self.profile.surfaces[surf]
        outside = ~_inside(surface.polygon, points, tol=1e-9)
        if outside.any():
            u, v = points[np.argmax(outside)]
            lo, hi = surface.polygon.min(axis=0), surface.polygon.max(axis=0)
            raise ConfigError(
                where,
                f"{what}: point ({u:.4g}, {v:.4g}) m lies outside surface `{surface.name}` of "
                f"desk `{self.profile.name}` (its outline spans {lo[0]:g}…{hi[0]:g}, "
                f"{lo[1]:g}…{hi[1]:g} m)",
            )

    def _object_load(
        self, name: str, mass: float, point: tuple[float, float], surf: int
    ) -> ObjectLoad:
        surface = self.profile.surfaces[surf]
        where = surface.to_desk(np.array(point[0]), np.array(point[1]))
        return ObjectLoad(name, np.array([0.0, 0.0, -mass * STANDARD_GRAVITY]), where)

    def _place(
        self,
        action: Step,
        index: int,
        start: float,
        rng: np.random.Generator,
        surfaces: dict[str, int],
        placed: dict[str, ObjectLoad],
    ) -> float:
        kind = _kind(action)
        if isinstance(action, TouchStep):
            surf = self._surface(action.surface, action.where, surfaces, f"a {kind}")
            self._check_inside(surf, _touch_points(action), action.where, kind)
            touch = touch_track(action, start, self.fs, rng, self.scene.human, surf, index)
            self.touches.append(touch)
            self._track_samples += len(touch.fn)
            if self._track_samples > MAX_TRACK_SAMPLES:
                raise ConfigError(
                    action.where,
                    f"the scene's touches last more than {MAX_TRACK_SAMPLES} samples together "
                    f"by this {kind} ({MAX_TRACK_SAMPLES / self.fs:g} s at {self.fs:g} Hz), "
                    "the most a run holds",
                )
            return touch.duration_s
        if isinstance(action, PutObject):
            if action.name in placed and placed[action.name].off0 == math.inf:
                raise ConfigError(action.where, f"object `{action.name}` is already on the desk")
            surf = self._surface(action.surface, action.where, surfaces, "an object")
            self._check_inside(surf, np.array([action.point]), action.where, kind)
            load = self._object_load(action.name, action.mass_kg, action.point, surf)
            load.on0, load.on1 = start, start + action.duration_s
            self.objects.append(load)
            placed[action.name] = load
            return action.duration_s
        if isinstance(action, LiftObject):
            lifted = placed.get(action.name)
            if lifted is None or lifted.off0 != math.inf:
                on_desk = [n for n, o in placed.items() if o.off0 == math.inf]
                raise ConfigError(
                    action.where,
                    f"cannot lift `{action.name}`: it is not on the desk; on the desk: "
                    f"{', '.join(on_desk) or 'nothing'}",
                )
            lifted.off0, lifted.off1 = start, start + action.duration_s
            return action.duration_s
        if isinstance(action, Idle):
            return action.duration_s
        raise TypeError(f"unknown action {type(action).__name__}")

    # --- rendering ----------------------------------------------------------------------------

    def render(self, k0: int, k1: int) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """Loads (n, 6) about the desk origin and ground truth for samples k0 … k1-1.

        The desk's own weight is not included (see :class:`~hapticdesk.sim.SimEffects`).
        """
        n = max(k1 - k0, 0)
        t = np.arange(k0, k0 + n) / self.fs
        loads = np.zeros((n, 6))
        force = np.zeros((n, 3))
        moment_fn = np.zeros((n, 3))  # Σ fn·P, for the centre of pressure
        fn_sum = np.zeros(n)
        surface = np.full(n, -1.0)
        action = np.full(n, -1.0)
        overlapping = np.flatnonzero((self._touch_from < k1) & (self._touch_to > k0))
        for touch in (self.touches[i] for i in overlapping):
            lo, hi = max(k0, touch.k0), min(k1, touch.k0 + len(touch.fn))
            sl = slice(lo - touch.k0, hi - touch.k0)
            out = slice(lo - k0, hi - k0)
            surf: Surface = self.profile.surfaces[touch.surface]
            fn = touch.fn[sl]
            uv = touch.uv[sl]
            tang = touch.tangential[sl]
            point = surf.to_desk(uv[:, 0], uv[:, 1])
            f = -fn[:, None] * surf.normal + tang[:, :1] * surf.u_axis + tang[:, 1:] * surf.v_axis
            loads[out] += point_load(f, point)
            force[out] += f
            moment_fn[out] += fn[:, None] * point
            fn_sum[out] += fn
            touching = fn > 0
            surface[out] = np.where(touching, touch.surface, surface[out])
            action[out] = np.where(touching, touch.action, action[out])
        for obj in self.objects:
            share = obj.factor(t)
            if np.any(share):
                loads += share[:, None] * point_load(obj.force, obj.point)
        touching = fn_sum > 0
        safe = np.where(touching, fn_sum, 1.0)
        centre = np.where(touching[:, None], moment_fn / safe[:, None], np.nan)
        truth = {
            "true_x": centre[:, 0],
            "true_y": centre[:, 1],
            "true_z": centre[:, 2],
            "true_fn": fn_sum,
            "true_fx": force[:, 0],
            "true_fy": force[:, 1],
            "true_fz": force[:, 2],
            "true_surface": surface,
            "true_action": action,
        }
        return loads, truth


def _kind(action: Step) -> str:
    """The scene-file name of an action (``long_press``, ``put`` …)."""
    names = {"LongPress": "long_press", "PutObject": "put", "LiftObject": "lift"}
    name = type(action).__name__
    return names.get(name, name.lower())


def _touch_points(action: TouchStep) -> np.ndarray:
    if isinstance(action, Swipe):
        return np.array([action.from_point, action.to_point])
    if isinstance(action, Drag | Stroke):
        return np.array(action.path)
    if isinstance(action, Press | Tap | Ramp):
        return np.array([action.point])
    raise TypeError(f"unknown touch action {type(action).__name__}")


def _inside(polygon: np.ndarray, points: np.ndarray, tol: float) -> np.ndarray:
    """Points (n, 2) inside a polygon (m, 2) or within ``tol`` of its outline."""
    x, y = points[:, 0:1], points[:, 1:2]
    a = polygon
    b = np.roll(polygon, -1, axis=0)
    # even-odd rule, a ray to +x
    crosses = ((a[:, 1] > y) != (b[:, 1] > y)) & (
        x
        < (b[:, 0] - a[:, 0]) * (y - a[:, 1]) / np.where(b[:, 1] == a[:, 1], 1.0, b[:, 1] - a[:, 1])
        + a[:, 0]
    )
    inside = np.count_nonzero(crosses, axis=1) % 2 == 1
    # distance to each edge, so points on the outline count as inside
    ab = b - a
    length2 = np.maximum(np.sum(ab**2, axis=1), 1e-300)
    s = np.clip(((x - a[:, 0]) * ab[:, 0] + (y - a[:, 1]) * ab[:, 1]) / length2, 0.0, 1.0)
    dx = x - (a[:, 0] + s * ab[:, 0])
    dy = y - (a[:, 1] + s * ab[:, 1])
    near = np.min(dx**2 + dy**2, axis=1) <= tol**2
    return inside | near
