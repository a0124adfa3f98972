"""Stage 5, the candidates: where each filtered wrench's line of action meets the desk.

P_er from the low-passed force and P_ed from the differentiated force (and, for ``fused``,
one from the fast wrench), each the intersection of its line of action with the surfaces
(paper eqs. 5, 12; :mod:`hapticdesk.estimator.geometry`), each with a covariance propagated
from the noise measured at the tare, plus the zero's drift since it was set and, for P_ed,
the term eq. (11) drops. :meth:`CandidateStage.process` works on the samples in contact of a
block; :meth:`CandidateStage.process_one` is the same for one sample on plain floats, with the
shared formulas (:func:`model_error_var`, :func:`motion_of`) written once for both.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from hapticdesk.estimator.geometry import (
    NO_CANDIDATE,
    VAR_CAP,
    Candidate,
    Intersection,
    intersect,
    intersect_one,
    pack_cov,
)
from hapticdesk.estimator.resolution import rounding_deficit
from hapticdesk.estimator.settings import EstimatorSettings

# `fused` leaves out a differentiated candidate this much less sure than the force's: it adds
# under 4 % of the information
DIFF_INFO_RATIO = 25.0


@dataclass(frozen=True)
class Covariances:
    """Per surface, the (3, 3) covariances of (F'z, M'x, M'y) of each filtered wrench, from the
    noise measured at the tare; ``packed`` the same as plain floats (single-sample path)."""

    lp: list[np.ndarray]
    diff: list[np.ndarray]
    det: list[np.ndarray]
    drift: list[np.ndarray]  # the zero's drift per second², growing as (age · rate)²
    packed: dict[str, list[tuple[float, float, float, float, float, float]]]

    @classmethod
    def of(
        cls, settings: EstimatorSettings, measured: np.ndarray, step: np.ndarray | None = None
    ) -> Covariances:
        """From the noise ``measured`` at the tare (6, 6) and the channels' resolution steps
        (6S,) learned so far (resolution.py; None or 0: none)."""
        s, m = settings.user, settings.wrench_map
        if s.noise_force_n > 0 or s.noise_moment_nm > 0:
            per_channel = np.where(settings.moment_channels, s.noise_moment_nm, s.noise_force_n)
            cov = m @ np.diag(per_channel**2) @ m.T
        else:
            cov = measured
        # the rounding of channels quieter than their step (resolution.py): in each reading
        # (in the noise), and slow (the zero's offset, and a reading's while it sits on one
        # step), which the force's low-pass passes whole. Not the slow part on the fast
        # wrench (`fused`'s first points): measured, it then put more edge taps in a wrong
        # button (16 against 9 of 1,000 at 0.1 N noise) and blurred the eight-legged desk's
        # steady presses; the difference cancels the offset
        slow = np.zeros((6, 6)) if step is None else rounding_deficit(m, step, cov)
        cov = cov + slow
        # a floor so that a perfectly noise-free input (simulation) still gives finite weights
        cov = cov + np.eye(6) * 1e-12
        rates = (
            np.where(settings.moment_channels, s.drift_moment_nm_per_min, s.drift_force_n_per_min)
            / 60.0
        )
        drift_cov = m @ np.diag(rates**2) @ m.T
        frames = settings.frames
        lp = [f.project_cov(cov * settings.gain_lp + 2.0 * slow) for f in frames]
        drift = [f.project_cov(drift_cov) for f in frames]
        diff = [f.project_cov(cov * settings.gain_diff) for f in frames]
        det = [f.project_cov(cov * settings.gain_det) for f in frames]
        named = (("lp", lp), ("diff", diff), ("det", det), ("drift", drift))
        packed = {name: [pack_cov(c) for c in covs] for name, covs in named}
        return cls(lp, diff, det, drift, packed)


def motion_of(rate: Any, where: Callable[..., Any] | None = None) -> Any:
    """The sign of the differentiated force magnitude (paper Fig. 3, step 2): +1 pressing,
    −1 releasing; arrays (with ``where=np.where``) or one float."""
    if where is None:
        return 1.0 if rate >= 0 else -1.0
    return where(rate >= 0, 1.0, -1.0)


def model_error_var(f_mag: Any, d_mag: Any, speed: float, maximum: Callable[..., Any]) -> Any:
    """The term F_e × Ṗ_e dropped in eq. (11), as a variance of P_ed: a finger drifting at
    ``speed`` (m/s); arrays (``maximum=np.maximum``) or plain floats (``maximum=max``)."""
    return (f_mag * speed / maximum(d_mag, 1e-9)) ** 2


@dataclass
class Candidates:
    """The candidates of the samples in contact of one block ((n,) arrays)."""

    force: Intersection | None  # P_er
    diff: Intersection | None  # P_ed
    fast: Intersection | None  # from the fast wrench (`fused`)
    f_mag: np.ndarray  # |F| after the conventional low-pass
    rate: np.ndarray | None  # the differentiated force along the fast force
    want_d: np.ndarray | None  # `switched`: where P_ed counts (paper Fig. 3, steps 3–4)


class CandidateStage:
    """The candidates for the located samples; stateless but for the covariances."""

    def __init__(self, settings: EstimatorSettings) -> None:
        self.settings = settings
        self.covs: Covariances | None = None  # set at the tare

    def process(
        self,
        wrench: np.ndarray,
        diff_at: np.ndarray,
        fast: np.ndarray | None,
        f_det_at: np.ndarray,
        inv_mag: np.ndarray,
        f_det_mag_at: np.ndarray,
        age2: np.ndarray,
    ) -> Candidates:
        """``wrench`` (6, n) tared low-passed, ``diff_at`` (3, n) packed differentiated,
        ``fast`` (6, n) tared fast wrench (``fused`` only), the fast force (3, n), 1/|F_fast|
        and |F_fast|, and the zero's age² (n,)."""
        s, covs = self.settings, self.covs
        assert covs is not None
        f_mag = np.sqrt(np.einsum("ik,ik->k", wrench[:3], wrench[:3]))
        method = "fused" if s.trace else s.method  # (trace: compute all three)
        cand_f = cand_d = cand_q = None
        rate = want_d = None
        if method in ("force", "switched", "fused"):
            cand_f = self._tared(wrench, covs.lp, age2, f_mag)
        if method in ("diff", "switched", "fused"):
            rate = np.einsum("ik,ik->k", f_det_at, diff_at.real) * inv_mag
            cand_d, want_d = self._diff(diff_at, rate, f_mag, cand_f)
        if method == "fused":  # the fast wrench: noisier, but it does not lag
            # (everywhere: it also stands in along a drawn stroke, where the zero's drift
            # makes both about as sure and the fast one does not lag behind the finger —
            # limiting it to where the force lags cost 3 points of stroke recognition)
            assert fast is not None
            cand_q = self._tared(fast, covs.det, age2, f_det_mag_at)
        return Candidates(cand_f, cand_d, cand_q, f_mag, rate, want_d)

    def _tared(
        self, wrench: np.ndarray, covs: list[np.ndarray], age2: np.ndarray, norm: np.ndarray
    ) -> Intersection:
        """A candidate from a tared (low-passed or fast) wrench: its noise, plus the drift of
        the zero since it was set (``age2``: that time, squared)."""
        assert self.covs is not None
        return intersect(
            self.settings.frames,
            wrench,
            1.0,
            covs,
            self.settings.user.min_normal_cos,
            drift_covs=self.covs.drift,
            drift_scale=age2,
            force_norm=norm,
        )

    def _diff(
        self,
        diff_at: np.ndarray,
        rate: np.ndarray,
        f_mag: np.ndarray,
        cand_f: Intersection | None,
    ) -> tuple[Intersection, np.ndarray | None]:
        """P_ed, and where it is wanted if not everywhere; computed only there."""
        s, user = self.settings, self.settings.user
        assert self.covs is not None
        n = len(rate)
        motion = motion_of(rate, np.where)
        d_force = diff_at.real
        want_d: np.ndarray | None = None
        d_at = np.arange(n)
        if s.method == "switched":
            # `switched` looks at P_ed only at small forces (paper Fig. 3, steps 3–4)
            assert cand_f is not None
            threshold = np.where(motion > 0, user.touch_threshold_n, user.release_threshold_n)
            want_d = (f_mag >= user.contact_force_n) & ((f_mag <= threshold) | ~cand_f.valid)
            if not s.trace:
                d_at = np.flatnonzero(want_d)
            d_force = np.take(d_force, d_at, axis=1)
            d_mag = np.sqrt(np.einsum("ik,ik->k", d_force, d_force))
            model = model_error_var(f_mag[d_at], d_mag, user.contact_speed_m_s, np.maximum)
        else:
            d_mag = np.sqrt(np.einsum("ik,ik->k", d_force, d_force))
            model = model_error_var(f_mag, d_mag, user.contact_speed_m_s, np.maximum)
            if s.method == "fused" and not s.trace:
                # the model term alone (added to both variances) makes most of P_ed far less
                # sure than P_er while a press is held: `fused` would leave those out
                # (DIFF_INFO_RATIO), so they are not computed at all
                assert cand_f is not None
                var_f = cand_f.var_uu + cand_f.var_vv
                want_d = ~cand_f.valid | (
                    2.0 * np.minimum(model, VAR_CAP) <= DIFF_INFO_RATIO * var_f
                )
                d_at = np.flatnonzero(want_d)
                d_mag, model = d_mag[d_at], model[d_at]
        cand_d = intersect(
            s.frames,
            unpacked_at(diff_at, d_at),
            motion[d_at],
            self.covs.diff,
            user.min_normal_cos,
            model,
            force_norm=d_mag,
        )
        if want_d is not None and not s.trace:
            cand_d = embed(cand_d, want_d)
        return cand_d, want_d

    def process_one(
        self,
        wrench: list[float],
        d_wrench: list[float],
        fast: list[float],
        inv: float,
        zero_age_s: float,
    ) -> tuple[Candidate, Candidate, Candidate, float, float]:
        """:meth:`process` for one sample on plain floats (not in trace mode): P_er, P_ed,
        the fast candidate (each :data:`NO_CANDIDATE` where the method does not need it),
        |F| and the motion."""
        s, user, covs = self.settings, self.settings.user, self.covs
        assert covs is not None
        fx, fy, fz = fast[:3]
        rate = (fx * d_wrench[0] + fy * d_wrench[1] + fz * d_wrench[2]) * inv
        motion = motion_of(rate)
        f_mag = math.sqrt(wrench[0] ** 2 + wrench[1] ** 2 + wrench[2] ** 2)
        cf = cd = cq = NO_CANDIDATE
        drift = covs.packed["drift"]
        if s.method != "diff":
            cf = intersect_one(
                s.frames, wrench, 1.0, covs.packed["lp"], user.min_normal_cos, 0.0, drift,
                zero_age_s**2,
            )  # fmt: skip
        if s.method != "force":
            d_mag = math.sqrt(d_wrench[0] ** 2 + d_wrench[1] ** 2 + d_wrench[2] ** 2)
            model = model_error_var(f_mag, d_mag, user.contact_speed_m_s, max)
            cd = intersect_one(
                s.frames, d_wrench, motion, covs.packed["diff"], user.min_normal_cos, model
            )
        if s.method == "fused":
            cq = intersect_one(
                s.frames, fast, 1.0, covs.packed["det"], user.min_normal_cos, 0.0, drift,
                zero_age_s**2,
            )  # fmt: skip
        return cf, cd, cq, f_mag, motion


def unpacked_at(packed: np.ndarray, at: np.ndarray) -> np.ndarray:
    """The wrench [F; M] (6, n) at the samples ``at`` of a packed one (3, k), F + 1j·M."""
    # np.take, not packed[:, at]: numpy's fancy indexing of a 2-D array is several times
    # slower than a take along one axis
    taken = np.take(packed, at, axis=1)
    out = np.empty((6, len(at)))
    out[:3] = taken.real
    out[3:] = taken.imag
    return out


def embed(part: Intersection, mask: np.ndarray) -> Intersection:
    """A candidate computed for the samples in ``mask``, as one for all (invalid elsewhere)."""
    n = len(mask)
    full = Intersection(
        np.zeros(n, bool),
        np.full(n, -1, np.int16),
        np.zeros((2, n)),
        np.full(n, VAR_CAP),
        np.full(n, VAR_CAP),
        np.zeros(n),
    )
    at = np.flatnonzero(mask)
    full.valid[at] = part.valid
    full.surface[at] = part.surface
    full.uv[0, at] = part.uv[0]  # row by row: 2-D fancy assignment is several times slower
    full.uv[1, at] = part.uv[1]
    full.var_uu[at] = part.var_uu
    full.var_vv[at] = part.var_vv
    full.cov_uv[at] = part.cov_uv
    return full
