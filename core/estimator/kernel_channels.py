"""One input sample checked and mapped, compiled: its flags, its wrench, the channels' steps.

Stage 1 of the kernel (:mod:`hapticdesk.estimator.kernel`), the per-sample side of
:mod:`hapticdesk.estimator.samples` and :mod:`hapticdesk.estimator.resolution`:
:func:`_samples` flags a sample (NaN, saturated, its time going back, a stuck input, a gap);
:func:`held_over` holds over a reading that jumps for one sample (a corrupt one);
:func:`wrench_of` maps its channels to the resultant force and moment about P_o,
[F_o; M_o] = M x (paper eqs. 1–4; the entries make it a sample ahead); :func:`_learn_steps`
learns each channel's resolution step from the changes between good readings, and
:func:`steps_changed` says when the covariances must be made anew for them.
"""

from __future__ import annotations

import math

import numpy as np

from hapticdesk.estimator.contacts import (
    FLAG_GAP,
    FLAG_NAN,
    FLAG_SATURATED,
    FLAG_STUCK,
    FLAG_TIME_BACK,
)
from hapticdesk.estimator.kernel_compile import inlined, inlined_entry
from hapticdesk.estimator.kernel_slots import (
    EV_JUMP,
    EV_LIVE,
    EV_NOISE_FREE,
    EV_STUCK,
    EV_TIME_BACK,
    I_C,
    I_CHECK_N,
    I_CONFIRM,
    I_JO_CHANGES,
    I_JO_LEARNING,
    I_JUMP_HOLD_N,
    I_LIVE_N,
    I_NOISE_FREE_REPEATS,
    I_PO_LIMIT,
    I_PO_MAP,
    I_REST_N,
    I_SO_LAST_ROW,
    I_SO_PREV_ROW,
    I_SO_REST_SQ,
    I_SO_STEP,
    I_SO_USED,
    I_STUCK_RUN,
    J_DIRTY,
    J_HAVE_LAST_ROW,
    J_HAVE_PREV,
    J_IN_CONTACT,
    J_JUMP,
    J_JUMP_HELD_N,
    J_JUMPS,
    J_LIVE,
    J_N_LEARNING,
    J_OFF_STEPS,
    J_REPEATS,
    J_REST_N,
    J_SEEN,
    J_SEEN_REPEATS,
    J_STARTED,
    J_STUCK_CHECK,
    J_TARED,
    J_TIME_BACK,
    JUMP_CALM,
    JUMP_HELD,
    JUMP_MOVING,
    P_JUMP_ARM_INV_SQ,
    P_JUMP_SQ,
    P_MAX_GAP,
    P_STEP_CHANGE,
    S_BACK_FROM,
    S_BACK_LAST,
    S_EV_LATEST,
    S_EV_T,
    S_JUMP_SIZE,
    S_JUMP_T,
    S_LAST_GOOD,
    S_LAST_STUCK_T,
    S_LAST_T,
    S_MAX_T,
    S_STUCK_SINCE,
    Wrench,
)


@inlined
def _samples(
    t: float,
    x: np.ndarray,
    before: np.ndarray,
    pf: np.ndarray,
    pi: np.ndarray,
    sf: np.ndarray,
    si: np.ndarray,
) -> tuple[int, int]:
    """Flags of one input sample (NaN, saturated, time back, stuck, gap; ``before``: the
    channels of the sample before, :func:`keep_row`) and, for a good one, its channels'
    changes into the resolution steps (its resultant is :func:`wrench_of`'s). Returns
    (flags, events)."""
    c_n = pi[I_C]
    flags = events = 0
    # one pass over the channels, without branches: each within its limit (so finite: False
    # for NaN too), equal to the sample before (a repeat, for the stuck check below)
    within = abs(t) < math.inf
    repeat = si[J_HAVE_PREV] == 1
    limit = pf[pi[I_PO_LIMIT] : pi[I_PO_LIMIT] + c_n]
    for c in range(c_n):
        v = x[c]
        within &= abs(v) < limit[c]
        repeat &= v == before[c]
    finite, saturated, reset = True, False, False
    if not within:  # (rare) which of the two
        finite = abs(t) < math.inf
        for c in range(c_n):
            finite &= abs(x[c]) < math.inf
            saturated |= abs(x[c]) >= limit[c]
    if not finite:
        flags |= FLAG_NAN
    else:
        if saturated:
            flags |= FLAG_SATURATED
        back, events, reset = _time_back(t, pf, sf, si)
        flags |= back
    stuck, told = _stuck_check(t, repeat, finite, pi, sf, si)
    flags |= stuck
    events |= told
    if flags:
        return flags, events
    if reset or sf[S_LAST_T] > -math.inf and t - sf[S_LAST_T] > pf[P_MAX_GAP]:
        flags |= FLAG_GAP
    sf[S_LAST_T] = t
    _learn_steps(x, pi, sf, si)
    return flags, events


