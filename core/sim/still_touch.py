"""A touch that stays put (press, long press, tap, ramp): its force envelope, where the finger
lands around the target, the pad's roll as the force grows and the slight sideways push (a
tangential force up to ``tangential`` × the normal force, in a random direction)."""

from __future__ import annotations

import math

import numpy as np

from hapticdesk.sim.actions import LongPress, Press, Ramp, Tap
from hapticdesk.sim.force_envelope import (
    ForceEnvelope,
    TouchSamples,
    modulation,
    release_rate,
    touch_rate,
    touch_time,
)
from hapticdesk.sim.human import HumanModel


class StillTouch:
    """A touch that stays put: press, tap, ramp."""

    def __init__(
        self,
        action: Press | Tap | Ramp,
        seg: ForceEnvelope,
        rng: np.random.Generator,
        human: HumanModel,
    ) -> None:
        self.seg = seg
        self.duration = seg.duration
        target = np.array(action.point)
        self.point = target + human.aim_sd_m * rng.standard_normal(2)
        roll_dir = rng.uniform(0.0, 2 * math.pi)
        self.roll = (
            human.roll_m
            * rng.uniform(0.5, 1.5)
            * np.array([math.cos(roll_dir), math.sin(roll_dir)])
        )
        side_dir = rng.uniform(0.0, 2 * math.pi)
        self.side = (
            human.tangential
            * rng.uniform(0.0, 1.0)
            * np.array([math.cos(side_dir), math.sin(side_dir)])
        )
        self.peak = max(seg.level_n, seg.end_n)

    def sample(
        self, tau: np.ndarray, rng: np.random.Generator, human: HumanModel, fs: float
    ) -> TouchSamples:
        env = self.seg.envelope(tau)
        fn = env * modulation(tau, rng, human)
        uv = self.point + (env / self.peak)[:, None] * self.roll
        return TouchSamples(fn, uv, fn[:, None] * self.side)


def press_touch(action: Press, rng: np.random.Generator, human: HumanModel) -> StillTouch:
    """A press or long press: rise to its peak, hold, release."""
    peak = action.peak_n if action.peak_n is not None else human.uniform(rng, human.peak_n)
    hold_range = human.long_hold_s if isinstance(action, LongPress) else human.hold_s
    hold = action.hold_s if action.hold_s is not None else human.uniform(rng, hold_range)
    rise = touch_rate(rng, human, action.rise_n_per_s)
    release = release_rate(rng, human, rise, action.release_n_per_s)
    seg = ForceEnvelope(touch_time(peak, rise), peak, hold, peak, touch_time(peak, release))
    return StillTouch(action, seg, rng, human)


def tap_touch(action: Tap, rng: np.random.Generator, human: HumanModel) -> StillTouch:
    """A tap: a short rise, a brief top and a release, shares of its duration."""
    peak = action.peak_n if action.peak_n is not None else human.uniform(rng, human.tap_peak_n)
    dur = (
        action.duration_s
        if action.duration_s is not None
        else human.uniform(rng, human.tap_duration_s)
    )
    seg = ForceEnvelope(0.45 * dur, peak, 0.15 * dur, peak, 0.4 * dur)
    return StillTouch(action, seg, rng, human)


def ramp_touch(action: Ramp, rng: np.random.Generator, human: HumanModel) -> StillTouch:
    """A ramp: rise to ``from_n``, change linearly to ``to_n``, release."""
    rise = touch_rate(rng, human, None)
    release = release_rate(rng, human, rise, None)
    seg = ForceEnvelope(
        touch_time(action.from_n, rise),
        action.from_n,
        action.duration_s,
        action.to_n,
        touch_time(action.to_n, release),
    )
    return StillTouch(action, seg, rng, human)
