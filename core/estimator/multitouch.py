"""A second finger: detected from the change of wrench when it lands while the first holds.

One resultant force gives one point: two fingers pressing straight down are, to the sensors,
one finger at their centre of pressure (a vertical force's wrench has no free moment, so the
residual of the single-point model cannot tell them apart). What does tell: when the second
finger lands while the first holds, the *change* of the wrench over the landing is itself the
wrench of a single point force, the second finger's (the differentiated wrench, paper eqs.
8/12: ΔM = P₂ × ΔF). Located like any wrench (eqs. 1–2 on the surface's plane), it lies
centimetres away from where the first finger is; a finger pressing harder gives a change
located where it already is.

This is an analysis over a recording and the estimator's contacts (no per-sample loop);
:func:`mark_second_touches` sets ``FLAG_MULTI`` on the contact samples it finds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import sosfilt, sosfilt_zi

from hapticdesk.estimator.contacts import FLAG_MULTI, ContactBlock
from hapticdesk.estimator.filters import butter_lowpass_sos
from hapticdesk.estimator.geometry import SurfaceFrame
from hapticdesk.files.profile import DeskProfile

LOWPASS_HZ = 12.0  # the wrench is smoothed this much before differencing (noise vs lag)
LAG_S = 0.08  # the change of wrench is taken over this interval (a finger lands in ≈0.1 s)
LANDING_S = 0.25  # the second finger's landing is over by its force's peak within this
MIN_STEP_N = 2.0  # the force must rise at least this much over LAG_S ...
MIN_STEP_SHARE = 0.1  # ... and at least this share of the force before it
MIN_APART_M = 0.03  # the change located at least this far from the first finger
MAX_FIRST_MOVE_M = 0.005  # the first finger held this still over the lag before (no swipe)


@dataclass(frozen=True)
class SecondTouches:
    """Per sample of the contacts: a second finger on the desk, and where it landed."""

    multi: np.ndarray  # (k,) bool: from the second finger's landing to the contact's end
    x2: np.ndarray  # (k,) where the second finger landed (desk frame, m); 0 where not multi
    y2: np.ndarray
    z2: np.ndarray


def locate_change(
    d_wrench: np.ndarray, origin: np.ndarray, normal: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Where the line of action of each wrench (k, 6) [F; M] meets the plane (origin, normal):
    the point P with M = P × F on it (paper eqs. 1–2). Returns points (k, 3) and whether the
    force crosses the plane at all (not parallel to it)."""
    f, m = d_wrench[:, :3], d_wrench[:, 3:]
    f2 = np.einsum("ij,ij->i", f, f)
    ok = f2 > 0
    safe_f2 = np.where(ok, f2, 1.0)
    foot = np.cross(f, m) / safe_f2[:, None]  # the line's point closest to the moment centre
    across = f @ normal
    ok &= np.abs(across) > 1e-3 * np.sqrt(safe_f2)
    lam = ((origin - foot) @ normal) / np.where(ok, across, 1.0)
    return foot + lam[:, None] * f, ok


def second_touches(
    profile: DeskProfile, t: np.ndarray, readings: np.ndarray, block: ContactBlock
) -> SecondTouches:
    """Find second fingers in a recording (``readings`` (k, S, 6)) from its contacts ``block``
    (the estimator's output for the same samples)."""
    k = len(t)
    fs = profile.sample_rate_hz
    wrench = readings.reshape(k, -1) @ profile.wrench_map().T  # (k, 6) resultant
    wrench = np.nan_to_num(wrench)
    sos = butter_lowpass_sos(LOWPASS_HZ, fs)
    zi = sosfilt_zi(sos)[:, :, None] * wrench[0][None, None, :]
    smooth, _ = sosfilt(sos, wrench, axis=0, zi=zi)
    n = max(1, round(LAG_S * fs))
    landing_n = max(1, round(LANDING_S * fs))
    multi = np.zeros(k, bool)
    out = np.zeros((3, k))
    if k <= n or not profile.surfaces:
        return SecondTouches(multi, *out)
    surface = profile.surfaces[0]
    d_wrench = smooth[n:] - smooth[:-n]  # ΔW over the lag, ending at sample n..k-1
    before = np.arange(k - n)  # the sample where each change starts
    earlier = np.maximum(before - n, 0)  # the first finger held still since here
    now = before + n
    force_then = block.force_n[before]
    step = np.linalg.norm(d_wrench[:, :3], axis=1)
    rising = block.force_n[now] - force_then
    origin, normal = np.asarray(surface.origin), np.asarray(surface.normal)
    points, ok = locate_change(d_wrench, origin, normal)
    first = np.stack([block.x[before], block.y[before], block.z[before]], axis=1)
    apart = np.linalg.norm(points - first, axis=1)
    rel = points - surface.origin  # the second finger must be on the board
    on_board = SurfaceFrame.of(surface).contains(rel @ surface.u_axis, rel @ surface.v_axis)
    moved = np.hypot(block.x[before] - block.x[earlier], block.y[before] - block.y[earlier])
    landing = (
        ok
        & block.in_contact[before]
        & block.located[before]
        & block.located[earlier]
        & (moved <= MAX_FIRST_MOVE_M)
        & block.in_contact[now]
        & (rising >= MIN_STEP_N)
        & (step >= MIN_STEP_SHARE * force_then)
        & (apart >= MIN_APART_M)
        & on_board
    )
    if not landing.any():
        return SecondTouches(multi, *out)
    # contacts are runs of in_contact: a landing flags its contact from there to its end
    edges = np.diff(np.concatenate([[0], block.in_contact.astype(np.int8), [0]]))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    hits = now[landing]
    run = np.searchsorted(starts, hits, side="right") - 1
    first_hit = np.full(len(starts), k)
    np.minimum.at(first_hit, run, hits)
    for j in np.flatnonzero(first_hit < k):  # per flagged contact (few), not per sample
        a, b = first_hit[j], ends[j]
        multi[a:b] = True
        # the second finger: the steepest change of wrench over its landing (within
        # LANDING_S of its start). Exact only while the first finger holds perfectly still:
        # its own change mixes in (two vertical forces' wrenches fix just the line through
        # both fingers), and pulls the point towards it.
        span = d_wrench[a - n : min(b, a + landing_n) - n]
        change = span[int(np.argmax(np.linalg.norm(span[:, :3], axis=1)))]
        point, _ = locate_change(change[None, :], origin, normal)
        out[:, a:b] = point[0][:, None]
    return SecondTouches(multi, *out)


def mark_second_touches(
    profile: DeskProfile, t: np.ndarray, readings: np.ndarray, block: ContactBlock
) -> SecondTouches:
    """:func:`second_touches`, and ``FLAG_MULTI`` set on ``block``'s samples (in place)."""
    found = second_touches(profile, t, readings, block)
    block.flags[found.multi] |= FLAG_MULTI
    return found
