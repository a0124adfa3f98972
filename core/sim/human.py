"""The human model: how a finger's force and contact point evolve during one touch action.

Shapes of the force (normal to the surface):

- touch: a quarter sine rising to the target, so the rate is largest at first contact; the
  rate at touch is drawn around the paper's mean of 45 N/s (§3.2);
- release: a quarter cosine, fastest as the finger leaves; its rate is the touch rate times
  a log-normal factor (median 1.8, log-σ 0.7), so release is faster in ≈80 % of presses as
  in the paper (63 of 81, §5.1);
- tremor (three sines in the 8–12 Hz physiological band) and a slow wander (0.3–1.5 Hz)
  multiply the force;
- a press pushes slightly sideways (a tangential force up to ``tangential`` × the normal
  force, in a random direction) and the finger pad rolls by ≈1 mm as the force grows;
- a moving finger drags against friction (tangential force ``friction`` × normal force along
  the motion, regularised below 5 mm/s) and follows a minimum-jerk speed profile along its
  path (any polyline: a shape, a character, a slider).

Each action draws its randomness from its own generator, so editing one action of a scene
leaves every other action unchanged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.optimize

from hapticdesk.errors import ConfigError
from hapticdesk.sim.actions import Drag, LongPress, Press, Ramp, Stroke, Swipe, Tap, TouchStep

Range = tuple[float, float]

#: the most samples one touch's track may have (its force, point and tangential force are
#: held for the whole run: 40 bytes a sample, 80 MB); 28 min at 1.2 kHz
MAX_TOUCH_SAMPLES = 2_000_000


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


@dataclass
class Touch:
    """One finger contact sampled on the scene's clock, samples ``k0 … k0 + len(fn) - 1``.

    ``fn`` (n,) the normal force the finger applies (N, ≥ 0); ``uv`` (n, 2) the contact
    point in surface coordinates (m); ``tangential`` (n, 2) the force the finger applies
    along the surface (N, in u and v).
    """

    k0: int
    fn: np.ndarray
    uv: np.ndarray
    tangential: np.ndarray
    surface: int
    action: int


def touch_track(
    action: TouchStep,
    t0: float,
    fs: float,
    rng: np.random.Generator,
    human: HumanModel,
    surface: int = 0,
    index: int = 0,
) -> tuple[Touch, float]:
    """Sample ``action`` starting at time ``t0`` (s) at ``fs`` Hz; returns it and its duration."""
    profile: _Stationary | _Moving
    if isinstance(action, Press):
        profile = _press(action, rng, human)
    elif isinstance(action, Tap):
        profile = _tap(action, rng, human)
    elif isinstance(action, Ramp):
        profile = _ramp(action, rng, human)
    elif isinstance(action, Swipe | Drag | Stroke):
        profile = _moving(action, rng, human)
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
    fn, uv, tangential = profile.sample(tau, rng, human, fs)
    return Touch(k0, fn, uv, tangential, surface, index), duration


# --- force envelopes ------------------------------------------------------------------------


def _rate(rng: np.random.Generator, human: HumanModel, given: float | None) -> float:
    if given is not None:
        return given
    rate = human.rise_n_per_s + human.rise_sd_n_per_s * rng.standard_normal()
    return max(rate, 0.3 * human.rise_n_per_s, 1.0)


def _release_rate(
    rng: np.random.Generator, human: HumanModel, rise: float, given: float | None
) -> float:
    if given is not None:
        return given
    factor = math.exp(
        math.log(max(human.release_factor, 1e-3)) + human.release_log_sd * rng.standard_normal()
    )
    return rise * min(max(factor, 0.5), 5.0)


def _modulation(tau: np.ndarray, rng: np.random.Generator, human: HumanModel) -> np.ndarray:
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
class _Segments:
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


def _touch_time(force: float, rate: float) -> float:
    """Quarter-sine duration whose slope at zero force is ``rate``."""
    return 0.5 * math.pi * force / rate


class _Stationary:
    """A touch that stays put: press, tap, ramp."""

    def __init__(
        self,
        action: Press | Tap | Ramp,
        seg: _Segments,
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
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        env = self.seg.envelope(tau)
        fn = env * _modulation(tau, rng, human)
        uv = self.point + (env / self.peak)[:, None] * self.roll
        return fn, uv, fn[:, None] * self.side


def _press(action: Press, rng: np.random.Generator, human: HumanModel) -> _Stationary:
    peak = action.peak_n if action.peak_n is not None else human.uniform(rng, human.peak_n)
    hold_range = human.long_hold_s if isinstance(action, LongPress) else human.hold_s
    hold = action.hold_s if action.hold_s is not None else human.uniform(rng, hold_range)
    rise = _rate(rng, human, action.rise_n_per_s)
    release = _release_rate(rng, human, rise, action.release_n_per_s)
    seg = _Segments(_touch_time(peak, rise), peak, hold, peak, _touch_time(peak, release))
    return _Stationary(action, seg, rng, human)


def _tap(action: Tap, rng: np.random.Generator, human: HumanModel) -> _Stationary:
    peak = action.peak_n if action.peak_n is not None else human.uniform(rng, human.tap_peak_n)
    dur = (
        action.duration_s
        if action.duration_s is not None
        else human.uniform(rng, human.tap_duration_s)
    )
    seg = _Segments(0.45 * dur, peak, 0.15 * dur, peak, 0.4 * dur)
    return _Stationary(action, seg, rng, human)


def _ramp(action: Ramp, rng: np.random.Generator, human: HumanModel) -> _Stationary:
    rise = _rate(rng, human, None)
    release = _release_rate(rng, human, rise, None)
    seg = _Segments(
        _touch_time(action.from_n, rise),
        action.from_n,
        action.duration_s,
        action.to_n,
        _touch_time(action.to_n, release),
    )
    return _Stationary(action, seg, rng, human)


def min_jerk(x: np.ndarray) -> np.ndarray:
    """The minimum-jerk position profile 10x³ − 15x⁴ + 6x⁵ on [0, 1], clipped outside."""
    x = np.clip(x, 0.0, 1.0)
    return x**3 * (10.0 - 15.0 * x + 6.0 * x**2)


class _Moving:
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
        rise = _rate(rng, human, None)
        release = _release_rate(rng, human, rise, None)

        if isinstance(action, Swipe):
            # A quick touch, and the hand's movement carries on past `to`: the finger is
            # lifted as it gets there, still moving. The contact keeps the mean speed.
            touch_s = _touch_time(level, 2.0 * rise)
            release_s = min(_touch_time(level, 2.0 * release), self.move_s)
            self.move_from = touch_s
            total_s = self.move_s / _min_jerk_inverse(SWIPE_CONTACT_SHARE)
            self.knots = np.array([0.0, self.length / SWIPE_CONTACT_SHARE])
            self.knot_times = np.array([0.0, total_s])
            plateau = self.move_s - release_s
        else:
            # Rest, move, rest. The finger slows to a stop at sharp corners (as in
            # handwriting): one minimum-jerk movement per piece, each at the mean speed.
            touch_s = _touch_time(level, rise)
            release_s = _touch_time(level, release)
            self.move_from = touch_s + self.SETTLE_S
            if self.timed is not None:  # every logged point is a knot, reached at its time
                self.knots, self.knot_times = self.arc, self.timed
            else:
                corners = np.flatnonzero(_turning_angles(self.path) > math.radians(CORNER_DEG))
                self.knots = self.arc[np.concatenate([[0], corners + 1, [len(self.path) - 1]])]
                self.knot_times = self.knots / speed
            plateau = self.SETTLE_S + self.move_s + self.SETTLE_S
        self.seg = _Segments(touch_s, level, plateau, level, release_s)
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
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        env = self.seg.envelope(tau)
        fn = env * _modulation(tau, rng, human)
        s = self._arc_at(tau - self.move_from)
        uv = np.stack([np.interp(s, self.arc, self.path[:, j]) for j in range(2)], axis=1)
        if len(tau) > 1:
            vel = np.gradient(uv, 1.0 / fs, axis=0)
        else:
            vel = np.zeros_like(uv)
        speed = np.linalg.norm(vel, axis=1, keepdims=True)
        tangential = self.friction * fn[:, None] * vel / np.sqrt(speed**2 + self.V_STATIC**2)
        return fn, uv, tangential


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


def _moving(action: Swipe | Drag | Stroke, rng: np.random.Generator, human: HumanModel) -> _Moving:
    return _Moving(action, rng, human)
