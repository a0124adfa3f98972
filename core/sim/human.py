"""The human model: the distributions a simulated person's touches are drawn from (their force
rates, peaks, holds, tremor, aim, friction and speeds), checked when made.

How a touch uses them: :mod:`.touch_track` samples one action, with its force shaped by
:mod:`.force_envelope` and its point by :mod:`.still_touch` or :mod:`.moving_touch`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

Range = tuple[float, float]

# settings that may be 0 (switching an effect off); every other one must be positive
_MAY_BE_ZERO = frozenset(
    {
        "rise_sd_n_per_s",
        "release_log_sd",
        "hold_s",
        "long_hold_s",
        "tremor",
        "wander",
        "tangential",
        "roll_m",
        "aim_sd_m",
        "friction",
        "trace_speed_sd_m_s",
        "pause_s",
    }
)


@dataclass(frozen=True)
class HumanModel:
    """Distributions of the human's actions. Ranges are uniform [low, high]."""

    rise_n_per_s: float = 45.0  # mean force rate at touch (paper §3.2)
    rise_sd_n_per_s: float = 10.0
    release_factor: float = 1.8  # median of release rate / touch rate
    release_log_sd: float = 0.7
    peak_n: Range = (15.0, 25.0)  # presses (paper: "20 N and more")
    hold_s: Range = (0.6, 1.5)
    long_hold_s: Range = (2.0, 3.0)
    tap_peak_n: Range = (2.0, 5.0)
    tap_duration_s: Range = (0.08, 0.16)
    tremor: float = 0.015  # RMS of the 8–12 Hz tremor, relative to the force
    wander: float = 0.03  # RMS of the slow force wander, relative
    tangential: float = 0.08  # a press's sideways force, at most this × the normal force
    roll_m: float = 0.001  # how far the contact point rolls as the force builds up
    aim_sd_m: float = 0.002  # scatter of where the finger lands around the target
    friction: float = 0.5  # kinetic friction coefficient, finger on the surface
    trace_speed_m_s: float = 0.0337  # paper §5.3: 3.37 ± 0.644 cm/s
    trace_speed_sd_m_s: float = 0.00644
    trace_force_n: Range = (12.0, 20.0)  # paper §5.3: "a large force" while tracing
    drag_speed_m_s: Range = (0.05, 0.12)
    drag_force_n: Range = (6.0, 12.0)
    swipe_speed_m_s: Range = (0.25, 0.5)
    swipe_force_n: Range = (3.0, 7.0)
    pause_s: Range = (0.6, 1.2)  # between actions when the scene does not say

    def __post_init__(self) -> None:
        for name, value in self.__dict__.items():
            values = value if isinstance(value, tuple) else (value,)
            low = 0.0 if name in _MAY_BE_ZERO else 1e-9
            if not all(math.isfinite(v) and v >= low for v in values):
                sign = ">= 0" if name in _MAY_BE_ZERO else "> 0"
                raise ValueError(f"HumanModel.{name} must be finite and {sign}, found {value}")
            if isinstance(value, tuple) and (len(value) != 2 or value[0] > value[1]):
                raise ValueError(f"HumanModel.{name} must be a range (low, high), found {value}")

    def uniform(self, rng: np.random.Generator, rng_range: Range) -> float:
        return float(rng.uniform(rng_range[0], rng_range[1]))

    def pause(self, rng: np.random.Generator) -> float:
        return self.uniform(rng, self.pause_s)
