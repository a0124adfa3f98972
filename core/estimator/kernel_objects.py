"""The object rule and an object's lift, compiled: is a still load an object put down?

The kernel's side of :mod:`hapticdesk.estimator.still_objects` (which states the rule, its
constants — here ``P_OBJECT_*``, ``P_HEAVY_*``, ``P_LIGHT_LOAD``, ``P_LIFT_TOLERANCE`` — and
how they were chosen). Judged at a still window's end
(:func:`hapticdesk.estimator.kernel_zero.still_window`) against the idle desk's yardsticks
(:mod:`.kernel_yardsticks`), so the window never leaves the compiled loop; only a verdict
that changes the zero does (``EV_ABSORBED``, ``EV_LIFTED``), for Python to word.
"""

from __future__ import annotations

import math

import numpy as np

from hapticdesk.estimator.kernel_compile import inlined
from hapticdesk.estimator.kernel_slots import (
    I_C,
    I_N_NOISY_EXTRA,
    I_N_OBJECT,
    I_PO_MAP,
    I_SO_OBJ_WINDOWS,
    I_SO_SCRATCH,
    I_SO_STEP,
    J_OBJ_GRACED,
    J_OBJ_RESTING,
    J_OBJ_WINDOWS_N,
    J_OBJ_WINDOWS_POS,
    J_OFF_STEPS,
    P_DRIFT_MAX,
    P_HEAVY_SPREAD_SHARE,
    P_HEAVY_WANDER_SHARE,
    P_LIFT_TOLERANCE,
    P_LIGHT_LOAD,
    P_NOISY_STILL_SHARE,
    P_NOISY_WANDER_SHARE,
    P_OBJECT_NOISE_FLOOR,
    P_OBJECT_RESTING_KEEP,
    P_OBJECT_SPIKE,
    P_OBJECT_STILL_FACTOR,
    P_OBJECT_WANDER_FACTOR,
    P_STEP_SPREAD_SHARE,
    P_STEP_WANDER_SHARE,
    P_STILL_N,
    S_OBJ_WEIGHT,
    S_OBJ_ZERO,
    S_QUIET_SPREAD,
    S_QUIET_WANDER,
    S_WIN_MEAN,
)
from hapticdesk.estimator.kernel_yardsticks import (
    nth_smallest,
    ring_push,
    ring_wander,
)


