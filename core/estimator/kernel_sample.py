"""One sample through every stage, compiled: the order the stages run in, in two halves.

:func:`_sample` is what both entries of :mod:`hapticdesk.estimator.kernel` run for a sample,
from where si[J_RESUME] says after an event: :func:`_front`, its first half (its flags and
wrench, stages 1 and 1b; the filter bank, stage 2; the zero's window, stage 3), then
:func:`_back`, its second (the filtered wrenches less the zero: the detector, stage 4; the
candidates and the method's point, stages 5 and 6, with the shear and the drag; the second
finger, stage 7), into the output columns. The paper's equations are cited in the stages'
modules (``kernel_channels``, ``kernel_filters``, ``kernel_methods``, ``kernel_multitouch``).
"""

from __future__ import annotations

import math

import numpy as np

from hapticdesk.estimator.contacts import (
    BAD_SAMPLE,
    FLAG_GAP,
    FLAG_NO_ACCEL,
    FLAG_NOT_TARED,
    PHASE_HOLD,
    PHASE_RELEASE,
    PHASE_TOUCH,
)
from hapticdesk.estimator.kernel_channels import _samples, held_over, steps_changed
from hapticdesk.estimator.kernel_compile import inlined
from hapticdesk.estimator.kernel_detector import detect
from hapticdesk.estimator.kernel_filters import _filters, _restart_filters
from hapticdesk.estimator.kernel_geometry import shear_of, surface_at
from hapticdesk.estimator.kernel_inertia import (
    ACCEL_ALL,
    ACCEL_ASK,
    ACCEL_USABLE,
    _accel_use,
    _inertial,
)
from hapticdesk.estimator.kernel_methods import _locate
from hapticdesk.estimator.kernel_multitouch import _second_finger
from hapticdesk.estimator.kernel_slots import (
    EV_COVS,
    EV_GAP,
    EV_PARTIAL_ACCEL,
    I_DET_FULL,
    I_IO_SURF,
    I_PO_GAIN,
    I_SO_PARTIAL_GAIN,
    I_SO_TRACE,
    I_TRACE,
    I_ZEROED,
    J_FLAGS,
    J_MT_ON,
    J_RESTING,
    J_RESTING_OFF,
    J_RESUME,
    J_STARTED,
    J_TARED,
    N_OUT_F,
    OUT_B_FLAGS,
    OUT_B_IN_CONTACT,
    OUT_B_LOCATED,
    OUT_B_LOCATED2,
    OUT_B_PHASE,
    OUT_B_RESTING,
    OUT_B_SOURCE,
    OUT_B_TRACED,
    OUT_DRAG_X,
    OUT_DRAG_Y,
    OUT_FORCE,
    OUT_SHEAR,
    OUT_SIGMA,
    OUT_T,
    OUT_X,
    OUT_X2,
    OUT_Y,
    OUT_Y2,
    OUT_Z,
    OUT_Z2,
    P_PHASE_RATE,
    P_SHEAR_CAP,
    P_SHEAR_CAP_INV,
    P_UNCERTAINTY_CAP,
    RESUME_AGAIN,
    RESUME_BACK,
    RESUME_NEXT,
    S_DET,
    S_DIFF,
    S_EV_T,
    S_LAST_GOOD,
    S_LP,
    S_MAX_T,
    S_RAW,
    S_TARED_Q,
    S_TARED_W,
    S_ZERO,
    SURF_DESK_XY,
    SURF_F,
    SURF_I,
    SURF_NORMAL,
    TRACE_ROWS,
    Wrench,
)
from hapticdesk.estimator.kernel_zero import window_add, zero_from_start


