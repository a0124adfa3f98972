"""The detector, compiled: in contact or not, from the tared fast force.

Stage 4 of the kernel (:mod:`hapticdesk.estimator.kernel`), the per-sample side of
:mod:`hapticdesk.estimator.detector`: :func:`detect` with hysteresis about the contact
threshold (the paper's F_th), an early release where a steep fall is predicted through it,
re-arming only below the release level; on an upright surface the ring guard of
:func:`_pressing` takes the largest recent pull along its normal off the push.
"""

from __future__ import annotations

import math

import numpy as np

from hapticdesk.estimator.kernel_compile import inlined
from hapticdesk.estimator.kernel_geometry import surface_at
from hapticdesk.estimator.kernel_slots import (
    I_IO_UP,
    I_N_SURF,
    I_N_UP,
    I_SO_GUARD,
    J_BLOCKED,
    J_IN_CONTACT,
    P_CONTACT,
    P_DET_DELAY,
    P_HYSTERESIS,
    P_MIN_COS,
    P_RELEASE_SLOPE,
    P_RING_DECAY,
    S_RELEASE,
    S_SLOPE,
    SURF_F,
    SURF_NORMAL,
)


@inlined
def detect(
    pf: np.ndarray,
    pi: np.ndarray,
    sf: np.ndarray,
    si: np.ndarray,
    fx: float,
    fy: float,
    fz: float,
    mag: float,
) -> tuple[bool, float]:
    """In contact from the tared fast force (its magnitude ``mag``) with hysteresis; a steep
    fall predicted through the contact force releases early, a contact ended above the
    release level re-arms only below it, and on an upright surface the largest pull along
    its normal lately (the ring guard) is taken off the push (detector.py). Returns
    (in contact, the force's slope along itself over I_N_RATE)."""
    inv = 1.0 / mag if mag > 0 else 0.0
    slope = (fx * sf[S_SLOPE] + fy * sf[S_SLOPE + 1] + fz * sf[S_SLOPE + 2]) * inv
    falling = (fx * sf[S_RELEASE] + fy * sf[S_RELEASE + 1] + fz * sf[S_RELEASE + 2]) * inv
    pressing, holding = _pressing(pf, pi, sf, fx, fy, fz, mag)
    threshold, hysteresis, steep = pf[P_CONTACT], pf[P_HYSTERESIS], pf[P_RELEASE_SLOPE]
    through = 0 < steep < -falling and mag + falling * pf[P_DET_DELAY] < threshold
    above = pressing and mag >= threshold and not through
    below = not holding or mag < threshold - hysteresis or through
    low = threshold - hysteresis
    if mag < low:
        si[J_BLOCKED] = 0
    elif si[J_BLOCKED] and mag < threshold + hysteresis:
        above = False
    was = si[J_IN_CONTACT] == 1
    now = above or (was and not below)
    si[J_IN_CONTACT] = 1 if now else 0
    if was and not now and mag >= low:
        si[J_BLOCKED] = 1
    return now, slope


@inlined
def _pressing(
    pf: np.ndarray,
    pi: np.ndarray,
    sf: np.ndarray,
    fx: float,
    fy: float,
    fz: float,
    mag: float,
) -> tuple[bool, bool]:
    """Whether the tared fast force (its magnitude ``mag``) pushes into a surface, within
    P_MIN_COS of its normal: (pressing, with the ring guard's pull taken off on an upright
    surface; holding, without it). Neither without surfaces."""
    n_surf = pi[I_N_SURF]
    least = pf[P_MIN_COS] * mag
    pressing = holding = False
    if n_surf:
        top = -math.inf
        for s in range(n_surf):
            at, n = surface_at(pi, s), SURF_NORMAL
            r = pf[at : at + SURF_F]
            top = max(top, r[n] * fx + r[n + 1] * fy + r[n + 2] * fz)
        holding = top >= least
        pressing = holding
        n_up = pi[I_N_UP]
        if n_up:
            guard, decay = pi[I_SO_GUARD], pf[P_RING_DECAY]
            top = -math.inf
            for s in range(n_surf):
                at, n = surface_at(pi, s), SURF_NORMAL
                r = pf[at : at + SURF_F]
                along = r[n] * fx + r[n + 1] * fy + r[n + 2] * fz
                for j in range(n_up):
                    if pi[pi[I_IO_UP] + j] == s:
                        held = sf[guard + j] * decay
                        pull = -along
                        held = pull if pull > held else held
                        sf[guard + j] = held
                        along -= held
                top = max(top, along)
            pressing = top >= least
    return pressing, holding
