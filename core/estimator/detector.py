"""Stage 4, the fast touch detector: contact from the fast (30 Hz) force, with hysteresis.

Touch-down at ``contact_force_n``, release below it less ``release_hysteresis_n``, and only
for a force that presses into a surface (a lifted object pulls); it does not wait for the
position filters. A force falling fast is released earlier, where it is *predicted* to cross
``contact_force_n``: the fast low-pass runs ``det_delay_s`` (≈ 7.5 ms at 30 Hz) behind the
true force, so the true force is about ``|F| + slope · det_delay_s``; without that a slow
release (20 N/s) took 25 ms to fall through the hysteresis. Only a steep fall
is extrapolated (``release_slope_n_s``, 10 N/s by default: the slope over 20 ms of a held press
— tremor 1.5 %, wander 3 %, noise — stays under 3 N/s; the slowest releases of the human model
fall at about 20 N/s), so a steady hold is never released. A contact that ends while the fast
force is still above the release level (a predicted release, or a force turning away from the
surface) re-arms only once the force has fallen below that level: until then a new touch-down
needs ``contact_force_n`` plus the hysteresis (see ``TouchDetector.blocked``; a light tap whose
force flattened at 2.0 N right after its predicted release touched down again for 10 ms and
its button fired twice). The phase of a contact (touch, hold,
release) follows the fast force's slope. :meth:`TouchDetector.process` is the block path;
:meth:`TouchDetector.process_one` the same for one sample on plain floats, with the decision
(:func:`contact_decision`) and the phase (:func:`phase_of`) written once for both.

Upright surfaces (a front panel) are pressed along the axes the desk sways on (5.9 Hz on the
paper's desk, rung for seconds by a push), and the ring is a force along the panel's normal
like a finger's: after a 30 N push on the desk's side it made ten touch-downs of 2–9 N. A
finger cannot pull, and each swing of the ring towards the panel follows one away from it at
least as large, so the force along an upright surface's normal counts less the largest pull
along it lately (:func:`ring_guard`, remembered for ``RING_MEMORY_S``) when a touch-down is
judged (a ring under a finger already in contact does not end its press); a horizontal
board is not guarded (its vertical modes are far above the sample rate).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from hapticdesk.estimator.contacts import PHASE_HOLD, PHASE_RELEASE, PHASE_TOUCH
from hapticdesk.estimator.settings import EstimatorSettings

#: the time constant (s) over which a pull along an upright surface's normal is forgotten.
#: A ring decays by e^(−ζ·π) a half period (≈ 9 % at the paper desk's ζ ≈ 0.03), and a swing
#: towards the panel is rejected while the guard holds more than 1 − min_normal_cos (80 %) of
#: it: a guard decaying by e^(−0.085 s / 1 s) ≈ 8 % over a 5.9 Hz half period keeps a margin
#: for lighter damping and slower sways; a real press right after a push waits for the ring
#: to fall below it (≈ 2.7 s after a 30 N push on the paper desk)
RING_MEMORY_S = 1.0
UPRIGHT_MAX_NZ = 0.5  # a surface whose normal's |z| is below this is upright (sways)


def ring_guard(pull: np.ndarray, start: np.ndarray, decay: float) -> np.ndarray:
    """The decaying peak hold g[k] = max(pull[k], decay · g[k−1]) of ``pull`` (m, k) ≥ 0 per
    row, from ``start`` (m,) before the first sample; vectorised as a running maximum of
    log pull[j] + j·a less k·a, with decay = e^(−a)."""
    m, k = pull.shape
    a = -math.log(decay)
    steps = np.arange(-1, k) * a
    with np.errstate(divide="ignore"):
        logs = np.log(np.concatenate([start[:, None], pull], axis=1))
    logs += steps
    np.maximum.accumulate(logs, axis=1, out=logs)
    return np.exp(logs[:, 1:] - steps[1:])


def contact_decision(
    pressing: Any, mag: Any, slope: Any, settings: EstimatorSettings, holding: Any = None
) -> tuple[Any, Any]:
    """(above, below): where contact starts and where it ends, from whether the fast force
    presses into a surface, its magnitude and its slope along itself (N/s); for arrays
    (bool, float) or plain values; ``&``, ``|`` and ``~`` keep to the arrays' elementwise
    meaning. A steep fall predicted through ``contact_force_n`` ends the contact (and does not
    start one: no touch right after such a release). ``holding`` (default ``pressing``):
    whether it presses enough to stay in contact — without the ring guard, which judges a
    touch-down only (a ring under a finger must not end its press)."""
    s = settings.user
    threshold, steep = s.contact_force_n, s.release_slope_n_s
    if holding is None:
        holding = pressing
    if isinstance(pressing, bool):
        through = 0 < steep < -slope and mag + slope * settings.det_delay_s < threshold
        above = pressing and mag >= threshold and not through
        below = not holding or mag < threshold - s.release_hysteresis_n or through
        return above, below
    through = (steep > 0) & (slope < -steep) & (mag + slope * settings.det_delay_s < threshold)
    return (
        pressing & (mag >= threshold) & ~through,
        ~holding | (mag < threshold - s.release_hysteresis_n) | through,
    )


def phase_of(slope: float, settings: EstimatorSettings) -> int:
    """The phase of a contact from the fast force's slope along it (N/s)."""
    rate = settings.user.phase_rate_n_s
    return PHASE_TOUCH if slope > rate else PHASE_RELEASE if slope < -rate else PHASE_HOLD


