"""The zero's rounding offset in a located point's 1-σ, compiled, at almost no cost per sample.

The kernel's side of :mod:`hapticdesk.estimator.resolution` (``zero_rounding_channels``,
``moved_share``): a channel quieter than its rounding step leaves the zero off by part of a
step, one error for every sample until the next tare, which the located point carries as
var_u + var_v = (Jacobian of eq. 5) · Σ_c offset_c · share_c · g_c g_cᵀ / F'z², g_c the
channel's column of the map in (F'z, M'x, M'y) and share_c how much of its offset the press
keeps (a channel the press does not move keeps none, one moved a sixth of a step or more all).

The sums over the channels (cz, czx, czy, cx, cy) change only as the shares do, and a share
changes only as the tared wrench does: so they are made anew only when the wrench has moved
more than ``REUSE_MOVE`` of its size since they were made (or the point is on another
surface, or a tare made the floor anew), and reused, scaled by 1/F'z², in between. Through a
held press that is once; through a tap's rise and fall a few dozen times. What is reused is
kept in the state (ROUND_SURFACE…ROUND_SUMS), so a stream pushed in pieces reuses exactly
what a batch does. Made anew, a channel's share is read off a table over its change (the
exact share at ROUND_TABLE_N + 1 points, made at the tare by
:class:`~hapticdesk.estimator.candidates.Covariances`), not summed from its harmonics.
"""

from __future__ import annotations

import math

import numpy as np

from hapticdesk.estimator.kernel_compile import compiled, inlined, inlined_entry
from hapticdesk.estimator.kernel_geometry import surface_at, surface_force
from hapticdesk.estimator.kernel_slots import (
    I_C,
    I_SO_ROUND,
    P_VAR_CAP,
    ROUND_ACTIVE,
    ROUND_LIMIT,
    ROUND_SPREAD,
    ROUND_SUMS,
    ROUND_SURFACE,
    ROUND_TABLE,
    ROUND_TABLE_N,
    ROUND_W,
    ROUND_WHOLE,
    SURF_F,
)

# the sums are reused while the tared wrench stays within this share of its size of where they
# were made: a change of the press by this share changes a channel's change, and so the share
# it keeps under noise (quadratic in a small change), by at most about twice this
# (tests/core/test_core_rounding_floor.py: the floor's 1-σ within 5 % of the exact one)
REUSE_MOVE = 0.02


@inlined
def _shares_summed(sf: np.ndarray, at: int, c_n: int, w: int, s: int) -> None:
    """The sums cz, czx, czy, cx, cy of surface ``s`` for the tared wrench sf[w:w+6], each
    channel's offset term by the share the press keeps (the table at ROUND_TABLE, read at the
    channel's change in steps), into the kept sums, with the wrench and surface they are for
    and how far from it they serve: ``REUSE_MOVE`` of its size, or, where every channel keeps
    all of its offset, as far as the wrench can go before one keeps less."""
    spread = at + ROUND_SPREAD
    reach = spread + 6 * c_n  # (wrench per step of a channel's change: 1 / its spread's norm)
    terms = reach + c_n + 5 * c_n * s
    table = at + ROUND_TABLE
    scale = 2.0 * ROUND_TABLE_N  # (table points per step of change; ``reach`` per point)
    whole = sf[at + ROUND_WHOLE]  # (the table point from which a channel keeps all)
    w0, w1, w2, w3, w4, w5 = sf[w], sf[w + 1], sf[w + 2], sf[w + 3], sf[w + 4], sf[w + 5]
    cz = czx = czy = cx = cy = 0.0
    margin = math.inf  # (how far the wrench can go before a channel keeps less)
    for c in range(c_n):
        if sf[reach + c] == 0.0:  # (a channel that keeps no offset)
            continue
        k = spread + 6 * c
        change = sf[k] * w0 + sf[k + 1] * w1 + sf[k + 2] * w2
        change += sf[k + 3] * w3 + sf[k + 4] * w4 + sf[k + 5] * w5
        x = min(abs(change) * scale, ROUND_TABLE_N)
        if x >= whole:
            share = sf[table + ROUND_TABLE_N]
            margin = min(margin, (x - whole) * sf[reach + c])
        else:
            i = int(x)
            share = sf[table + i] + (x - i) * (sf[table + i + 1] - sf[table + i])
            margin = 0.0
        t = terms + 5 * c
        cz += share * sf[t]
        czx += share * sf[t + 1]
        czy += share * sf[t + 2]
        cx += share * sf[t + 3]
        cy += share * sf[t + 4]
    kept = at + ROUND_SUMS
    sf[kept], sf[kept + 1], sf[kept + 2], sf[kept + 3], sf[kept + 4] = cz, czx, czy, cx, cy
    sf[at + ROUND_SURFACE] = s
    size = 0.0
    for j in range(6):
        sf[at + ROUND_W + j] = sf[w + j]
        size += sf[w + j] * sf[w + j]
    sf[at + ROUND_LIMIT] = max(REUSE_MOVE * REUSE_MOVE * size, margin * margin)


