"""One touch action sampled on the scene's clock: its force, contact point and tangential force,
bounded in samples. Each action draws its randomness from its own generator, so editing one
action of a scene leaves every other action unchanged."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from hapticdesk.errors import ConfigError
from hapticdesk.sim.actions import Drag, Press, Ramp, Stroke, Swipe, Tap, TouchStep
from hapticdesk.sim.human import HumanModel
from hapticdesk.sim.moving_touch import MovingTouch
from hapticdesk.sim.still_touch import StillTouch, press_touch, ramp_touch, tap_touch

#: the most samples one touch's track may have (its force, point and tangential force are
#: held for the whole run: 40 bytes a sample, 80 MB); 28 min at 1.2 kHz
MAX_TOUCH_SAMPLES = 2_000_000


@dataclass
class Touch:
    """One finger contact sampled on the scene's clock, samples ``k0 … k0 + len(fn) - 1``.

    ``fn`` (n,) the normal force the finger applies (N, ≥ 0); ``uv`` (n, 2) the contact
    point in surface coordinates (m); ``tangential`` (n, 2) the force the finger applies
    along the surface (N, in u and v); ``duration_s`` how long its action lasts (the next
    action starts after it).
    """

    k0: int
    fn: np.ndarray
    uv: np.ndarray
    tangential: np.ndarray
    surface: int
    action: int
    duration_s: float


def touch_track(
    action: TouchStep,
    t0: float,
    fs: float,
    rng: np.random.Generator,
    human: HumanModel,
    surface: int = 0,
    index: int = 0,
) -> Touch:
    """Sample ``action`` starting at time ``t0`` (s) at ``fs`` Hz."""
    profile: StillTouch | MovingTouch
    if isinstance(action, Press):
        profile = press_touch(action, rng, human)
    elif isinstance(action, Tap):
        profile = tap_touch(action, rng, human)
    elif isinstance(action, Ramp):
        profile = ramp_touch(action, rng, human)
    elif isinstance(action, Swipe | Drag | Stroke):
        profile = MovingTouch(action, rng, human)
    else:
        raise TypeError(f"not a touch action: {type(action).__name__}")
    duration = profile.duration
    k0 = math.ceil(t0 * fs - 1e-9)
    k1 = math.floor((t0 + duration) * fs + 1e-9)
    if k1 - k0 + 1 > MAX_TOUCH_SAMPLES:  # before its arrays are made
        kind = {"LongPress": "long_press"}.get(type(action).__name__, type(action).__name__)
        raise ConfigError(
            action.where,
            f"this {kind.lower()} lasts {duration:g} s, {k1 - k0 + 1} samples at {fs:g} Hz; one "
            f"touch may have at most {MAX_TOUCH_SAMPLES} samples ({MAX_TOUCH_SAMPLES / fs:g} s "
            "at this desk's rate)",
        )
    tau = np.arange(k0, k1 + 1) / fs - t0
    sampled = profile.sample(tau, rng, human, fs)
    return Touch(k0, sampled.fn, sampled.uv, sampled.tangential, surface, index, duration)