@inlined
def _front(
    t: float,
    x: np.ndarray,
    before: np.ndarray,
    mapped: Wrench,
    a: np.ndarray,
    given: bool,
    pf: np.ndarray,
    pi: np.ndarray,
    sf: np.ndarray,
    si: np.ndarray,
) -> int:
    """The first half of a sample (``before``: the channels of the sample before; ``mapped``:
    its channels' wrench, kernel_channels.wrench_of):
    its flags and wrench (stages 1, 1b; a jump held over: kernel_channels.held_over), the filters
    (stage 2) and the zero's window (stage 3). Leaves the sample in flight in S_RAW, S_LP,
    S_DET, S_DIFF, S_SLOPE, S_RELEASE and J_FLAGS; returns its events."""
    accel, no_accel = _accel_use(a, given, pf, pi, si)
    if accel == ACCEL_ASK:
        return EV_PARTIAL_ACCEL  # its gain from Python (before anything moves on)
    flags, events = _samples(t, x, before, pf, pi, sf, si)
    first_good = False
    zeroed = pi[I_ZEROED] == 1
    held, told = held_over(t, mapped, flags, pf, pi, sf, si)
    events |= told
    if (flags == 0 or flags == FLAG_GAP) and not held:  # a good sample: its wrench kept
        good = sf[S_LAST_GOOD : S_LAST_GOOD + 6]  # (paper eqs. 1–4)
        good[0], good[1], good[2], good[3], good[4], good[5] = mapped
        first_good = si[J_STARTED] == 0
        si[J_STARTED] = 1
        if zeroed and not si[J_TARED]:
            zero_from_start(t, pf, pi, sf, si)
            events |= EV_COVS
        elif steps_changed(pf, pi, sf, si):
            events |= EV_COVS
    started = si[J_STARTED] == 1
    for r in range(6):
        sf[S_RAW + r] = sf[S_LAST_GOOD + r] if started else 0.0
    if accel == ACCEL_ALL:
        _inertial(a, pf, pf, pi, sf, pi[I_PO_GAIN], False)
    elif accel == ACCEL_USABLE:
        _inertial(a, sf, pf, pi, sf, pi[I_SO_PARTIAL_GAIN], True)
    if no_accel:
        flags |= FLAG_NO_ACCEL
    if started:
        if first_good:
            _restart_filters(pf, pi, sf, si)
        elif flags & FLAG_GAP:
            _restart_filters(pf, pi, sf, si)
            sf[S_EV_T] = t
            events |= EV_GAP
        _filters(pf, pi, sf, si)
    else:
        for r in range(6):
            sf[S_LP + r] = sf[S_DET + r] = sf[S_DIFF + r] = 0.0
    si[J_FLAGS] = flags
    if zeroed:
        return events
    return events | window_add(t, flags, first_good, pf, pi, sf, si)


@inlined
def _back(
    t: float,
    pf: np.ndarray,
    pi: np.ndarray,
    sf: np.ndarray,
    si: np.ndarray,
    out_f: np.ndarray,
    out_b: np.ndarray,
    out_s: np.ndarray,
    col: int,
) -> int:
    """The second half of a sample: contact and position from the filtered wrenches less the
    zero (stages 4–6), the outputs, the second finger (stage 7). Returns its events."""
    flags = si[J_FLAGS]
    # every output row of the sample written once (a row written twice, zeroed then set,
    # cost ~6 ns a sample): the point's rows by _emit where a point is chosen, the defaults
    # below where none is
    out_f[OUT_T, col] = _out_time(t, sf)
    out_b[OUT_B_LOCATED, col] = 0
    inside = located = False
    phase = traced = 0
    mag = shear = drag_x = drag_y = 0.0
    if si[J_TARED]:
        _tare(pi, sf)
        fx, fy, fz = sf[S_TARED_Q], sf[S_TARED_Q + 1], sf[S_TARED_Q + 2]
        mag = math.sqrt(fx * fx + fy * fy + fz * fz)
        inside, slope = detect(pf, pi, sf, si, fx, fy, fz, mag)
        if inside and flags & BAD_SAMPLE == 0:
            # the phase from the fast path's slope, which does not wait for the 166 ms window
            rate = pf[P_PHASE_RATE]
            phase = PHASE_TOUCH if slope > rate else PHASE_RELEASE if slope < -rate else PHASE_HOLD
            _locate(t, mag, pf, pi, sf, out_f, out_b, out_s, col)
            if pi[I_TRACE]:
                traced = 1
                _trace_rows(pi, sf, out_f, col)
            located = out_b[OUT_B_LOCATED, col] == 1
            if located:
                shear, drag_x, drag_y = _shear_and_drag(pf, pi, fx, fy, fz, mag, out_s[col])
    else:
        flags |= FLAG_NOT_TARED
    if not located:
        out_f[OUT_X, col] = out_f[OUT_Y, col] = out_f[OUT_Z, col] = 0.0
        out_f[OUT_SIGMA, col] = pf[P_UNCERTAINTY_CAP]
        out_b[OUT_B_SOURCE, col] = 0
        out_s[col] = -1
    out_f[OUT_FORCE, col] = mag
    out_f[OUT_SHEAR, col], out_f[OUT_DRAG_X, col], out_f[OUT_DRAG_Y, col] = shear, drag_x, drag_y
    out_f[OUT_X2, col] = out_f[OUT_Y2, col] = out_f[OUT_Z2, col] = 0.0  # (_second_finger's)
    out_b[OUT_B_LOCATED2, col] = 0
    out_b[OUT_B_PHASE, col] = phase
    out_b[OUT_B_TRACED, col] = traced
    out_b[OUT_B_IN_CONTACT, col] = 1 if inside else 0
    out_b[OUT_B_RESTING, col] = 1 if inside and si[J_RESTING] else 0
    out_b[OUT_B_FLAGS, col] = flags  # (int8 holds the uint8 bits: read as uint8)
    if si[J_MT_ON] and si[J_STARTED]:
        return _second_finger(pf, pi, sf, si, flags, out_f, out_b, out_s, col)
    return 0


