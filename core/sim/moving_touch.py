"""A touch that travels along a path (swipe, drag, stroke): a minimum-jerk speed profile along
any polyline (a shape, a character, a slider), stopping at sharp corners, and the drag against
friction (``friction`` × normal force along the motion, regularised below 5 mm/s)."""

from __future__ import annotations

import math

import numpy as np
import scipy.optimize

from hapticdesk.sim.actions import Drag, Stroke, Swipe
from hapticdesk.sim.force_envelope import (
    ForceEnvelope,
    TouchSamples,
    modulation,
    release_rate,
    touch_rate,
    touch_time,
)
from hapticdesk.sim.human import HumanModel


def min_jerk(x: np.ndarray) -> np.ndarray:
    """The minimum-jerk position profile 10x³ − 15x⁴ + 6x⁵ on [0, 1], clipped outside."""
    x = np.clip(x, 0.0, 1.0)
    return x**3 * (10.0 - 15.0 * x + 6.0 * x**2)


class MovingTouch:
    """A touch that travels along a path: swipe, drag, stroke."""

    SETTLE_S = 0.1  # the finger rests this long after touching and before lifting
    V_STATIC = 0.005  # m/s: below this, friction fades (regularised Coulomb friction)

    def __init__(
        self, action: Swipe | Drag | Stroke, rng: np.random.Generator, human: HumanModel
    ) -> None:
        level, speed = _level_and_speed(action, rng, human)
        if isinstance(action, Swipe):
            path = np.array([action.from_point, action.to_point])
        else:
            path = np.array(action.path)
        path = path + human.aim_sd_m * rng.standard_normal(2)
        steps = np.linalg.norm(np.diff(path, axis=0), axis=1)
        moved = np.concatenate([[True], steps > 0])
        self.path = path[moved]
        self.arc = np.concatenate([[0.0], np.cumsum(steps[steps > 0])])
        self.length = float(self.arc[-1])
        self.move_s = self.length / speed
        # a stroke with logged times: where the finger is when, point by point
        times = getattr(action, "times", None)
        self.timed = None if times is None else np.asarray(times)[moved]
        if self.timed is not None:
            self.move_s = float(self.timed[-1])
        self.friction = human.friction
        rise = touch_rate(rng, human, None)
        release = release_rate(rng, human, rise, None)

        if isinstance(action, Swipe):
            # A quick touch, and the hand's movement carries on past `to`: the finger is
            # lifted as it gets there, still moving. The contact keeps the mean speed.
            touch_s = touch_time(level, 2.0 * rise)
            release_s = min(touch_time(level, 2.0 * release), self.move_s)
            self.move_from = touch_s
            total_s = self.move_s / _min_jerk_inverse(SWIPE_CONTACT_SHARE)
            self.knots = np.array([0.0, self.length / SWIPE_CONTACT_SHARE])
            self.knot_times = np.array([0.0, total_s])
            plateau = self.move_s - release_s
        else:
            # Rest, move, rest. The finger slows to a stop at sharp corners (as in
            # handwriting): one minimum-jerk movement per piece, each at the mean speed.
            touch_s = touch_time(level, rise)
            release_s = touch_time(level, release)
            self.move_from = touch_s + self.SETTLE_S
            if self.timed is not None:  # every logged point is a knot, reached at its time
                self.knots, self.knot_times = self.arc, self.timed
            else:
                corners = np.flatnonzero(_turning_angles(self.path) > math.radians(CORNER_DEG))
                self.knots = self.arc[np.concatenate([[0], corners + 1, [len(self.path) - 1]])]
                self.knot_times = self.knots / speed
            plateau = self.SETTLE_S + self.move_s + self.SETTLE_S
        self.seg = ForceEnvelope(touch_s, level, plateau, level, release_s)
        self.duration = self.seg.duration

    def _arc_at(self, t: np.ndarray) -> np.ndarray:
        """Arc length travelled ``t`` seconds after the movement began."""
        if self.timed is not None:  # logged samples are dense: straight between them
            return np.interp(t, self.knot_times, self.knots)
        piece = np.clip(
            np.searchsorted(self.knot_times, t, side="right") - 1, 0, len(self.knots) - 2
        )
        t0, t1 = self.knot_times[piece], self.knot_times[piece + 1]
        a0, a1 = self.knots[piece], self.knots[piece + 1]
        return a0 + (a1 - a0) * min_jerk((t - t0) / (t1 - t0))

    def sample(
        self, tau: np.ndarray, rng: np.random.Generator, human: HumanModel, fs: float
    ) -> TouchSamples:
        env = self.seg.envelope(tau)
        fn = env * modulation(tau, rng, human)
        s = self._arc_at(tau - self.move_from)
        uv = np.stack([np.interp(s, self.arc, self.path[:, j]) for j in range(2)], axis=1)
        if len(tau) > 1:
            vel = np.gradient(uv, 1.0 / fs, axis=0)
        else:
            vel = np.zeros_like(uv)
        speed = np.linalg.norm(vel, axis=1, keepdims=True)
        tangential = self.friction * fn[:, None] * vel / np.sqrt(speed**2 + self.V_STATIC**2)
        return TouchSamples(fn, uv, tangential)


SWIPE_CONTACT_SHARE = 0.7  # a swipe's contact covers this share of the hand's movement


def _min_jerk_inverse(share: float) -> float:
    """The time fraction at which a minimum-jerk movement has covered ``share`` of its way."""
    return float(scipy.optimize.brentq(lambda x: float(min_jerk(np.array(x))) - share, 0.0, 1.0))


CORNER_DEG = 45.0  # a path turning more than this at a point has a corner there


def _turning_angles(path: np.ndarray) -> np.ndarray:
    """Turning angle (radians) at each inner point of a polyline (n - 2,)."""
    d = np.diff(path, axis=0)
    if len(d) < 2:
        return np.zeros(0)
    a, b = d[:-1], d[1:]
    cross = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    return np.abs(np.arctan2(cross, np.sum(a * b, axis=1)))


def _level_and_speed(
    action: Swipe | Drag | Stroke, rng: np.random.Generator, human: HumanModel
) -> tuple[float, float]:
    """The force a moving finger presses with and its mean speed (given or drawn)."""
    if isinstance(action, Swipe):
        forces, speeds = human.swipe_force_n, human.swipe_speed_m_s
    elif isinstance(action, Drag):
        forces, speeds = human.drag_force_n, human.drag_speed_m_s
    else:
        forces, speeds = human.trace_force_n, (0.0, 0.0)
    level = action.force_n if action.force_n is not None else human.uniform(rng, forces)
    if action.speed is not None:
        speed = action.speed
    elif isinstance(action, Stroke):
        drawn = human.trace_speed_m_s + human.trace_speed_sd_m_s * rng.standard_normal()
        speed = max(drawn, 0.3 * human.trace_speed_m_s, 1e-3)
    else:
        speed = human.uniform(rng, speeds)
    return level, speed