@inlined
def _time_back(t: float, pf: np.ndarray, sf: np.ndarray, si: np.ndarray) -> tuple[int, int, bool]:
    """Whether the finite sample's time ``t`` is not after an earlier one's (FLAG_TIME_BACK,
    told at the 1st, 10th, 100th… such sample). Times that went back but rise among
    themselves for longer than ``max_gap_s`` are a clock that jumped back (or one earlier
    time far ahead, a corrupt line): from there on they are the times (the third item True:
    a gap, the filters restart), where before one bad time kept every later sample out.
    Returns (flags, events, reset)."""
    if t > sf[S_MAX_T]:
        sf[S_MAX_T] = t
        sf[S_BACK_LAST] = math.inf
        return 0, 0, False
    if not t > sf[S_BACK_LAST]:  # a run of times that went back starts here
        sf[S_BACK_FROM] = t
    sf[S_BACK_LAST] = t
    if t - sf[S_BACK_FROM] > pf[P_MAX_GAP]:
        sf[S_MAX_T] = t
        sf[S_BACK_LAST] = math.inf
        return 0, 0, True
    si[J_TIME_BACK] += 1
    if _told_at(si[J_TIME_BACK]):
        sf[S_EV_T], sf[S_EV_LATEST] = t, sf[S_MAX_T]
        return FLAG_TIME_BACK, EV_TIME_BACK, False
    return FLAG_TIME_BACK, 0, False


@inlined
def _told_at(count: int) -> bool:
    """Whether the ``count``-th of a kind of bad reading is told: the 1st, 10th, 100th…"""
    mark = 1
    while mark < count:
        mark *= 10
    return mark == count


@inlined
def held_over(
    t: float,
    mapped: Wrench,
    flags: int,
    pf: np.ndarray,
    pi: np.ndarray,
    sf: np.ndarray,
    si: np.ndarray,
) -> tuple[bool, int]:
    """Whether the sample (``flags``, its wrench ``mapped``) is held over for its jump
    (:func:`jumped`), and the events: a good sample after a good one may be; one after a
    gap is taken (the filters restart there)."""
    if flags == 0 and si[J_STARTED]:
        return jumped(t, mapped, pf, pi, sf, si)
    if flags == FLAG_GAP:
        si[J_JUMP] = JUMP_CALM
    return False, 0