@inlined_entry
def rounding_floor(
    pf: np.ndarray,
    pi: np.ndarray,
    sf: np.ndarray,
    w: int,
    s: int,
    u: float,
    v: float,
    inv_fz: float,
) -> float:
    """var_u + var_v that the zero's rounding offset gives the point (u, v) of surface ``s``
    under the tared wrench sf[w:w+6]: a floor growing as 1/F'z, the same error for every
    sample until the next tare, so no averaging of samples lowers it (0 where no channel
    keeps an offset). The sums over the channels are the kept ones while the wrench stays
    near where they were made (module docstring), else made anew. ``inv_fz``: 1/F'z of the
    wrench on ``s`` where a candidate made from it has it (the same bits as made here: both
    kernel_geometry.surface_force), 0 to make it here."""
    at = pi[I_SO_ROUND]
    if sf[at + ROUND_ACTIVE] == 0.0:  # no channel rounds quieter than its step
        return 0.0
    kept = at + ROUND_W
    moved = 0.0
    for j in range(6):
        moved += (sf[w + j] - sf[kept + j]) ** 2
    if sf[at + ROUND_SURFACE] != s or moved > sf[at + ROUND_LIMIT]:
        _shares_summed(sf, at, pi[I_C], w, s)
    if inv_fz == 0.0:
        r = pf[surface_at(pi, s) : surface_at(pi, s) + SURF_F]
        fz = surface_force(r, sf[w], sf[w + 1], sf[w + 2], sf[w + 3], sf[w + 4], sf[w + 5])
        inv_fz = 1.0 / fz
    inv2 = min(inv_fz * inv_fz, 1e18)
    sums = at + ROUND_SUMS
    cz, czx, czy, cx, cy = sf[sums], sf[sums + 1], sf[sums + 2], sf[sums + 3], sf[sums + 4]
    # through the Jacobian of eq. (5), as kernel_geometry._point_covariance
    cap = pf[P_VAR_CAP]
    var_u = min((u * u * cz + 2 * u * czy + cy) * inv2, cap)
    var_v = min((v * v * cz - 2 * v * czx + cx) * inv2, cap)
    return var_u + var_v


@inlined
def _channel_likelihood(
    k: float, mean: np.ndarray, log_mean: np.ndarray, r: int, top: float
) -> float:
    """log mean_p exp(k log μ_rp − μ_rp) (the Poisson's log k! left out: the same for every
    noise), ``top`` its largest term, summed from it down (terms under e⁻⁴⁰ of it left out)."""
    summed = 0.0
    for p in range(mean.shape[1]):
        t = k * log_mean[r, p] - mean[r, p] - top
        if t > -40.0:
            summed += math.exp(t)
    return top + math.log(summed / mean.shape[1])


# rows of likeliest_noise's scratch (6, Q): by channel (q), by place in count order (j), by turn
_BY_COUNT, _COUNT, _TURN, _TERM, _KNOWN, _SUM = range(6)


@compiled
def likeliest_noise(
    counts: np.ndarray,
    mean: np.ndarray,
    log_mean: np.ndarray,
    bound: np.ndarray,
    scratch: np.ndarray,
) -> int:
    """At the tare (resolution.zero_rounding_noise): which of R noises makes the quiet
    channels' squared rest changes ``counts`` (Q,) likeliest, each a Poisson count of mean
    ``mean`` (R, P) at P places between two steps alike (``log_mean`` its log), the
    log-likelihood of a noise being Σ_q log mean_p exp(k_q log μ − μ) (the first on a tie).

    A channel's term is at most max_p (k_q log μ − μ), and that at most the concave
    k log μ − μ's largest over [min_p μ, max_p μ] (at μ = k clipped into it): one logarithm
    a channel and noise, not one a place (into ``bound`` (R, Q + 1), their sum last; the
    margin covers the rounding of the two logarithms). The noises are opened from the highest
    bound down, until a bound falls below the likeliest so far; an opened noise is summed
    whole only if :func:`_may_beat` cannot show it falls short. The whole grid in numpy,
    (Q, R, P) arrays, took 8 ms a tare, a tenth of a minute's estimation; the bound at every
    place, 0.15 ms of this search's 0.4. ``scratch`` (6, Q): room for the channels' order
    by count and an opened noise's terms."""
    n_rho, n_places = mean.shape
    n_q = counts.shape[0]
    for r in range(n_rho):
        low, high = math.inf, -math.inf
        for p in range(n_places):
            low, high = min(low, mean[r, p]), max(high, mean[r, p])
        total = 0.0
        for q in range(n_q):
            at = min(max(counts[q], low), high)
            top = counts[q] * math.log(at) - at
            top += 1e-9 * (1.0 + abs(top))
            bound[r, q] = top
            total += top
        bound[r, n_q] = total
    _turns(counts, scratch)
    best, best_r = -math.inf, 0
    while True:
        r = 0
        for j in range(1, n_rho):
            if bound[j, n_q] > bound[r, n_q]:
                r = j
        if not bound[r, n_q] >= best or bound[r, n_q] == -math.inf:
            return best_r
        left = bound[r, n_q]
        bound[r, n_q] = -math.inf
        if not _may_beat(best, r, counts, mean, log_mean, bound, scratch):
            continue
        # (summed as the bounds and the terms in the channels' order: the same bits as the
        # search that summed every channel in turn)
        for q in range(n_q):
            left += scratch[_TERM, q] - bound[r, q]
        if left > best or (left == best and r < best_r):
            best, best_r = left, r


