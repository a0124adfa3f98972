"""A second finger: detected from the change of wrench when it lands while the first holds.

One resultant force gives one point: two fingers pressing straight down are, to the sensors,
one finger at their centre of pressure (a vertical force's wrench has no free moment, so the
residual of the single-point model cannot tell them apart). What does tell: when the second
finger lands while the first holds, the *change* of the wrench over the landing is itself the
wrench of a single point force, the second finger's (the differentiated wrench, paper eqs.
8/12: ΔM = P₂ × ΔF). Located like any wrench (eqs. 1–2 on the surface's plane), it lies
centimetres away from where the first finger is; a finger pressing harder gives a change
located where it already is, and a finger starting to swipe one that is mostly sideways (its
drag), not pressing down.

Where the second finger is: the change located as it stands mixes in the first finger's own
change of force (two vertical forces fix only the line through both fingers: any point on it
explains one change with some split of the force). Taken about the first finger's point P₁,
though, the first finger's force has no moment at all, so n × (ΔM − P₁ × ΔF) = (P₂ − P₁)·f₂
follows the second finger's force alone, while the normal force n·ΔF = Δf₁ + f₂ holds both.
Over a window from before the landing to after it, the first finger's part is fitted as a
quadratic in time (its drift; a finger still pressing in bends it: a straight line left the
second finger 28 mm off at the median there, 12 mm with the bend) and the second's as
1/|P₂ − P₁| times the first quantity (:func:`fit_second_point`): a linear least-squares fit
of four numbers.

The stage runs when ``second_finger`` is on (or a layout binds a gesture that reads a second
finger): it sets ``FLAG_MULTI`` on the contact samples from the landing to the contact's end
and reports the second finger's point (``x2``, ``y2``, ``z2``, ``located2``) once its fit
window is over. The per-sample work — the smoothing, the landing test on the change of
wrench, the flags, the fit window — is ``_second_finger`` in
:mod:`hapticdesk.estimator.kernel_multitouch`; what it leaves to Python is here: the fit of
the second finger's point at a landing window's end (:func:`fit_second_point`) and the
desk's own stray, learned at each contact's end (:class:`SecondFingerStage`).
"""

from __future__ import annotations

from collections import deque

import numpy as np

from hapticdesk.estimator.contacts import MULTI_LAG_S

LOWPASS_HZ = 12.0  # the wrench is smoothed this much before differencing (noise vs lag)
LAG_S = MULTI_LAG_S  # the change of wrench is taken over this long (a finger lands in ≈0.1 s)
LANDING_S = 0.18  # the second finger's place is fitted over this long after its landing
MIN_STEP_N = 2.0  # the force must rise at least this much over LAG_S ...
MIN_STEP_SHARE = 0.1  # ... and at least this share of the force before it
# ... pressing down: its normal part at least this share of it (a swipe's drag is sideways)
MIN_NORMAL_SHARE = 0.8
# How far from the first finger the change must be located. A single press's own change
# strays from it as the press rocks the desk: by at most 2.8 cm on the paper desk and 3.0 cm
# on the unseen 6-sensor desk of scripts/tap_accuracy.py, but 6.7 cm on its tall, soft
# 4-sensor desk (300 single touches each), where a fixed 3 cm took 26 % of single touches for
# two fingers. So the desk's own stray is measured: each press without a second finger gives
# the farthest its changes landed (its stray); the minimum is STRAY_MARGIN times the upper
# quartile of the last STRAY_PRESSES presses' strays (the quartile leaves out the few pairs
# missed as single), within [MIN_APART_FLOOR_M, MIN_APART_CAP_M]; until STRAY_MIN_PRESSES
# presses are in, MIN_APART_M (enough on all three desks). Only presses under the minimum
# are measured, so a minimum learnt low would never rise if presses later strayed further
# (a heavier hand, a monitor put on the desk): when more than MAX_FLAGGED_SHARE of the last
# STRAY_PRESSES contacts with a change were flagged, the stage starts learning afresh
# from MIN_APART_M (a missed pair is better than a made-up one)
MIN_APART_M = 0.07
MIN_APART_FLOOR_M = 0.03  # a finger's own width and the fit's spread
MIN_APART_CAP_M = 0.15
STRAY_MARGIN = 1.7  # the quartile to the largest stray: 1.56, 1.43, 1.63 on the three desks
STRAY_PRESSES = 32
STRAY_MIN_PRESSES = 8
MAX_FLAGGED_SHARE = 0.5
MAX_FIRST_MOVE_M = 0.005  # the first finger held this still over the lag before (no swipe)


def fit_second_point(
    first: np.ndarray, normal: np.ndarray, wrench: np.ndarray
) -> np.ndarray | None:
    """The second finger's point from the smoothed wrench (m, 6) over a window that starts
    before its landing (evenly sampled), the first finger at ``first`` (3,) on the plane with
    ``normal`` (see the module docstring). None when the window does not pin it down."""
    d = wrench - wrench[0]
    d_force, d_moment = d[:, :3], d[:, 3:]
    lever = np.cross(normal, d_moment - np.cross(first, d_force))  # (P₂ − P₁)·f₂
    size = np.linalg.norm(lever, axis=1)
    j = int(np.argmax(size))
    if size[j] <= 0:
        return None
    toward = lever[j] / size[j]
    along = lever @ toward  # |P₂ − P₁|·f₂
    normal_force = d_force @ normal  # Δf₁ + f₂
    tau = np.arange(len(d), dtype=float)  # samples, not the times: they may be bad
    design = np.stack([along, np.ones_like(tau), tau, tau * tau], axis=1)
    (inv_distance, *_), *_ = np.linalg.lstsq(design, normal_force, rcond=None)
    if not inv_distance > 0:
        return None
    return first + toward / inv_distance


class SecondFingerStage:
    """The desk's own stray, learned at each contact's end (see MIN_APART_M): the minimum
    distance from the first finger a landing must be."""

    def __init__(self) -> None:
        # the last presses' strays, and whether the last contacts with a change were flagged
        self.strays: deque[float] = deque(maxlen=STRAY_PRESSES)
        self.flagged_contacts: deque[bool] = deque(maxlen=STRAY_PRESSES)
        self.min_apart_m = MIN_APART_M

    def contact_ended(self, flagged: bool, stray: float) -> None:
        """A contact ended: ``flagged`` with a second finger, or a press whose own changes
        strayed ``stray`` (m) from it at most."""
        if flagged or stray > 0:
            recent = self.flagged_contacts
            recent.append(flagged)
            if len(recent) >= STRAY_MIN_PRESSES and sum(recent) > MAX_FLAGGED_SHARE * len(recent):
                self.strays.clear()  # see MAX_FLAGGED_SHARE: learn afresh
                recent.clear()
                self.min_apart_m = MIN_APART_M
        if not flagged and stray > 0:
            self.strays.append(stray)
            if len(self.strays) >= STRAY_MIN_PRESSES:
                quartile = float(np.percentile(np.fromiter(self.strays, float), 75))
                self.min_apart_m = min(
                    max(STRAY_MARGIN * quartile, MIN_APART_FLOOR_M), MIN_APART_CAP_M
                )
