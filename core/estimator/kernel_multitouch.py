"""The second finger, compiled: its landing while the first finger holds, flagged and kept.

Stage 7 of the kernel (:mod:`hapticdesk.estimator.kernel`), the per-sample side of
:mod:`hapticdesk.estimator.multitouch`: :func:`_second_finger` keeps a short history of the
smoothed wrench and of the first finger's point; :func:`_mt_landing` judges whether the
change over the lag is one force on the board, pressing down, away from the first finger
(its line of action met with the board's plane, paper eqs. 1–2). From the landing to the
contact's end the samples are flagged ``FLAG_MULTI``; once the landing's fit window is full,
Python fits the second point (``EV_FIT``); a contact's end hands Python the stray the desk
showed (:func:`_mt_end_contact`, ``EV_CONTACT_END``).
"""

from __future__ import annotations

import math

import numpy as np

from hapticdesk.estimator.contacts import (
    FLAG_GAP,
    FLAG_MULTI,
)
from hapticdesk.estimator.kernel_compile import inlined
from hapticdesk.estimator.kernel_filters import _sections, _steady
from hapticdesk.estimator.kernel_geometry import contains, surface_at
from hapticdesk.estimator.kernel_slots import (
    EV_CONTACT_END,
    EV_FIT,
    I_JO_MT_HIST,
    I_MT_BOARD,
    I_MT_LAG,
    I_MT_LANDING,
    I_NS,
    I_PO_MT_SOS,
    I_PO_MT_ZI,
    I_SO_LANDING,
    I_SO_MT_HIST,
    I_SO_MT_ZI,
    J_MT_COUNT,
    J_MT_END_FLAGGED,
    J_MT_FLAGGED,
    J_MT_HAS_SECOND,
    J_MT_LANDING,
    J_MT_NEED,
    J_MT_POS,
    J_MT_PREV_IN,
    J_MT_ROWS,
    J_MT_STARTED,
    MT_F,
    MT_FORCE,
    MT_I,
    MT_INSIDE,
    MT_LOCATED,
    MT_SURFACE,
    MT_X,
    MT_Y,
    MT_Z,
    OUT_B_FLAGS,
    OUT_B_IN_CONTACT,
    OUT_B_LOCATED,
    OUT_B_LOCATED2,
    OUT_FORCE,
    OUT_X,
    OUT_X2,
    OUT_Y,
    OUT_Y2,
    OUT_Z,
    OUT_Z2,
    P_MT_MAX_FIRST_MOVE,
    P_MT_MIN_NORMAL_SHARE,
    P_MT_MIN_STEP,
    P_MT_MIN_STEP_SHARE,
    S_MT_END_STRAY,
    S_MT_FIRST,
    S_MT_MIN_APART,
    S_MT_SECOND,
    S_MT_STRAY,
    S_RAW,
    SURF_F,
    SURF_NORMAL,
    SURF_ORIGIN,
    SURF_U,
    SURF_V,
)


@inlined
def _mt_restart(pf: np.ndarray, pi: np.ndarray, sf: np.ndarray, si: np.ndarray) -> int:
    """The second-finger stage afresh (at a gap, as the filters): its smoothing from the
    sample in flight, no history; the open contact ends. Returns the events."""
    _steady(pf, pi[I_PO_MT_ZI], pi[I_NS], sf, pi[I_SO_MT_ZI], S_RAW)
    si[J_MT_STARTED] = 1
    si[J_MT_COUNT] = 0
    si[J_MT_POS] = 0
    events = _mt_end_contact(sf, si)
    si[J_MT_PREV_IN] = 0
    return events


@inlined
def _mt_end_contact(sf: np.ndarray, si: np.ndarray) -> int:
    """The open contact ended: what it showed goes to Python (EV_CONTACT_END, the desk's
    stray learned there) if anything; the contact's state is cleared."""
    events = 0
    if si[J_MT_FLAGGED] or sf[S_MT_STRAY] > 0:
        si[J_MT_END_FLAGGED] = si[J_MT_FLAGGED]
        sf[S_MT_END_STRAY] = sf[S_MT_STRAY]
        events = EV_CONTACT_END
    sf[S_MT_STRAY] = 0.0
    si[J_MT_FLAGGED] = si[J_MT_LANDING] = si[J_MT_HAS_SECOND] = 0
    return events