def phases_of(slope: np.ndarray, settings: EstimatorSettings) -> np.ndarray:
    """:func:`phase_of` for an array of slopes."""
    rate = settings.user.phase_rate_n_s
    phase = np.full(len(slope), PHASE_HOLD, np.int8)
    phase[slope > rate] = PHASE_TOUCH
    phase[slope < -rate] = PHASE_RELEASE
    return phase


def hysteresis(on: np.ndarray, off: np.ndarray, state: bool) -> np.ndarray:
    """Vectorised two-threshold switch: set where ``on``, cleared where ``off``, else held."""
    k = len(on)
    if k == 1:
        return np.array([bool(on[0]) or (state and not off[0])])
    decided = np.flatnonzero(on | off)
    if len(decided) == 0:
        return np.full(k, state)
    value = on[decided]  # what each decided sample sets
    before = np.empty(len(value), bool)
    before[0] = state
    before[1:] = value[:-1]
    flips = np.flatnonzero(value != before)  # the decided samples that change the state
    # runs of a constant state between the flips, written out with one np.repeat
    bounds = np.concatenate(([0], decided[flips], [k]))
    values = np.concatenate(([state], value[flips]))
    return np.repeat(values, np.diff(bounds))


class TouchDetector:
    """In contact or not, per sample, from the tared fast force; its state: in contact."""

    def __init__(self, settings: EstimatorSettings) -> None:
        self.settings = settings
        self.in_contact = False
        # a contact ended above the release level and the force has not fallen below it
        # since: a touch-down needs the hysteresis on top of contact_force_n (module doc)
        self.blocked = False
        normals = settings.normals
        self.upright = np.flatnonzero(np.abs(normals[:, 2]) < UPRIGHT_MAX_NZ)
        self.guarded = bool(len(self.upright))  # (a plain bool for the single-sample path)
        # the ring guard (N) per upright surface; plain floats for the single-sample path
        self.ring: list[float] = [0.0] * len(self.upright)
        self.upright_list: list[int] = self.upright.tolist()
        self.ring_decay = math.exp(-1.0 / (RING_MEMORY_S * settings.sample_rate_hz))

    def process(
        self,
        f_det: np.ndarray,
        f_det_mag: np.ndarray,
        slope: np.ndarray,
        tared: np.ndarray | None,
    ) -> np.ndarray:
        """In contact (k,) for the fast force (3, k), its magnitude (k,) and its slope along
        itself over ``n_release`` samples (k,, :func:`slope_along`); ``tared`` (k,) where the
        zero is known (None: everywhere)."""
        s = self.settings
        normals = s.normals
        holding = None
        if self.guarded:
            along = normals @ f_det
            least = s.user.min_normal_cos * f_det_mag
            holding = along.max(axis=0) >= least
            pull = np.maximum(-along[self.upright], 0.0)
            if tared is not None:
                pull *= tared  # (no zero: no force known)
            guard = ring_guard(pull, np.array(self.ring), self.ring_decay)
            self.ring = guard[:, -1].tolist()
            along[self.upright] -= guard
            pressing = along.max(axis=0) >= least
        elif len(normals) == 1:
            pressing = normals[0] @ f_det >= s.user.min_normal_cos * f_det_mag
        elif len(normals):
            pressing = (normals @ f_det).max(axis=0) >= s.user.min_normal_cos * f_det_mag
        else:
            pressing = np.zeros(len(f_det_mag), bool)
        above, below = contact_decision(pressing, f_det_mag, slope, s, holding)
        if tared is not None:
            above &= tared
            below |= ~tared
        in_contact = self._rearmed(above, below, f_det_mag)
        self.in_contact = bool(in_contact[-1])
        return in_contact

    def _rearmed(self, above: np.ndarray, below: np.ndarray, mag: np.ndarray) -> np.ndarray:
        """In contact (k,) from the touch-downs ``above`` and releases ``below``, where a
        touch-down after a contact that ended above the release level needs the hysteresis
        on top until the force has fallen below that level (module doc). Per sample, as
        :meth:`process_one`: re-armed when |F| is below the release level, then the touch-down
        judged, then blocked after a contact that ended at or above it. Early ends are rare
        (a few a minute), so the vectorised switch is run again once per new one found."""
        s = self.settings.user
        low = s.contact_force_n - s.release_hysteresis_n
        rearm = mag < low
        weak = mag < s.contact_force_n + s.release_hysteresis_n
        state, blocked_before = self.in_contact, self.blocked
        early = np.zeros(len(mag), bool)
        for _ in range(len(mag) + 1):  # (ends after a few rounds: one per early end)
            starts = np.concatenate(([False], early[:-1]))  # blocked from the next sample
            blocked = hysteresis(starts & ~rearm, rearm, blocked_before)
            in_contact = hysteresis(above & ~(blocked & weak), below, state)
            before = np.concatenate(([state], in_contact[:-1]))
            now_early = before & ~in_contact & ~rearm
            if np.array_equal(now_early, early):
                break
            early = now_early
        self.blocked = bool(early[-1] or blocked[-1])
        return in_contact

    def process_one(
        self, fast: list[float], det_slope: list[float], release: list[float]
    ) -> tuple[bool, float, float]:
        """:meth:`process` for one tared sample and its two slopes (3,): in contact, |F| of
        the fast force and its slope along itself over ``n_rate`` (for the phase)."""
        s = self.settings
        fx, fy, fz = fast[:3]
        mag = math.sqrt(fx * fx + fy * fy + fz * fz)
        inv = 1.0 / mag if mag > 0 else 0.0
        sx, sy, sz = det_slope
        slope = (fx * sx + fy * sy + fz * sz) * inv
        rx, ry, rz = release
        falling = (fx * rx + fy * ry + fz * rz) * inv
        normals = s.normals_list
        holding = None
        if self.guarded:
            alongs = [n[0] * fx + n[1] * fy + n[2] * fz for n in normals]
            least = s.user.min_normal_cos * mag
            holding = max(alongs) >= least
            ring, decay = self.ring, self.ring_decay
            for j, i in enumerate(self.upright_list):
                held = ring[j] * decay
                pull = -alongs[i]
                ring[j] = held = pull if pull > held else held  # (held ≥ 0)
                alongs[i] -= held
            pressing = max(alongs) >= least
        elif normals:
            along = max(n[0] * fx + n[1] * fy + n[2] * fz for n in normals)
            pressing = along >= s.user.min_normal_cos * mag
        else:
            pressing = False
        above, below = contact_decision(pressing, mag, falling, s, holding)
        # the re-arm rule of _rearmed, on one sample
        user = s.user
        low = user.contact_force_n - user.release_hysteresis_n
        if mag < low:
            self.blocked = False
        elif self.blocked and mag < user.contact_force_n + user.release_hysteresis_n:
            above = False
        was = self.in_contact
        self.in_contact = above or (was and not below)
        if was and not self.in_contact and mag >= low:
            self.blocked = True
        return self.in_contact, mag, slope


def slope_along(f_det: np.ndarray, det_slope: np.ndarray, f_det_mag: np.ndarray) -> np.ndarray:
    """The fast force's slope along itself (k,), N/s: d|F|/dt (0 where |F| is 0)."""
    along = np.einsum("ik,ik->k", f_det, det_slope)
    return np.divide(along, f_det_mag, out=np.zeros_like(along), where=f_det_mag > 0)
