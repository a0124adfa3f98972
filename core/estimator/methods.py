"""Stage 6, the methods: which candidate is reported, or how they are fused.

``force`` (the conventional), ``diff``, ``switched`` (paper Fig. 3 with F_tth, F_rth) or
``fused`` (inverse-covariance combination of the candidates, no threshold; a point is
reported when its 1-σ is below ``max_sigma_m``). :func:`select` writes a block's located
samples; :func:`select_one` is the same for one sample on plain floats; the fusion's
information and solution (:func:`information`, :func:`solve`) are written once for both.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from hapticdesk.estimator.candidates import DIFF_INFO_RATIO, Candidates
from hapticdesk.estimator.contacts import SOURCE_DIFF, SOURCE_FORCE, SOURCE_FUSED, ContactBlock
from hapticdesk.estimator.geometry import (
    NO_CANDIDATE,
    VAR_CAP,
    Candidate,
    Intersection,
    SurfaceFrame,
)
from hapticdesk.estimator.settings import EstimatorSettings

DET_FLOOR = 1e-12  # a 2×2 covariance is inverted as if its determinant were at least this share
# of the product of its variances (never singular, whatever the scale)


def information(var_uu: Any, var_vv: Any, cov_uv: Any, maximum: Callable[..., Any]) -> Any:
    """Σ⁻¹ = [[ia, ib], [ib, ic]] of one candidate's in-plane covariance, (ia, ib, ic);
    arrays (``maximum=np.maximum``) or plain floats (``maximum=max``)."""
    product = var_uu * var_vv
    det = maximum(maximum(product - cov_uv * cov_uv, DET_FLOOR * product), 1e-300)
    weight = 1.0 / det
    return var_vv * weight, -cov_uv * weight, var_uu * weight


def solve(a: Any, b: Any, c: Any, ru: Any, rv: Any, maximum: Callable[..., Any]) -> Any:
    """p = (Σ Σ_i⁻¹)⁻¹ Σ Σ_i⁻¹ p_i from the summed information [[a, b], [b, c]] and
    (ru, rv) = Σ Σ_i⁻¹ p_i: (u, v, var_u, var_v, cov_uv) before capping."""
    inv_det = 1.0 / maximum(maximum(a * c - b * b, DET_FLOOR * a * c), 1e-300)
    return (
        (c * ru - b * rv) * inv_det,
        (a * rv - b * ru) * inv_det,
        c * inv_det,
        a * inv_det,
        (-b * inv_det),
    )


def fuse(cands: list[Intersection]) -> tuple[Intersection, np.ndarray]:
    """The valid candidates on the surface of the surest one fused, per sample, 2×2 in
    closed form. Returns the fused candidate and how many were fused."""
    valid = np.logical_or.reduce([c.valid for c in cands])
    if max(int(c.surface.max(initial=-1)) for c in cands) <= 0:
        surface = np.where(valid, 0, -1).astype(np.int16)  # one surface: nothing to choose
        takes = [c.valid for c in cands]
    else:
        sigmas = np.stack([np.where(c.valid, c.sigma(), np.inf) for c in cands])
        best = np.argmin(sigmas, axis=0)
        surface = np.choose(best, [c.surface for c in cands]).astype(np.int16)
        takes = [c.valid & (c.surface == surface) for c in cands]
    members = np.sum(takes, axis=0)
    a = b = c_ = ru = rv = np.zeros(len(valid))
    for cand, take in zip(cands, takes, strict=True):
        ia, ib, ic = information(cand.var_uu, cand.var_vv, cand.cov_uv, np.maximum)
        ia, ib, ic = ia * take, ib * take, ic * take  # zero for a candidate not taken
        cu, cv = cand.uv
        a, b, c_ = a + ia, b + ib, c_ + ic
        ru = ru + ia * cu + ib * cv
        rv = rv + ib * cu + ic * cv
    u, v, var_u, var_v, cov = solve(a, b, c_, ru, rv, np.maximum)
    uv = np.stack([u, v])
    uv[:, ~valid] = 0.0
    return Intersection(
        valid,
        surface,
        uv,
        np.where(valid, np.minimum(var_u, VAR_CAP), VAR_CAP),
        np.where(valid, np.minimum(var_v, VAR_CAP), VAR_CAP),
        np.where(valid, cov, 0.0),
    ), members


def fuse_one(cands: list[Candidate]) -> tuple[Candidate, int]:
    """:func:`fuse` for one sample on plain floats."""
    valid = [c for c in cands if c[0] >= 0]
    if not valid:
        return NO_CANDIDATE, 0
    surest = min(valid, key=lambda c: math.sqrt(c[3] + c[4]))
    a = b = c_ = ru = rv = 0.0
    members = 0
    for cand in valid:
        if cand[0] != surest[0]:
            continue
        ia, ib, ic = information(cand[3], cand[4], cand[5], max)
        a, b, c_ = a + ia, b + ib, c_ + ic
        ru += ia * cand[1] + ib * cand[2]
        rv += ib * cand[1] + ic * cand[2]
        members += 1
    u, v, var_u, var_v, cov = solve(a, b, c_, ru, rv, max)
    return (surest[0], u, v, min(var_u, VAR_CAP), min(var_v, VAR_CAP), cov), members


def select(
    block: ContactBlock, idx: np.ndarray, cands: Candidates, settings: EstimatorSettings
) -> None:
    """Write the method's point for the samples ``idx`` in contact into ``block``."""
    s, frames = settings.user, settings.frames
    cand_f, cand_d, cand_q, f_mag = cands.force, cands.diff, cands.fast, cands.f_mag
    if settings.method == "force":
        assert cand_f is not None
        use = cand_f.valid & (f_mag >= s.contact_force_n)
        emit(block, idx, use, cand_f, SOURCE_FORCE, frames)
    elif settings.method == "diff":
        assert cand_d is not None
        use = cand_d.valid & (cand_d.sigma() <= s.max_sigma_m)
        emit(block, idx, use, cand_d, SOURCE_DIFF, frames)
    elif settings.method == "switched":
        assert cand_f is not None and cand_d is not None and cands.want_d is not None
        gate = f_mag >= s.contact_force_n  # paper Fig. 3, step 4
        use_d = cand_d.valid & cands.want_d  # step 3
        emit(block, idx, gate & cand_f.valid & ~use_d, cand_f, SOURCE_FORCE, frames)
        emit(block, idx, use_d, cand_d, SOURCE_DIFF, frames)
    else:
        assert cand_f is not None and cand_d is not None and cand_q is not None
        # the fast and the low-passed candidates share their noise (one filtered from the
        # other's input), so they are not fused: the fast one stands in where it is the
        # surer (the low-passed force has not caught up yet, or has already let go)
        var_f = cand_f.var_uu + cand_f.var_vv
        cand_q.valid &= ~cand_f.valid | (cand_q.var_uu + cand_q.var_vv < var_f)
        # a differentiated candidate 5 times less sure than the force's adds under 4 % of
        # the information: leave it out
        cand_d.valid &= ~cand_f.valid | (cand_d.var_uu + cand_d.var_vv <= DIFF_INFO_RATIO * var_f)
        emit_fused(block, idx, [cand_f, cand_d, cand_q], settings)


