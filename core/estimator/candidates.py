"""Stage 5, the candidates: where each filtered wrench's line of action meets the desk.

P_er from the low-passed force and P_ed from the differentiated force (and, for ``fused``,
one from the fast wrench), each the intersection of its line of action with the surfaces
(paper eqs. 5, 12; :mod:`hapticdesk.estimator.geometry`), each with a covariance propagated
from the noise measured at the tare, plus the zero's drift since it was set and, for P_ed,
the term eq. (11) drops (a finger drifting at ``contact_speed_m_s``). The zero's rounding
offset, which all of them share, is kept apart (``Covariances.rounding``): the kernel adds it
to the located point's 1-σ at the touch's force, after the method has chosen and weighed.

The per-sample work is ``_locate`` in :mod:`hapticdesk.estimator.kernel_methods`; here the
covariances it propagates are made, at the tare and again when a channel's resolution step
is learned (:class:`Covariances`), and packed into the kernel's state.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from hapticdesk.estimator.geometry import pack_cov
from hapticdesk.estimator.kernel_slots import (
    ROUND_ACTIVE,
    ROUND_SURFACE,
    ROUND_TABLE,
    ROUND_TABLE_N,
    ROUND_WHOLE,
)
from hapticdesk.estimator.resolution import (
    moved_share,
    rounding_deficit,
    zero_rounding_channels,
    zero_rounding_noise,
)
from hapticdesk.estimator.settings import EstimatorSettings


@dataclass(frozen=True)
class Covariances:
    """Per surface, the (3, 3) covariances of (F'z, M'x, M'y) of each filtered wrench, from the
    noise measured at the tare."""

    lp: list[np.ndarray]
    diff: list[np.ndarray]
    det: list[np.ndarray]
    drift: list[np.ndarray]  # the zero's drift per second², growing as (age · rate)²
    # the zero's rounding offset (resolution.zero_rounding): shared by every candidate and
    # every sample until the next tare, so not in the fusion's weights but added to the
    # located point's (a floor growing as 1/F that no averaging lowers); per surface where
    # every channel moves under the press, its bound
    rounding: list[np.ndarray]
    # the same per channel (C,), the noise in steps it was made with (C,), and the wrench's
    # least-norm spread over the channels (C, 6): how much each channel moves under a press,
    # so one it does not move keeps none (resolution.moved_share; kernel_rounding.py)
    rounding_channels: np.ndarray
    rounding_noise: np.ndarray
    spread: np.ndarray
    # per surface and channel (n_surfaces, C, 5): the channel's offset through the map into
    # (F'z, M'x, M'y) of the surface, g, as var·(gz², gz·gx, gz·gy, gx², gy²)
    # (settings.floor_terms): the terms of the located point's floor (kernel_rounding.py)
    rounding_terms: np.ndarray

    @classmethod
    def of(
        cls,
        settings: EstimatorSettings,
        measured: np.ndarray,
        step: np.ndarray | None = None,
        rest_var: np.ndarray | None = None,
        rest_n: int = 0,
    ) -> Covariances:
        """From the noise ``measured`` at the tare (6, 6), the channels' resolution steps
        (C,) learned so far (resolution.py; None or 0: none) and their variance at rest (C,;
        None: not measured, no rounding offset)."""
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
        per_channel = noise = np.zeros(m.shape[1])
        if step is not None and rest_var is not None:
            noise = zero_rounding_noise(step, rest_var, rest_n)
            per_channel = zero_rounding_channels(step, rest_var, rest_n, noise)
        offset = m @ (m.T * per_channel[:, None])
        rounding = [f.project_cov(offset) for f in frames]
        terms = settings.floor_terms * per_channel[:, None]
        return cls(
            lp, diff, det, drift, rounding, per_channel, noise, settings.channel_spread, terms
        )

    def packed(self) -> np.ndarray:
        """(n_surfaces, 4, 6): per surface its lp, diff, det and drift covariances, each as
        :func:`~hapticdesk.estimator.geometry.pack_cov` (the kernel's COV_* order)."""
        per_surface = zip(self.lp, self.diff, self.det, self.drift, strict=True)
        return np.array([[pack_cov(c) for c in covs] for covs in per_surface]).reshape(-1, 4, 6)

    def packed_rounding(self, step: np.ndarray) -> np.ndarray:
        """The kernel's I_SO_ROUND (``ROUND_*`` in kernel_slots.py) for the resolution steps
        ``step`` (C,) the offsets were made with: how many channels keep an offset, no sums
        kept yet, the share a press keeps over a change of 0 to ½ step (moved_share at the
        quiet channels' one noise, zero_rounding_noise), each channel's spread in steps (0
        where it keeps nothing) and the terms per surface and channel."""
        keeps = (self.rounding_channels > 0) & (step > 0)
        rho = float(self.rounding_noise[keeps].max()) if keeps.any() else 0.0
        table = _share_table(rho)
        spread = np.where(keeps[:, None], self.spread / np.where(keeps, step, 1.0)[:, None], 0.0)
        head = np.zeros(ROUND_TABLE)
        head[ROUND_ACTIVE], head[ROUND_SURFACE] = np.count_nonzero(keeps), -1.0
        head[ROUND_WHOLE] = np.argmax(table >= table[-1])
        norms = np.sqrt(np.sum(spread**2, axis=1))
        # (the wrench that moves a channel by one table point at most)
        reach = np.where(keeps, 1.0 / (2 * ROUND_TABLE_N * np.where(keeps, norms, 1.0)), 0.0)
        return np.concatenate([head, table, spread.ravel(), reach, self.rounding_terms.ravel()])


@functools.cache
def _share_table(rho: float) -> np.ndarray:
    """moved_share over a change of 0 to ½ step at ROUND_TABLE_N + 1 points, under a noise
    of ``rho`` steps (one of zero_rounding_noise's grid: made once a process for each)."""
    return moved_share(np.linspace(0.0, 0.5, ROUND_TABLE_N + 1), 1.0, rho)