@inlined
def _mt_landing(pf: np.ndarray, pi: np.ndarray, sf: np.ndarray, si: np.ndarray) -> float:
    """Whether the change of the smoothed wrench over the lag before the sample in flight is
    a single force on the board, rising and pressing down, while the first finger was in
    contact, located and still over the lag before that: how far from the first finger it
    lies (its line of action met with the board, paper eqs. 1–2), or −1 where it is no
    such change (multitouch.py)."""
    lag = pi[I_MT_LAG]
    size = 2 * lag + 1
    if si[J_MT_COUNT] < size or pi[I_MT_BOARD] < 0:
        return -1.0
    hist, ints = pi[I_SO_MT_HIST], pi[I_JO_MT_HIST]
    now = si[J_MT_POS]
    before = now - lag if now >= lag else now - lag + size
    earlier = now + 1 if now + 1 < size else 0
    fn, ib, ie = hist + MT_F * now, ints + MT_I * before, ints + MT_I * earlier
    fb, fe = hist + MT_F * before, hist + MT_F * earlier
    moved = math.hypot(sf[fb + MT_X] - sf[fe + MT_X], sf[fb + MT_Y] - sf[fe + MT_Y])
    if not (
        si[ib + MT_INSIDE]
        and si[ib + MT_LOCATED]
        and si[ie + MT_LOCATED]
        and si[ib + MT_SURFACE] == 0  # the first finger on the board, as the second
        and si[ie + MT_SURFACE] == 0
        and moved <= pf[P_MT_MAX_FIRST_MOVE]
        and si[ints + MT_I * now + MT_INSIDE]
        and sf[fn + MT_FORCE] - sf[fb + MT_FORCE] >= pf[P_MT_MIN_STEP]
    ):
        return -1.0
    return _mt_apart(pf, pi, sf, fn, fb)


@inlined
def _mt_apart(pf: np.ndarray, pi: np.ndarray, sf: np.ndarray, fn: int, fb: int) -> float:
    """How far from the first finger (its point in the history's row at ``fb``) the change of
    the smoothed wrench from that row to the row at ``fn`` lies: its line of action met with
    the board's plane (paper eqs. 1–2); −1 where the change is no single force on the board,
    pressing down, large enough for the force before it."""
    dfx, dfy, dfz = sf[fn] - sf[fb], sf[fn + 1] - sf[fb + 1], sf[fn + 2] - sf[fb + 2]
    dmx, dmy, dmz = sf[fn + 3] - sf[fb + 3], sf[fn + 4] - sf[fb + 4], sf[fn + 5] - sf[fb + 5]
    step = math.sqrt(dfx * dfx + dfy * dfy + dfz * dfz)
    at = surface_at(pi, pi[I_MT_BOARD])
    board = pf[at : at + SURF_F]
    o, n = SURF_ORIGIN, SURF_NORMAL
    ox, oy, oz = board[o], board[o + 1], board[o + 2]
    nx, ny, nz = board[n], board[n + 1], board[n + 2]
    # the point P with ΔM = P × ΔF on the board's plane
    f2 = dfx * dfx + dfy * dfy + dfz * dfz
    ok = f2 > 0
    safe_f2 = f2 if ok else 1.0
    footx = (dfy * dmz - dfz * dmy) / safe_f2
    footy = (dfz * dmx - dfx * dmz) / safe_f2
    footz = (dfx * dmy - dfy * dmx) / safe_f2
    across = dfx * nx + dfy * ny + dfz * nz
    ok = ok and abs(across) > 1e-3 * math.sqrt(safe_f2)
    lam = ((ox - footx) * nx + (oy - footy) * ny + (oz - footz) * nz) / (across if ok else 1.0)
    px, py, pz = footx + lam * dfx, footy + lam * dfy, footz + lam * dfz
    ax, ay, az = px - sf[fb + MT_X], py - sf[fb + MT_Y], pz - sf[fb + MT_Z]
    apart = math.sqrt(ax * ax + ay * ay + az * az)
    rx, ry, rz = px - ox, py - oy, pz - oz
    ua, va = SURF_U, SURF_V
    on_board = contains(
        pf,
        pi,
        pi[I_MT_BOARD],
        rx * board[ua] + ry * board[ua + 1] + rz * board[ua + 2],
        rx * board[va] + ry * board[va + 1] + rz * board[va + 2],
    )
    pressing = abs(dfx * nx + dfy * ny + dfz * nz) >= pf[P_MT_MIN_NORMAL_SHARE] * step
    if ok and step >= pf[P_MT_MIN_STEP_SHARE] * sf[fb + MT_FORCE] and pressing and on_board:
        return apart
    return -1.0


@inlined
def _second_finger(
    pf: np.ndarray,
    pi: np.ndarray,
    sf: np.ndarray,
    si: np.ndarray,
    flags: int,
    out_f: np.ndarray,
    out_b: np.ndarray,
    out_s: np.ndarray,
    col: int,
) -> int:
    """A second finger that lands while the first holds: flagged FLAG_MULTI from its landing
    to the contact's end, placed once its fit window is over (multitouch.py). Returns the
    events (the fit and a contact's end are Python's)."""
    events = 0
    if flags & FLAG_GAP or not si[J_MT_STARTED]:
        events |= _mt_restart(pf, pi, sf, si)
    pos = _mt_record(pf, pi, sf, si, out_f, out_b, out_s, col)
    inside = out_b[OUT_B_IN_CONTACT, col] == 1
    apart = _mt_landing(pf, pi, sf, si)
    if not inside:
        if si[J_MT_PREV_IN]:
            events |= _mt_end_contact(sf, si)
        si[J_MT_PREV_IN] = 0
        return events
    si[J_MT_PREV_IN] = 1
    if not si[J_MT_FLAGGED]:
        if apart < 0 or apart < sf[S_MT_MIN_APART]:
            sf[S_MT_STRAY] = max(sf[S_MT_STRAY], max(apart, 0.0))
            return events
        si[J_MT_FLAGGED] = 1
        out_b[OUT_B_FLAGS, col] |= FLAG_MULTI
        _mt_land(pi, sf, si, pos)
        return events
    out_b[OUT_B_FLAGS, col] |= FLAG_MULTI
    return events | _mt_follow(pi, sf, si, pos, out_f, out_b, col)


