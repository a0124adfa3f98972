"""Stage 2, the filters on the resultant wrench, restarted after a gap.

The conventional second-order low-pass; the pseudo-differentiated wrench (paper eq. 8: an
n-sample difference, then the low-pass); and a fast (30 Hz) low-pass for touch-down and
release detection, with its slope over a short window (the touch phase) and over a shorter
one (the release prediction, :mod:`.detector`), both from one history of the fast force.
Wrenches are filtered packed, force + 1j·moment (:func:`filters.pack_pairs`): three complex
lanes cost about what three real ones do.
"""

from __future__ import annotations

import logging
from typing import Any

import numpy as np

from hapticdesk.estimator.contacts import FLAG_GAP
from hapticdesk.estimator.filters import DelayLine, SosFilter, pack_pairs
from hapticdesk.estimator.notices import Notice, add_notice
from hapticdesk.estimator.settings import EstimatorSettings
from hapticdesk.estimator.sway import SwayStage

Filtered = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]


class FilterState:
    """The filters' memories (SOS states and delay rings), made from the first sample."""

    def __init__(self, settings: EstimatorSettings) -> None:
        self.lp = SosFilter(settings.lp_sos, 3)
        self.diff_lp = None if settings.shared_lp else SosFilter(settings.diff_sos, 3)
        self.delay = DelayLine(settings.n_diff, 3)
        # the fast wrench: the force for detection (real); the whole wrench (packed) for
        # `fused`'s third candidate
        self.det = SosFilter(settings.det_sos, 3)
        self.det_delay = DelayLine(settings.n_rate, 3)
        # stage 2b: the sway's inertial wrench, on the low-passed wrench (and on the separately
        # low-passed differentiated one, which the correction commutes with)
        sway = settings.sway
        self.sway = None if sway is None else SwayStage(sway)
        self.sway_diff = None if sway is None or settings.shared_lp else SwayStage(sway)


class FilterBank:
    """Low-passed wrench, fast force (or wrench), differentiated wrench and the fast slope."""

    def __init__(self, settings: EstimatorSettings, notices: list[Notice]) -> None:
        self.settings = settings
        self.notices = notices
        self.state = FilterState(settings)

    def process(self, t: np.ndarray, raw: np.ndarray, flags: np.ndarray, started: bool) -> Filtered:
        """``lp``, ``det``, ``diff``, ``det_slope``, ``release_slope`` for the wrench ``raw``
        (6, k): wrenches packed (3, k) complex, force + 1j·moment (``det`` real (3, k) unless
        ``det_full``); the slopes (3, k) of the fast force over ``n_rate`` and
        ``n_release`` samples. ``started``: a good sample has been seen (before it, nothing
        is filtered)."""
        if not started:
            z = np.zeros((3, raw.shape[1]), complex)
            det = z.copy() if self.settings.det_full else np.zeros((3, raw.shape[1]))
            return z, det, z.copy(), np.zeros((3, raw.shape[1])), np.zeros((3, raw.shape[1]))
        gaps = flags & FLAG_GAP
        if not gaps.any():
            return self._segment(raw)
        starts = np.flatnonzero(gaps).tolist()
        bounds = [0, *starts, raw.shape[1]]
        parts = []
        for a, b in zip(bounds[:-1], bounds[1:], strict=True):
            if b <= a:
                continue
            if a in starts:
                self.restart(raw[:, a])
                add_notice(
                    self.notices,
                    float(t[a]),
                    "gap",
                    "gap in sample times: filters restarted",
                    logging.WARNING,
                )
            parts.append(self._segment(raw[:, a:b]))
        lp, det, diff, slope, release = (
            np.concatenate(p, axis=1) for p in zip(*parts, strict=True)
        )
        return lp, det, diff, slope, release

    def process_one(
        self, raw: list[float]
    ) -> tuple[list[complex], list[Any], list[complex], list[float], list[float]]:
        """:meth:`process` for one sample (6,) with a shared low-pass, on plain numbers (the
        filters' :meth:`~SosFilter.step`): ``lp`` (3,) packed, ``det`` (3,) (packed if
        ``det_full``), ``diff`` (3,) packed and both slopes."""
        st, s = self.state, self.settings
        packed = [raw[0] + 1j * raw[3], raw[1] + 1j * raw[4], raw[2] + 1j * raw[5]]
        det = st.det.step(packed if s.det_full else raw[:3])
        det_f = [d.real for d in det] if s.det_full else det
        slope, release = st.det_delay.step_one(det_f, s.n_release)
        rate, rel = s.rate_scale, s.release_scale
        lp = st.lp.step(packed)
        if st.sway is not None:
            lp = st.sway.process_one(lp)
        diff, _ = st.delay.step_one(lp)  # paper eq. (8)
        scale = s.diff_scale
        return (
            lp,
            det,
            [d * scale for d in diff],
            [v * rate for v in slope],
            [v * rel for v in release],
        )

    def restart(self, x0: np.ndarray) -> None:
        """Every filter as if ``x0`` had been the input forever (after a gap)."""
        st = self.state
        packed = x0[:3] + 1j * x0[3:]
        st.lp.restart(packed)
        st.det.restart(packed if self.settings.det_full else x0[:3])
        st.det_delay.restart(x0[:3])
        st.delay.restart(packed)
        if st.diff_lp is not None:
            st.diff_lp.restart(np.zeros(3, complex))
        if st.sway is not None:
            st.sway.restart(packed)
        if st.sway_diff is not None:
            st.sway_diff.restart(np.zeros(3, complex))

    def _segment(self, raw: np.ndarray) -> Filtered:
        """The filters over a stretch without a gap."""
        st, s = self.state, self.settings
        packed = pack_pairs(raw)  # force + 1j·moment
        det = st.det.process(packed if s.det_full else raw[:3])
        det_f = det.real if s.det_full else det
        if st.det_delay.ring is None:
            st.det_delay.restart(det_f[:, 0])
        release = st.det_delay.recent_difference(det_f, s.n_release)  # before the history moves
        release *= s.release_scale
        det_slope = st.det_delay.difference(det_f)
        det_slope *= s.rate_scale
        if st.diff_lp is None:
            lp = st.lp.process(packed, in_place=True)
            if st.sway is not None:
                st.sway.process(lp)
            diff = st.delay.difference(lp)  # paper eq. (8)
            diff *= s.diff_scale
        else:
            if st.diff_lp.zi is None:
                st.diff_lp.restart(np.zeros(3, complex))
            raw_diff = st.delay.difference(packed)
            raw_diff *= s.diff_scale
            diff = st.diff_lp.process(raw_diff, in_place=True)
            lp = st.lp.process(packed, in_place=True)
            if st.sway is not None and st.sway_diff is not None:
                st.sway.process(lp)
                st.sway_diff.process(diff)
        return lp, det, diff, det_slope, release