@inlined
def jumped(
    t: float, mapped: Wrench, pf: np.ndarray, pi: np.ndarray, sf: np.ndarray, si: np.ndarray
) -> tuple[bool, int]:
    """Whether a good sample after a good one is held (its wrench ``mapped`` not taken: the
    last good one stands for it), and the events. A corrupt reading lasts a sample or a few:
    one that jumps from a calm wrench (settings.JUMP_SHARE) is held, and so are the next ones
    that stay away from the last good wrench, up to I_JUMP_HOLD_N in a row
    (settings.JUMP_HOLD_S); the one after is taken whatever it is. One that came back ends
    the run: the held ones were corrupt (counted, told at the 1st, 10th… such); if the run
    outlasts the hold, the change is real, and none is held while it keeps jumping."""
    good = sf[S_LAST_GOOD : S_LAST_GOOD + 6]
    df = (mapped[0] - good[0]) ** 2 + (mapped[1] - good[1]) ** 2 + (mapped[2] - good[2]) ** 2
    dm = (mapped[3] - good[3]) ** 2 + (mapped[4] - good[4]) ** 2 + (mapped[5] - good[5]) ** 2
    dm *= pf[P_JUMP_ARM_INV_SQ]
    jump = df > pf[P_JUMP_SQ] or dm > pf[P_JUMP_SQ]
    state = si[J_JUMP]
    if state == JUMP_CALM:
        if jump:
            si[J_JUMP] = JUMP_HELD
            si[J_JUMP_HELD_N] = 1
            sf[S_JUMP_T], sf[S_JUMP_SIZE] = t, math.sqrt(max(df, dm))
        return jump, 0
    if state == JUMP_HELD and jump and si[J_JUMP_HELD_N] < pi[I_JUMP_HOLD_N]:
        si[J_JUMP_HELD_N] += 1  # (still away: held too)
        return True, 0
    si[J_JUMP] = JUMP_MOVING if jump else JUMP_CALM
    if state == JUMP_HELD and not jump:  # it came back: the held reading was corrupt
        si[J_JUMPS] += 1
        if _told_at(si[J_JUMPS]):
            return False, EV_JUMP
    return False, 0


@inlined
def keep_row(x: np.ndarray, last: int, start: int, pi: np.ndarray, sf: np.ndarray) -> None:
    """The row ``last`` of the block ``x``, the last one checked (none before ``start``), kept
    in the state (I_SO_PREV_ROW): the stuck check compares a block's first sample with it,
    and each other with the block's row before."""
    if last >= start:
        prev = sf[pi[I_SO_PREV_ROW] : pi[I_SO_PREV_ROW] + pi[I_C]]
        row = x[last]
        for c in range(pi[I_C]):
            prev[c] = row[c]


@inlined
def _stuck_check(
    t: float,
    repeat: bool,
    finite: bool,
    pi: np.ndarray,
    sf: np.ndarray,
    si: np.ndarray,
) -> tuple[int, int]:
    """Whether the input sticks (``repeat``: the sample equals the one before, which the
    channels' pass of :func:`samples` keeps). Returns (FLAG_STUCK or 0, events)."""
    flags = 0
    events = 0
    # a stuck input repeats its last sample bit for bit; a noise-free one does so all the
    # time, so the first CHECK_N samples decide whether to look at all
    check = si[J_STUCK_CHECK]
    if check != 0:
        si[J_HAVE_PREV] = 1
        if check < 0:
            if repeat:
                si[J_SEEN_REPEATS] += 1
            si[J_SEEN] += 1
            if si[J_SEEN_REPEATS] >= pi[I_NOISE_FREE_REPEATS]:
                si[J_STUCK_CHECK] = 0
                events |= EV_NOISE_FREE
            elif si[J_SEEN] >= pi[I_CHECK_N]:
                si[J_STUCK_CHECK] = 1
        else:
            si[J_REPEATS] = si[J_REPEATS] + 1 if repeat and finite else 0
            if si[J_REPEATS] >= pi[I_STUCK_RUN]:
                flags |= FLAG_STUCK
                if si[J_LIVE] >= pi[I_LIVE_N]:
                    sf[S_STUCK_SINCE] = t
                    events |= EV_STUCK
                si[J_LIVE] = 0
                sf[S_LAST_STUCK_T] = t
            elif si[J_LIVE] < pi[I_LIVE_N]:
                si[J_LIVE] += 1
                if si[J_LIVE] == pi[I_LIVE_N]:
                    sf[S_EV_T] = t
                    events |= EV_LIVE
    return flags, events