@inlined
def _turns(counts: np.ndarray, scratch: np.ndarray) -> None:
    """The channels in order of their count (scratch[_BY_COUNT]: which channel is j-th, as a
    float; [_COUNT] its count), and the order :func:`_may_beat` works their terms out in
    ([_TURN]: the places j): the lowest count, the highest, then each time the place in the
    middle of the widest span of counts between two places already taken."""
    n_q = counts.shape[0]
    by_count, count, turn, taken = (
        scratch[_BY_COUNT],
        scratch[_COUNT],
        scratch[_TURN],
        scratch[_KNOWN],
    )
    for q in range(n_q):  # (insertion: stable)
        j = q
        while j > 0 and count[j - 1] > counts[q]:
            by_count[j], count[j] = by_count[j - 1], count[j - 1]
            j -= 1
        by_count[j], count[j] = q, counts[q]
        taken[q] = 0.0
    for i in range(n_q):
        j = 0 if i == 0 else n_q - 1
        if i > 1:
            widest, a = -1.0, 0
            for b in range(1, n_q):
                if taken[b] == 1.0:
                    if b - a > 1 and count[b] - count[a] > widest:
                        j, widest = (a + b) // 2, count[b] - count[a]
                    a = b
        turn[i] = j
        taken[j] = 1.0


@inlined
def _may_beat(
    best: float,
    r: int,
    counts: np.ndarray,
    mean: np.ndarray,
    log_mean: np.ndarray,
    bound: np.ndarray,
    scratch: np.ndarray,
) -> bool:
    """Noise ``r``'s channel terms into scratch[_TERM] (Q,), worked out one channel at a time
    (in the turns of :func:`_turns`) until every one is (True) or a bound on their sum falls
    below ``best`` (False: the noise is less likely). A channel's term log mean_p
    exp(k log μ_rp − μ_rp) is convex in its count k (a log-sum-exp of lines in k), so below
    the chord between the terms of the nearest channels worked out either side of it in
    count (with a margin for their rounding): each channel not yet worked out counts at the
    lower of that chord and its own bound (in scratch[_SUM], by place in count order). On the
    paper desk's tare this works out 543 of the 1,241 channel terms the bounds alone needed
    (the same noise)."""
    n_q = counts.shape[0]
    by_count, known, summed = scratch[_BY_COUNT], scratch[_KNOWN], scratch[_SUM]
    for j in range(n_q):
        known[j] = 0.0
        summed[j] = bound[r, int(by_count[j])]
    for i in range(n_q):
        j = int(scratch[_TURN, i])
        q = int(by_count[j])
        term = _channel_likelihood(counts[q], mean, log_mean, r, bound[r, q])
        scratch[_TERM, q] = summed[j] = term
        known[j] = 1.0
        if i == n_q - 1:
            return True
        a, b = j - 1, j + 1
        while a >= 0 and known[a] == 0.0:
            a -= 1
        while b < n_q and known[b] == 0.0:
            b += 1
        if a >= 0:
            _chords(a, j, r, bound, scratch)
        if b < n_q:
            _chords(j, b, r, bound, scratch)
        total = 0.0
        for u in range(n_q):
            total += summed[u]
        if total < best:
            return False
    return True


@inlined
def _chords(a: int, b: int, r: int, bound: np.ndarray, scratch: np.ndarray) -> None:
    """The channels between places ``a`` and ``b`` in count order (whose terms are worked
    out) at the lower of their own bound and the chord between those two terms
    (:func:`_may_beat`)."""
    if b - a < 2:
        return
    by_count, count, summed = scratch[_BY_COUNT], scratch[_COUNT], scratch[_SUM]
    fa, fb = summed[a], summed[b]
    # (the rounding, and the places a term leaves out, each under e⁻⁴⁰ of its bound: they
    # lower it by at most exp(bound − term − 40), so the chord of the terms left whole lies
    # at most that much higher)
    gap = max(bound[r, int(by_count[a])] - fa, bound[r, int(by_count[b])] - fb)
    margin = 1e-9 * (1.0 + abs(fa) + abs(fb)) + math.exp(gap - 40.0)
    ka = count[a]
    slope = (fb - fa) / (count[b] - ka) if count[b] > ka else 0.0
    for u in range(a + 1, b):
        summed[u] = min(fa + (count[u] - ka) * slope + margin, bound[r, int(by_count[u])])
