"""A finger's force over one touch: the envelope (touch, plateau or ramp, release), the rates
it is drawn at, and the tremor and wander that modulate it.

- touch: a quarter sine rising to the target, so the rate is largest at first contact; the
  rate at touch is drawn around the paper's mean of 45 N/s (§3.2);
- release: a quarter cosine, fastest as the finger leaves; its rate is the touch rate times
  a log-normal factor (median 1.8, log-σ 0.7), so release is faster in ≈80 % of presses as
  in the paper (63 of 81, §5.1);
- tremor (three sines in the 8–12 Hz physiological band) and a slow wander (0.3–1.5 Hz)
  multiply the force.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from hapticdesk.sim.human import HumanModel


class TouchSamples(NamedTuple):
    """A touch sampled at its times (what a still or a moving touch's ``sample`` gives)."""

    fn: np.ndarray  # (n,) the normal force the finger applies, N
    uv: np.ndarray  # (n, 2) the contact point in surface coordinates, m
    tangential: np.ndarray  # (n, 2) the force along the surface (u, v), N


def touch_rate(rng: np.random.Generator, human: HumanModel, given: float | None) -> float:
    if given is not None:
        return given
    rate = human.rise_n_per_s + human.rise_sd_n_per_s * rng.standard_normal()
    return max(rate, 0.3 * human.rise_n_per_s, 1.0)


def release_rate(
    rng: np.random.Generator, human: HumanModel, rise: float, given: float | None
) -> float:
    if given is not None:
        return given
    factor = math.exp(
        math.log(max(human.release_factor, 1e-3)) + human.release_log_sd * rng.standard_normal()
    )
    return rise * min(max(factor, 0.5), 5.0)


def modulation(tau: np.ndarray, rng: np.random.Generator, human: HumanModel) -> np.ndarray:
    """1 + tremor + wander, never below 0.1 (the finger keeps pushing)."""
    freq = rng.uniform(8.0, 12.0, 3)
    phase = rng.uniform(0.0, 2 * math.pi, 4)
    slow = rng.uniform(0.3, 1.5)
    tremor = (
        human.tremor
        * math.sqrt(2.0 / 3.0)
        * np.sin(2 * math.pi * freq[None, :] * tau[:, None] + phase[None, :3]).sum(axis=1)
    )
    wander = human.wander * math.sqrt(2.0) * np.sin(2 * math.pi * slow * tau + phase[3])
    return np.maximum(1.0 + tremor + wander, 0.1)


@dataclass
class ForceEnvelope:
    """A force envelope as touch (quarter sine), plateau or linear ramp, release (quarter
    cosine). Times in seconds from first contact."""

    touch_s: float
    level_n: float  # force at the end of the touch
    plateau_s: float
    end_n: float  # force at the end of the plateau (linear from level_n)
    release_s: float

    @property
    def duration(self) -> float:
        return self.touch_s + self.plateau_s + self.release_s

    def envelope(self, tau: np.ndarray) -> np.ndarray:
        t1 = self.touch_s
        t2 = t1 + self.plateau_s
        rise = self.level_n * np.sin(0.5 * math.pi * np.clip(tau / max(t1, 1e-12), 0.0, 1.0))
        frac = np.clip((tau - t1) / max(self.plateau_s, 1e-12), 0.0, 1.0)
        plateau = self.level_n + (self.end_n - self.level_n) * frac
        fall = self.end_n * np.cos(
            0.5 * math.pi * np.clip((tau - t2) / max(self.release_s, 1e-12), 0.0, 1.0)
        )
        out = np.where(tau < t1, rise, np.where(tau < t2, plateau, fall))
        return np.where((tau < 0) | (tau > self.duration), 0.0, out)


def touch_time(force: float, rate: float) -> float:
    """Quarter-sine duration whose slope at zero force is ``rate``."""
    return 0.5 * math.pi * force / rate