def select_one(
    cf: Candidate, cd: Candidate, cq: Candidate, f_mag: float, motion: float, s: EstimatorSettings
) -> tuple[Candidate | None, int]:
    """:func:`select` for one sample: the chosen candidate (or None) and its source."""
    user = s.user
    f_ok, d_ok = cf[0] >= 0, cd[0] >= 0
    if s.method == "force":
        return (cf, SOURCE_FORCE) if f_ok and f_mag >= user.contact_force_n else (None, 0)
    if s.method == "diff":
        sure = math.sqrt(cd[3] + cd[4]) <= user.max_sigma_m
        return (cd, SOURCE_DIFF) if d_ok and sure else (None, 0)
    if s.method == "switched":
        if f_mag >= user.contact_force_n:
            threshold = user.touch_threshold_n if motion > 0 else user.release_threshold_n
            if d_ok and (f_mag <= threshold or not f_ok):
                return cd, SOURCE_DIFF
            if f_ok:
                return cf, SOURCE_FORCE
        return None, 0
    if f_ok and cq[0] >= 0 and not (cq[3] + cq[4] < cf[3] + cf[4]):
        cq = NO_CANDIDATE  # see select
    if f_ok and d_ok and cd[3] + cd[4] > DIFF_INFO_RATIO * (cf[3] + cf[4]):
        cd = NO_CANDIDATE  # see select
    fused, members = fuse_one([cf, cd, cq])
    if not (fused[0] >= 0 and math.sqrt(fused[3] + fused[4]) <= user.max_sigma_m):
        return None, 0
    if members > 1:
        return fused, SOURCE_FUSED
    only_diff = cd[0] == fused[0] and cf[0] != fused[0] and cq[0] != fused[0]
    return fused, SOURCE_DIFF if only_diff else SOURCE_FORCE