@inlined
def wrench_of(x: np.ndarray, pf: np.ndarray, pi: np.ndarray) -> Wrench:
    """A sample's resultant [F_o; M_o] = M x about P_o (paper eqs. 1–4), whatever its flags
    (it depends on nothing else: the entries make the next sample's while this one runs)."""
    c_n = pi[I_C]
    # the matrix stored by channel (C, 6), its six sums side by side and each split in two
    # (even and odd channels) so that no long chain of additions waits on itself
    m = pf[pi[I_PO_MAP] : pi[I_PO_MAP] + 6 * c_n]
    f0 = f1 = f2 = m0 = m1 = m2 = 0.0
    g0 = g1 = g2 = n0 = n1 = n2 = 0.0
    for h in range(c_n // 2):
        c = 2 * h
        v, u = x[c], x[c + 1]
        a, b = 6 * c, 6 * c + 6
        f0 += m[a] * v
        f1 += m[a + 1] * v
        f2 += m[a + 2] * v
        m0 += m[a + 3] * v
        m1 += m[a + 4] * v
        m2 += m[a + 5] * v
        g0 += m[b] * u
        g1 += m[b + 1] * u
        g2 += m[b + 2] * u
        n0 += m[b + 3] * u
        n1 += m[b + 4] * u
        n2 += m[b + 5] * u
    if c_n % 2:
        v, a = x[c_n - 1], 6 * (c_n - 1)
        f0 += m[a] * v
        f1 += m[a + 1] * v
        f2 += m[a + 2] * v
        m0 += m[a + 3] * v
        m1 += m[a + 4] * v
        m2 += m[a + 5] * v
    return f0 + g0, f1 + g1, f2 + g2, m0 + n0, m1 + n1, m2 + n2


@inlined
def _learn_steps(x: np.ndarray, pi: np.ndarray, sf: np.ndarray, si: np.ndarray) -> None:
    """Each channel's smallest change between good readings (its resolution step), until
    I_CONFIRM changes confirm it, and the squared changes of its first I_REST_N readings
    out of contact (its noise: resolution.py)."""
    rest = si[J_REST_N] < pi[I_REST_N] and si[J_IN_CONTACT] == 0
    if si[J_N_LEARNING] == 0 and not rest:
        si[J_HAVE_LAST_ROW] = 0  # (the row kept goes stale)
        return
    c_n = pi[I_C]
    last = sf[pi[I_SO_LAST_ROW] : pi[I_SO_LAST_ROW] + c_n]
    step = sf[pi[I_SO_STEP] : pi[I_SO_STEP] + c_n]
    changes = si[pi[I_JO_CHANGES] : pi[I_JO_CHANGES] + c_n]
    learning = si[pi[I_JO_LEARNING] : pi[I_JO_LEARNING] + c_n]
    if si[J_HAVE_LAST_ROW]:
        if rest:
            squares = sf[pi[I_SO_REST_SQ] : pi[I_SO_REST_SQ] + c_n]
            for c in range(c_n):
                squares[c] += (x[c] - last[c]) ** 2
            si[J_REST_N] += 1
        for c in range(c_n):
            if not learning[c]:
                continue
            change = abs(x[c] - last[c])
            if change > 0:
                before = step[c]
                now = min(before, change) if before > 0 else change
                if now != before:
                    step[c] = now
                    si[J_DIRTY] = 1
                if not (_whole(change / now) and _whole(before / now)):
                    si[J_OFF_STEPS] = 1  # (a continuous reading: its "step" is no resolution)
                changes[c] += 1
                if changes[c] >= pi[I_CONFIRM]:
                    learning[c] = 0
                    si[J_N_LEARNING] -= 1
    for c in range(c_n):
        last[c] = x[c]
    si[J_HAVE_LAST_ROW] = 1


@inlined
def _whole(ratio: float) -> bool:
    """Whether a change in steps is a whole number of them (0 too: no step before)."""
    return abs(ratio - round(ratio)) <= 1e-6 * max(1.0, ratio)


@inlined_entry
def steps_changed(pf: np.ndarray, pi: np.ndarray, sf: np.ndarray, si: np.ndarray) -> bool:
    """Once tared: whether a step is new or shrank by over P_STEP_CHANGE since the
    covariances were made (the steps they use become the current ones)."""
    if not si[J_DIRTY] or not si[J_TARED]:
        return False
    si[J_DIRTY] = 0
    step, used = pi[I_SO_STEP], pi[I_SO_USED]
    changed = False
    for c in range(pi[I_C]):
        if (sf[used + c] == 0 and sf[step + c] > 0) or sf[step + c] < sf[used + c] * (
            1.0 - pf[P_STEP_CHANGE]
        ):
            changed = True
    if changed:
        for c in range(pi[I_C]):
            sf[used + c] = sf[step + c]
    return changed