@inlined
def _out_time(t: float, sf: np.ndarray) -> float:
    """The time a sample is written out with: its own, or for one whose time is NaN or
    infinite (flagged ``nan``) the latest finite time so far (0 before any), so the outputs
    stay finite and in order."""
    if abs(t) < math.inf:
        return t
    return sf[S_MAX_T] if sf[S_MAX_T] > -math.inf else 0.0


@inlined
def _tare(pi: np.ndarray, sf: np.ndarray) -> None:
    """The low-passed and the fast wrench of the sample in flight less the zero, into
    S_TARED_W and S_TARED_Q (the fast one's moments only where I_DET_FULL: 0 otherwise)."""
    det_full = pi[I_DET_FULL] == 1
    for r in range(6):
        sf[S_TARED_W + r] = sf[S_LP + r] - sf[S_ZERO + r]
        sf[S_TARED_Q + r] = sf[S_DET + r] - sf[S_ZERO + r] if det_full or r < 3 else 0.0


@inlined
def _trace_rows(pi: np.ndarray, sf: np.ndarray, out_f: np.ndarray, col: int) -> None:
    """The traced candidates of the sample in flight into its trace rows."""
    at = pi[I_SO_TRACE]
    for row in range(TRACE_ROWS):
        out_f[N_OUT_F + row, col] = sf[at + row]


@inlined
def _shear_and_drag(
    pf: np.ndarray,
    pi: np.ndarray,
    fx: float,
    fy: float,
    fz: float,
    mag: float,
    s: int,
) -> tuple[float, float, float]:
    """The outputs of a located sample's tared fast force (``mag`` its magnitude) on its
    surface ``s``: (the shear, the finger's drag along a horizontal board in x and y; 0
    elsewhere)."""
    # the shear from the fast force and the surface's normal; the finger's drag
    # along a horizontal board (F is the desk's reaction: the force along it)
    at, n = surface_at(pi, s), SURF_NORMAL
    surf = pf[at : at + SURF_F]
    into = fx * surf[n] + fy * surf[n + 1] + fz * surf[n + 2]
    shear = shear_of(into, mag, pf[P_SHEAR_CAP], pf[P_SHEAR_CAP_INV])
    if pi[pi[I_IO_SURF] + s * SURF_I + SURF_DESK_XY]:
        return shear, into * surf[n] - fx, into * surf[n + 1] - fy
    return shear, 0.0, 0.0


@inlined
def _sample(
    t: float,
    x: np.ndarray,
    before: np.ndarray,
    mapped: Wrench,
    a: np.ndarray,
    given: bool,
    pf: np.ndarray,
    pi: np.ndarray,
    sf: np.ndarray,
    si: np.ndarray,
    out_f: np.ndarray,
    out_b: np.ndarray,
    out_s: np.ndarray,
    col: int,
) -> int:
    """One sample (``x``, its channels; ``before``, the sample before's, ``keep_row``;
    ``mapped``, their wrench, ``wrench_of``) through every stage, from where si[J_RESUME]
    says; returns the events it raised (0: none)."""
    resume = si[J_RESUME]
    si[J_RESUME] = RESUME_NEXT
    events = 0
    if resume != RESUME_BACK:
        events = _front(t, x, before, mapped, a, given, pf, pi, sf, si)
        if events & EV_PARTIAL_ACCEL:
            si[J_RESUME] = RESUME_AGAIN
            return events
        if events & EV_COVS:  # the sample's own candidates use them: after Python made them
            si[J_RESUME] = RESUME_BACK
            return events
    events |= _back(t, pf, pi, sf, si, out_f, out_b, out_s, col)
    if si[J_RESTING_OFF]:
        si[J_RESTING_OFF] = si[J_RESTING] = 0
    return events