@inlined
def _mt_record(
    pf: np.ndarray,
    pi: np.ndarray,
    sf: np.ndarray,
    si: np.ndarray,
    out_f: np.ndarray,
    out_b: np.ndarray,
    out_s: np.ndarray,
    col: int,
) -> int:
    """The sample in flight into the history (a ring of 2·I_MT_LAG + 1 rows): its smoothed
    wrench, the first finger's point and force from the outputs. Returns its row."""
    ns = pi[I_NS]
    lag = pi[I_MT_LAG]
    size = 2 * lag + 1
    pos = si[J_MT_POS] + 1 if si[J_MT_COUNT] else 0
    if pos >= size:
        pos = 0
    si[J_MT_POS] = pos
    hist, ints = pi[I_SO_MT_HIST] + MT_F * pos, pi[I_JO_MT_HIST] + MT_I * pos
    _sections(pf, pi[I_PO_MT_SOS], ns, sf, pi[I_SO_MT_ZI], S_RAW, hist)
    inside = out_b[OUT_B_IN_CONTACT, col] == 1
    sf[hist + MT_X], sf[hist + MT_Y], sf[hist + MT_Z] = (
        out_f[OUT_X, col],
        out_f[OUT_Y, col],
        out_f[OUT_Z, col],
    )
    sf[hist + MT_FORCE] = out_f[OUT_FORCE, col]
    si[ints + MT_LOCATED] = out_b[OUT_B_LOCATED, col]
    si[ints + MT_SURFACE] = out_s[col]
    si[ints + MT_INSIDE] = 1 if inside else 0
    si[J_MT_COUNT] = min(si[J_MT_COUNT] + 1, size)
    return pos


@inlined
def _mt_land(pi: np.ndarray, sf: np.ndarray, si: np.ndarray, pos: int) -> None:
    """A second finger landed at the history's row ``pos``: the fit window starts."""
    lag = pi[I_MT_LAG]
    size = 2 * lag + 1
    # landed: its fit window holds the smoothed wrench from 2·lag before to I_MT_LANDING
    # after; the first finger's point is where it was a lag before
    before = pos - lag if pos >= lag else pos - lag + size
    fb = pi[I_SO_MT_HIST] + MT_F * before
    sf[S_MT_FIRST], sf[S_MT_FIRST + 1], sf[S_MT_FIRST + 2] = (
        sf[fb + MT_X],
        sf[fb + MT_Y],
        sf[fb + MT_Z],
    )
    rows = si[J_MT_COUNT]
    landing = pi[I_SO_LANDING]
    for j in range(rows):
        at = pos - rows + 1 + j
        if at < 0:
            at += size
        for lane in range(6):
            sf[landing + 6 * j + lane] = sf[pi[I_SO_MT_HIST] + MT_F * at + lane]
    si[J_MT_ROWS] = rows
    si[J_MT_LANDING] = 1
    si[J_MT_NEED] = pi[I_MT_LANDING]


@inlined
def _mt_follow(
    pi: np.ndarray,
    sf: np.ndarray,
    si: np.ndarray,
    pos: int,
    out_f: np.ndarray,
    out_b: np.ndarray,
    col: int,
) -> int:
    """A sample after the landing (the history's row ``pos``): into the fit window until it
    is full (EV_FIT, Python fits the point), then the second point into the outputs.
    Returns the events."""
    events = 0
    hist = pi[I_SO_MT_HIST] + MT_F * pos
    if si[J_MT_LANDING]:
        landing = pi[I_SO_LANDING] + 6 * si[J_MT_ROWS]
        for lane in range(6):
            sf[landing + lane] = sf[hist + lane]
        si[J_MT_ROWS] += 1
        si[J_MT_NEED] -= 1
        if si[J_MT_NEED] == 0:
            si[J_MT_LANDING] = 0
            events |= EV_FIT  # its point is known at this sample
    elif si[J_MT_HAS_SECOND]:
        out_f[OUT_X2, col], out_f[OUT_Y2, col], out_f[OUT_Z2, col] = (
            sf[S_MT_SECOND],
            sf[S_MT_SECOND + 1],
            sf[S_MT_SECOND + 2],
        )
        out_b[OUT_B_LOCATED2, col] = 1
    return events
