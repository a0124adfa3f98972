"""One touch as the recognizers see it: from ``down`` to ``up``, with the best position so far.

The estimator gives every contact sample a 1-σ uncertainty ``sigma_m``. A tap or press is
judged by the precision-weighted mean over the whole touch (weights 1/σ², the minimum-variance
combination of independent estimates), not by the first, noisiest samples. Moving gestures
(slide, stroke) use a track smoothed the same way over a short sliding time constant.

A sample that jumps away from the last accepted one by much more than both σ allow (and
farther than a finger moves in the time between) is left out: the differentiated-force
candidate assumes a still finger (paper eq. 11), and a finger lifting off while it moves
can place the release tens of centimetres away with a σ that does not say so.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from hapticdesk.estimator.contacts import MULTI_LAG_S, ContactEvent

#: time constant of the smoothed track used by slides and strokes, seconds
TRACK_TIME_CONSTANT_S = 0.03
#: no sample is trusted to better than this (keeps weights finite on noise-free input)
SIGMA_FLOOR_M = 1e-4
#: a sample farther from the last accepted one than this many combined σ (plus what a finger
#: can travel meanwhile) is an outlier
GATE_SIGMAS = 4.0
#: fastest finger motion taken into account by the gate, m/s
MAX_FINGER_SPEED_M_S = 1.5
#: outliers that last longer than this are believed after all (the touch did move there)
GATE_RESET_S = 0.08
#: a still touch (a tap) is placed by its pressed samples after this share of them
#: (:meth:`Touch.settled`): its first ones are farther off. On the 120-desk sweep's 31,923
#: guard-less taps (median error 4.8 mm by the whole touch's mean, 4.4 by its last quarter's;
#: light ones, under 3 N, 7.0 and 6.6; the 399 the tap guard refused or let into a wrong
#: button 15.2 and 14.5). Chosen with the guard's odds leaving one desk out
#: (scripts/tap_guard_loo.py: shares 0-0.9; recognizer.LOG_ODDS)
SETTLED_SHARE = 0.7


class BestPoint(NamedTuple):
    """Where a touch is, by the precision-weighted mean of its samples (:meth:`Touch.best`)."""

    x: float  # desk frame, m
    y: float
    sigma_m: float  # the mean's 1-σ, as if the samples' errors were independent


class Touch:
    """What is known about the current touch. The engine updates it; recognizers read it."""

    def __init__(self, t_down: float, delay_s: float = 0.0, pressed_n: float = 0.0) -> None:
        self.t_down = t_down
        #: samples below this force are the touch's tail (the finger landing or lifting
        #: off): where the touch is and whether it moved is judged without them
        self.pressed_n = pressed_n
        #: how far the positions run behind the finger: the estimator's low-pass delay (a
        #: moving finger is seen where it was this long ago); 0 for contacts that do not lag
        self.delay_s = delay_s
        self.t_up: float | None = None
        self.t_last = t_down
        self.surface = -1  # surface of the first located sample
        self.force_n = 0.0
        self.peak_force_n = 0.0
        self._t: list[float] = []
        self._x: list[float] = []
        self._y: list[float] = []
        self._sigma: list[float] = []
        self._sx: list[float] = []  # smoothed track
        self._sy: list[float] = []
        self._sum_w = self._sum_wx = self._sum_wy = 0.0
        self._pressed: list[bool] = []
        self._force: list[float] = []
        self._shear: list[float] = []  # pressed located samples' shear (ContactEvent.shear)
        self._drag_x = self._drag_y = 0.0  # their drag (ContactEvent.drag_x, drag_y), summed
        self._drag_length = 0.0  # ... and its lengths summed
        self._pressed_w = self._pressed_wx = self._pressed_wy = 0.0
        self._pressed_n = 0  # pressed located samples in the sums
        self._ema_w = self._ema_wx = self._ema_wy = 0.0
        self._outliers_since: float | None = None  # start of the current run of outliers
        self.outliers = 0  # samples left out by the gate
        #: the touch was already down when the stream came back from a gap: its start was
        #: not seen, so a short rest of it is no tap (touch_tracker.TouchTracker sets it)
        self.began_unseen = False
        #: a second finger landed during the touch (the estimator's ``FLAG_MULTI``); the
        #: samples from then on place the fingers' centre of pressure, not a finger, so the
        #: touch's position stays the first finger's
        self.multi = False
        #: where the second finger landed (x, y), once the estimator placed it
        self.second: tuple[float, float] | None = None
        #: the gesture that holds this touch (arbitration: the first of ``arbitration.ORDER``
        #: that fired an event a binding reacts to), None while none did; set by the engine
        self.claimed_by: str | None = None
        #: the load is as still as an object put down and the estimator has not yet decided
        #: (the latest event's ``resting``): a hold waits for the verdict
        self.resting = False

    def add(self, event: ContactEvent) -> None:
        """Take one contact event of this touch (the engine calls this before the recognizers)."""
        self.t_last = event.t
        self.force_n = event.force_n
        self.resting = event.resting
        if event.kind == "up":
            self.t_up = event.t
            return
        self.peak_force_n = max(self.peak_force_n, event.force_n)
        if event.multi:
            if not self.multi:
                self.multi = True
                # the landing is seen from the change over the last MULTI_LAG_S: the samples
                # since then may already place both fingers' centre of pressure
                self._forget_since(event.t - MULTI_LAG_S)
            if event.located2:
                self.second = (event.x2, event.y2)
            return
        if not event.located:
            return
        if self.surface < 0:
            self.surface = event.surface
        elif event.surface != self.surface:
            return  # one resultant force cannot touch two surfaces; keep the first
        if event.force_n >= self.pressed_n:  # (whatever the gate says of its position)
            self._shear.append(event.shear)
            self._drag_x += event.drag_x
            self._drag_y += event.drag_y
            self._drag_length += math.hypot(event.drag_x, event.drag_y)
        sigma = max(event.sigma_m, SIGMA_FLOOR_M)
        if self._t and not self._accept(event, sigma):
            self.outliers += 1
            return
        w = 1.0 / (sigma * sigma)
        pressed = event.force_n >= self.pressed_n
        self._pressed.append(pressed)
        self._force.append(event.force_n)
        self._weigh(w, event.x, event.y, pressed)
        if self._t:
            decay = math.exp(-(event.t - self._t[-1]) / TRACK_TIME_CONSTANT_S)
            self._ema_w *= decay
            self._ema_wx *= decay
            self._ema_wy *= decay
        self._ema_w += w
        self._ema_wx += w * event.x
        self._ema_wy += w * event.y
        self._t.append(event.t)
        self._x.append(event.x)
        self._y.append(event.y)
        self._sigma.append(sigma)
        self._sx.append(self._ema_wx / self._ema_w)
        self._sy.append(self._ema_wy / self._ema_w)

    def _forget_since(self, t: float) -> None:
        """Leave the located samples from ``t`` on out of the touch's position."""
        keep = len(self._t)
        while keep and self._t[keep - 1] >= t:
            keep -= 1
        if keep == len(self._t):
            return
        for samples in (
            self._t,
            self._x,
            self._y,
            self._sigma,
            self._sx,
            self._sy,
            self._pressed,
            self._force,
        ):
            del samples[keep:]
        self._sum_w = self._sum_wx = self._sum_wy = 0.0
        self._pressed_w = self._pressed_wx = self._pressed_wy = 0.0
        self._pressed_n = 0
        for x, y, sigma, pressed in zip(self._x, self._y, self._sigma, self._pressed, strict=True):
            self._weigh(1.0 / (sigma * sigma), x, y, pressed)

    def _weigh(self, w: float, x: float, y: float, pressed: bool) -> None:
        """Add one accepted sample to the sums of :meth:`best`."""
        self._sum_w += w
        self._sum_wx += w * x
        self._sum_wy += w * y
        if pressed:
            self._pressed_w += w
            self._pressed_wx += w * x
            self._pressed_wy += w * y
            self._pressed_n += 1

    def _accept(self, event: ContactEvent, sigma: float) -> bool:
        """The gate (see the module docstring)."""
        last_sigma = self._sigma[-1]
        allowed = GATE_SIGMAS * math.sqrt(sigma * sigma + last_sigma * last_sigma)
        allowed += MAX_FINGER_SPEED_M_S * (event.t - self._t[-1])
        if math.hypot(event.x - self._x[-1], event.y - self._y[-1]) <= allowed:
            self._outliers_since = None
            return True
        if self._outliers_since is None:
            self._outliers_since = event.t
        if event.t - self._outliers_since > GATE_RESET_S:
            self._outliers_since = None
            self._ema_w = self._ema_wx = self._ema_wy = 0.0  # the track restarts here
            return True
        return False

    @property
    def located(self) -> bool:
        """Whether any sample of the touch was placed on a surface."""
        return bool(self._t)

    @property
    def samples(self) -> int:
        """Number of located samples."""
        return len(self._t)

    def duration(self) -> float:
        """Seconds from down to up (or to the latest sample while still down)."""
        return (self.t_up if self.t_up is not None else self.t_last) - self.t_down

    def best(self) -> BestPoint:
        """The precision-weighted mean of the located samples pressed at least
        ``pressed_n`` so far (of every located sample while there is none)."""
        if not self._t:
            raise ValueError("the touch has no located sample")
        if self._pressed_w > 0:
            w, wx, wy = self._pressed_w, self._pressed_wx, self._pressed_wy
        else:
            w, wx, wy = self._sum_w, self._sum_wx, self._sum_wy
        return BestPoint(wx / w, wy / w, 1.0 / math.sqrt(w))

    def settled(self, share: float = SETTLED_SHARE) -> BestPoint:
        """Where a still touch is: the precision-weighted mean of its pressed samples after
        the first ``share`` of them (of every located sample while there is none pressed;
        the last one at least), ``sigma_m`` that mean's as in :meth:`best`. The estimator's
        position settles through a touch: on a light tap, on sensors quieter than their
        rounding step, the first samples are off by more than their σ, the last ones less."""
        if not self._t:
            raise ValueError("the touch has no located sample")
        pressed = np.asarray(self._pressed)
        keep = np.flatnonzero(pressed) if pressed.any() else np.arange(len(pressed))
        keep = keep[min(int(share * len(keep)), len(keep) - 1) :]
        w = 1.0 / np.asarray(self._sigma)[keep] ** 2
        x = float(w @ np.asarray(self._x)[keep] / w.sum())
        y = float(w @ np.asarray(self._y)[keep] / w.sum())
        return BestPoint(x, y, 1.0 / math.sqrt(float(w.sum())))

    def place_sigma(self) -> float:
        """How well :meth:`best` places the touch, metres (1-σ): the samples' typical σ (the
        root of their count over their summed weights), not the mean's σ of :meth:`best`.
        Neighbouring samples share the estimator's low-pass and, on a sensor quieter than
        its rounding step, the zero's error, so they do not average each other's errors out:
        a light tap was placed 18-51 mm off while each of its samples claimed about 7 mm
        and their mean 1-2 mm (scripts/desk_sweep.py)."""
        if not self._t:
            raise ValueError("the touch has no located sample")
        if self._pressed_w > 0:
            return math.sqrt(self._pressed_n / self._pressed_w)
        return math.sqrt(len(self._t) / self._sum_w)

    def current(self) -> tuple[float, float]:
        """The latest point of the smoothed track."""
        if not self._t:
            raise ValueError("the touch has no located sample")
        return self._sx[-1], self._sy[-1]

    def times(self) -> np.ndarray:
        """Sample times of the located samples."""
        return np.asarray(self._t)

    def points(self) -> np.ndarray:
        """(n, 2) located samples as the estimator gave them (outliers left out)."""
        return np.column_stack([self._x, self._y]) if self._t else np.zeros((0, 2))

    def track(self) -> np.ndarray:
        """(n, 2) smoothed track (for strokes and slides)."""
        return np.column_stack([self._sx, self._sy]) if self._t else np.zeros((0, 2))

    def dragged(self) -> float:
        """How hard the finger dragged along the surface for how hard it pressed into it: the
        75th percentile of the pressed samples' shear (``ContactEvent.shear``), 0 without
        any. Where the located points cannot follow a quick finger, this still tells a
        slide from a tap: friction drags the surface (simulated flicks 0.6-0.9 on four kinds
        of desk), a tap presses into it (0.06-0.16)."""
        return float(np.percentile(self._shear, 75)) if self._shear else 0.0

    def drag(self) -> tuple[float, float]:
        """The way the finger dragged a horizontal board, desk (x, y): its pressed samples'
        drag summed (friction pulls the board the way a finger slides); (0, 0) elsewhere."""
        return self._drag_x, self._drag_y

    def drag_straightness(self) -> float:
        """How much the drag kept one way: its sum's length over its lengths' sum, 1 for a
        straight slide, near 0 for a circle drawn; 0 without any drag."""
        if self._drag_length <= 0.0:
            return 0.0
        return math.hypot(self._drag_x, self._drag_y) / self._drag_length

    def moved(self, x: float, y: float, rise_share: float = 0.0) -> float:
        """How far the touch went from (x, y) beyond its own uncertainty, metres.

        The largest distance of a sample from (x, y) less twice that sample's σ: a noisy
        sample at touch-down does not count as movement, a real slide does. Only pressed
        samples count when there are any: the lift-off tail below the contact force is where
        the differentiated candidate's still-finger assumption breaks (13 cm jumps seen).
        With ``rise_share``, the touch's rise is left out too: the samples before the force
        first reached that share of its peak so far, whose points err as 1/force and, on
        sensors quieter than their resolution step, by more than their σ says. Every later
        sample counts, however light (a finger easing off as it slides away).
        """
        if not self._t:
            return 0.0
        pressed = np.asarray(self._pressed)
        if rise_share > 0:
            force = np.asarray(self._force)
            risen = int(np.argmax(force >= rise_share * self.peak_force_n))
            after = pressed.copy()
            after[:risen] = False
            if after.any():
                pressed = after
        keep = pressed if pressed.any() else np.ones(len(pressed), bool)
        d = np.hypot(np.asarray(self._x)[keep] - x, np.asarray(self._y)[keep] - y)
        return max(0.0, float((d - 2 * np.asarray(self._sigma)[keep]).max()))

    def position_at(self, t: float, t0: float, t1: float) -> tuple[float, float] | None:
        """Position at time ``t`` from a precision-weighted straight-line fit over the located
        samples with t0 <= time <= t1: it averages the noise of a swipe's ends without the
        bias a plain mean has while the finger moves. None when there is no sample there."""
        times = np.asarray(self._t)
        sel = (times >= t0) & (times <= t1)
        if not sel.any():
            return None
        w = 1.0 / np.asarray(self._sigma)[sel] ** 2
        dt = times[sel] - t
        xy = np.column_stack([np.asarray(self._x)[sel], np.asarray(self._y)[sel]])
        sw, swt, swtt = w.sum(), (w * dt).sum(), (w * dt * dt).sum()
        det = sw * swtt - swt * swt
        if det <= 1e-12 * sw * max(swtt, 1e-30):  # one sample, or all at one time: the mean
            mean = (w[:, None] * xy).sum(axis=0) / sw
            return float(mean[0]), float(mean[1])
        swx = (w[:, None] * xy).sum(axis=0)
        swtx = (w[:, None] * dt[:, None] * xy).sum(axis=0)
        at_t = (swtt * swx - swt * swtx) / det  # intercept of the weighted least squares line
        return float(at_t[0]), float(at_t[1])