def emit(
    block: ContactBlock,
    idx: np.ndarray,
    use: np.ndarray,
    cand: Intersection,
    source: int | np.ndarray,
    frames: list[SurfaceFrame],
) -> None:
    """Write the candidate's samples ``use`` (over ``idx``) into the block."""
    if not use.any():
        return
    pick = np.flatnonzero(use)
    at = idx[pick]
    block.located[at] = True
    block.surface[at] = cand.surface[pick]
    if len(frames) == 1 and frames[0].desk_xy:  # one horizontal board
        origin = frames[0].surface.origin
        block.x[at] = cand.uv[0][pick] + origin[0]
        block.y[at] = cand.uv[1][pick] + origin[1]
        block.z[at] = origin[2]
    else:
        x, y, z = cand.points(frames, pick)
        block.x[at] = x
        block.y[at] = y
        block.z[at] = z
    block.sigma_m[at] = np.sqrt(cand.var_uu[pick] + cand.var_vv[pick])
    block.source[at] = source if np.isscalar(source) else source[pick]  # type: ignore[index]


def emit_one(
    block: ContactBlock, chosen: Candidate, source: int, frames: list[SurfaceFrame]
) -> None:
    """:func:`emit` for a one-sample block."""
    index, u, v, var_u, var_v = chosen[:5]
    surface = frames[index].surface
    o, ua, va = surface.origin, surface.u_axis, surface.v_axis
    block.located[0] = True
    block.surface[0] = index
    block.x[0] = float(o[0] + u * ua[0] + v * va[0])
    block.y[0] = float(o[1] + u * ua[1] + v * va[1])
    block.z[0] = float(o[2] + u * ua[2] + v * va[2])
    block.sigma_m[0] = math.sqrt(var_u + var_v)
    block.source[0] = source


def emit_fused(
    block: ContactBlock, idx: np.ndarray, cands: list[Intersection], settings: EstimatorSettings
) -> None:
    """Inverse-covariance combination of the candidates that lie on the surface of the
    surest one (force, differentiated, fast; see :func:`fuse`)."""
    max_sigma, frames = settings.user.max_sigma_m, settings.frames
    first = cands[0]
    others = np.logical_or.reduce([c.valid for c in cands[1:]])
    # where the low-passed force's candidate is alone (most samples of a held press) it is
    # the result as it is; only the other samples are fused
    alone = first.valid & ~others
    sure = first.var_uu + first.var_vv <= max_sigma * max_sigma
    emit(block, idx, alone & sure, first, SOURCE_FORCE, frames)
    at = np.flatnonzero(others)
    if len(at) == 0:
        return
    some = [c.take(at) for c in cands]
    fused, members = fuse(some)
    use = fused.valid & (fused.sigma() <= max_sigma)
    # one candidate alone: say which (the differentiated one, or one from the force)
    only_diff = (members == 1) & some[1].valid & (some[1].surface == fused.surface)
    source = np.where(members > 1, SOURCE_FUSED, np.where(only_diff, SOURCE_DIFF, SOURCE_FORCE))
    emit(block, idx[at], use, fused, source.astype(np.int8), frames)