@inlined
def object_still(
    run: int,
    spread: float,
    f0: float,
    f1: float,
    f2: float,
    load: float,
    pf: np.ndarray,
    pi: np.ndarray,
    sf: np.ndarray,
    si: np.ndarray,
) -> tuple[int, bool]:
    """One more window of a load (``run``: the object run so far; the window's ``spread``,
    its mean force less the zero and that force's size ``load``): is it held long enough as
    still as the idle desk to be an object? Returns the run's new length (0: no object, for
    now) and the verdict. Judged on the last I_N_OBJECT windows (one more under
    P_LIGHT_LOAD; I_N_NOISY_EXTRA more on a noisy desk, :func:`_waits`): their means
    within the allowed wander of each other, their upper median spread within the limit, none
    over P_OBJECT_SPIKE times it (but one of a light load that rests on through it,
    J_OBJ_GRACED). Also notes whether the load rests (J_OBJ_RESTING: its last windows so
    far, as many as elsewhere, as still as an object's)."""
    n_object = pi[I_N_OBJECT]
    quiet_spread, quiet_wander = _yardsticks(pf, pi, sf, si)
    limit = max(pf[P_OBJECT_STILL_FACTOR] * quiet_spread, pf[P_HEAVY_SPREAD_SHARE] * load)
    if (
        n_object == 0
        or load < pf[P_DRIFT_MAX]  # (drift, also when drift is not followed)
        or quiet_spread < pf[P_OBJECT_NOISE_FLOOR]
    ):
        return 0, False
    # a window spread past an object's ends the run, but for one a run of a light load that
    # rests and whose mean keeps it resting (a desk still ringing from a cup's landing:
    # still_objects.OBJECT_SPIKE); it counts toward no verdict
    spiked = spread >= pf[P_OBJECT_SPIKE] * limit
    light = load < pf[P_LIGHT_LOAD]
    if spiked and not (light and si[J_OBJ_RESTING] and run > 0 and not si[J_OBJ_GRACED]):
        return 0, False
    if run == 0:
        si[J_OBJ_WINDOWS_N] = si[J_OBJ_GRACED] = 0
    run += 1
    allowed = max(pf[P_OBJECT_WANDER_FACTOR] * quiet_wander, pf[P_HEAVY_WANDER_SHARE] * load)
    judged, wait = _waits(light, allowed, load, pf, pi, sf)
    cap, at = n_object + 1 + pi[I_N_NOISY_EXTRA], pi[I_SO_OBJ_WINDOWS]
    k = ring_push(si, J_OBJ_WINDOWS_N, J_OBJ_WINDOWS_POS, cap, wait)
    sf[at + 4 * k] = spread
    sf[at + 4 * k + 1], sf[at + 4 * k + 2], sf[at + 4 * k + 3] = f0, f1, f2
    n, pos = si[J_OBJ_WINDOWS_N], si[J_OBJ_WINDOWS_POS]
    strayed = ring_wander(sf, at, cap, pos, n)
    recent = strayed if n <= judged else ring_wander(sf, at, cap, pos, judged)
    # the resting flag, once up in this run, drops only past P_OBJECT_RESTING_KEEP times the
    # allowed wander (still_objects.OBJECT_RESTING_KEEP says why)
    keep = pf[P_OBJECT_RESTING_KEEP] if si[J_OBJ_RESTING] and run > 1 else 1.0
    si[J_OBJ_RESTING] = 1 if recent < keep * allowed else 0
    if spiked:
        si[J_OBJ_GRACED] = 1
        return (run, False) if si[J_OBJ_RESTING] else (0, False)
    median = nth_smallest(sf, at, 4, cap, pos, n, n // 2, pi[I_SO_SCRATCH])
    # (a load that strays is no object, for now)
    return run, strayed < allowed and run >= wait and median < limit


@inlined
def _waits(
    light: bool, allowed: float, load: float, pf: np.ndarray, pi: np.ndarray, sf: np.ndarray
) -> tuple[int, int]:
    """The windows a load's resting is judged on (I_N_OBJECT, one more when ``light``) and
    the windows it waits to be an object: I_N_NOISY_EXTRA more on a desk whose idle windows
    spread P_NOISY_STILL_SHARE of P_STILL_N or more and where the wander ``allowed`` is
    P_NOISY_WANDER_SHARE of the ``load`` or more (still_objects.NOISY_EXTRA_WINDOWS says
    why)."""
    judged = pi[I_N_OBJECT] + 1 if light else pi[I_N_OBJECT]
    noisy = sf[S_QUIET_SPREAD] >= pf[P_NOISY_STILL_SHARE] * pf[P_STILL_N]
    if noisy and allowed >= pf[P_NOISY_WANDER_SHARE] * load:
        return judged, judged + pi[I_N_NOISY_EXTRA]
    return judged, judged


@inlined
def _yardsticks(
    pf: np.ndarray, pi: np.ndarray, sf: np.ndarray, si: np.ndarray
) -> tuple[float, float]:
    """The idle desk's quiet spread and wander (S_QUIET_*); where its readings sat still (a
    spread under P_OBJECT_NOISE_FLOOR: a sensor quieter than its resolution step), shares of
    the force one step of its coarsest channel makes (still_objects.STEP_SPREAD_SHARE), 0
    while no step is known or where the readings are not quantised (J_OFF_STEPS: the
    smallest change of a continuous reading is no resolution step)."""
    spread, wander = sf[S_QUIET_SPREAD], sf[S_QUIET_WANDER]
    if spread >= pf[P_OBJECT_NOISE_FLOOR] or si[J_OFF_STEPS]:
        return spread, wander
    c_n = pi[I_C]
    m = pf[pi[I_PO_MAP] : pi[I_PO_MAP] + 6 * c_n]
    step = sf[pi[I_SO_STEP] : pi[I_SO_STEP] + c_n]
    force = 0.0
    for c in range(c_n):
        k = 6 * c
        force = max(force, math.sqrt(m[k] ** 2 + m[k + 1] ** 2 + m[k + 2] ** 2) * step[c])
    return pf[P_STEP_SPREAD_SHARE] * force, pf[P_STEP_WANDER_SHARE] * force


@inlined
def lifted(pf: np.ndarray, sf: np.ndarray) -> bool:
    """The window's mean force (S_WIN_MEAN) is back at the zero from before the last
    absorbed object (S_OBJ_ZERO; within P_LIFT_TOLERANCE of its weight, or P_STILL_N): the
    object was lifted."""
    d0 = sf[S_WIN_MEAN] - sf[S_OBJ_ZERO]
    d1 = sf[S_WIN_MEAN + 1] - sf[S_OBJ_ZERO + 1]
    d2 = sf[S_WIN_MEAN + 2] - sf[S_OBJ_ZERO + 2]
    off = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    return off < max(pf[P_STILL_N], pf[P_LIFT_TOLERANCE] * sf[S_OBJ_WEIGHT])
