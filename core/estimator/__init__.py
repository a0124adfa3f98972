"""The contact estimator: sensor wrenches in, contact samples out (paper §2–3, Fig. 3).

One pass per block, the same code for a single sample or a million (``push``), so streaming
and batch give the same output for any split of the input:

1. Bad samples (NaN/inf, a saturated channel, time not increasing) are flagged and replaced
   by the last good sample, so no filter state is poisoned; a gap in time restarts the
   filters.
2. The 6·S channels become the resultant wrench [F_o; M_o] about P_o by one linear map
   (paper eqs. 1–4; :meth:`DeskProfile.wrench_map`).
3. Filters on that wrench: the conventional second-order low-pass; the pseudo-differentiated
   wrench (paper eq. 8: an n-sample difference, then the low-pass); and a fast (30 Hz)
   low-pass for touch-down/release detection that does not wait for the position filters.
4. Zero: an automatic tare over the first ``tare_s`` of a quiet desk (refused with a warning
   and retried while the desk is not quiet); the zero then follows sensor drift whenever the
   idle desk rests for ``drift_settle_s``, and a load held perfectly still for ``settle_s``
   (an object put down) becomes part of it, with a notice.
5. Candidates: P_er from the force and P_ed from the differentiated force (and, for
   ``fused``, one from the fast wrench), each the intersection of its line of action with the
   surfaces (paper eqs. 5, 12; :mod:`hapticdesk.estimator.geometry`), each with a covariance
   propagated from the noise measured at the tare, plus the zero's drift since it was set
   and, for P_ed, the term eq. (11) drops.
6. Method: ``force`` (the conventional), ``diff``, ``switched`` (paper Fig. 3 with F_tth,
   F_rth) or ``fused`` (inverse-covariance combination of the candidates, no threshold; a
   point is reported when its 1-σ is below ``max_sigma_m``).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, replace

import numpy as np

from hapticdesk.estimator.contacts import (
    FLAG_GAP,
    FLAG_NAN,
    FLAG_NOT_TARED,
    FLAG_SATURATED,
    FLAG_TIME_BACK,
    PHASE_HOLD,
    PHASE_RELEASE,
    PHASE_TOUCH,
    SOURCE_DIFF,
    SOURCE_FORCE,
    SOURCE_FUSED,
    UNCERTAINTY_CAP_M,
    ContactBlock,
)
from hapticdesk.estimator.filters import (
    DelayLine,
    SosFilter,
    butter_lowpass_sos,
    group_delay_s,
    noise_gain,
    pack_pairs,
)
from hapticdesk.estimator.geometry import (
    VAR_CAP,
    Intersection,
    SurfaceFrame,
    intersect,
    intersect_one,
    pack_cov,
)
from hapticdesk.files.profile import METHODS, DeskProfile, EstimationSettings
from hapticdesk.files.recording import Recording

log = logging.getLogger("hapticdesk.estimator")

BAD_SAMPLE = FLAG_NAN | FLAG_SATURATED | FLAG_TIME_BACK  # replaced by the last good sample

WINDOW_S = 0.2  # tare and stillness are judged on windows of this length
DET_FLOOR = 1e-12  # a 2×2 covariance is inverted as if its determinant were at least this share
# of the product of its variances (never singular, whatever the scale)
DIFF_INFO_RATIO = 25.0  # `fused` leaves out a differentiated candidate this much less sure
RATE_WINDOW_S = 0.05  # slope of the fast force for the touch/hold/release phase
# samples per piece of a long push: small enough that a piece's working arrays stay in the
# CPU caches between the stages (measured best between 8k and 32k here)
BATCH_CHUNK = 16384
UNRATED_LIMIT = 1e12  # a channel without a rating counts as saturated beyond this


@dataclass(frozen=True)
class CandidateTrace:
    """Both candidates for the samples in contact of one push (``trace=True``).

    ``force_n``: |F_o| after the conventional low-pass; ``rate_n_s``: the differentiated force
    magnitude (paper Fig. 3, its sign is the motion); points (3, n) in the desk frame with
    their validity and 1-σ uncertainty: P_er from the force, P_ed from its derivative.
    """

    t: np.ndarray
    force_n: np.ndarray
    rate_n_s: np.ndarray
    force_point: np.ndarray
    force_valid: np.ndarray
    force_sigma_m: np.ndarray
    diff_point: np.ndarray
    diff_valid: np.ndarray
    diff_sigma_m: np.ndarray
    fast_point: np.ndarray  # from the fast (detection) low-pass: the third `fused` candidate
    fast_valid: np.ndarray
    fast_sigma_m: np.ndarray

    @classmethod
    def concat(cls, traces: list[CandidateTrace]) -> CandidateTrace:
        """Join the traces of several pushes."""
        names = [f for f in cls.__dataclass_fields__]
        if not traces:
            z = np.zeros(0)
            none = np.zeros((3, 0))
            return cls(
                z, z, z, none, z.astype(bool), z, none, z.astype(bool), z, none, z.astype(bool), z
            )
        return cls(**{n: np.concatenate([getattr(tr, n) for tr in traces], axis=-1) for n in names})


@dataclass(frozen=True)
class Notice:
    """Something the estimator did on its own that a user should know about."""

    t: float
    kind: str  # tare, tare_refused, absorbed, drift, gap
    message: str


class ContactEstimator:
    """Streaming contact estimator for one desk. See the module docstring for the stages.

    ``push(t, wrench)`` takes k samples (k ≥ 0): ``t`` (k,) seconds, ``wrench`` (k, S, 6) in
    each sensor's own frame, and returns a :class:`ContactBlock` for exactly those samples.
    """

    def __init__(
        self,
        profile: DeskProfile,
        method: str | None = None,
        settings: EstimationSettings | None = None,
        trace: bool = False,
    ) -> None:
        """``trace``: also keep both candidates of every sample in contact in :attr:`traces`
        (for research: the paper's D_er and D_ed, threshold derivation, plots)."""
        settings = settings or profile.estimation
        self.trace = trace
        self.traces: list[CandidateTrace] = []
        if method is not None:
            if method not in METHODS:
                raise ValueError(f"method must be one of {', '.join(METHODS)}, found {method!r}")
            settings = replace(settings, method=method)
        self.profile = profile
        self.settings = s = settings
        self.method = s.method
        fs = profile.sample_rate_hz
        self.sample_rate_hz = fs
        self._map = np.ascontiguousarray(profile.wrench_map())  # (6, 6S)
        limits = profile.saturation_limits()
        if limits is None:
            limits = np.full((len(profile.sensors), 6), np.inf)
        # an unrated channel counts as rated at UNRATED_LIMIT, so that no finite reading
        # can overflow the resultant wrench (and put infinity into the filters)
        limits = np.where(np.isfinite(limits), limits, UNRATED_LIMIT)
        self._range_flat = limits.reshape(-1)  # (6S,)
        self._inv_range2 = 1.0 / self._range_flat**2
        self._squares = np.empty((4096, len(self._range_flat)))  # see _in_range
        self._frames = [SurfaceFrame.of(surf) for surf in profile.surfaces]
        self._normals = (
            np.array([surf.normal for surf in profile.surfaces])
            if profile.surfaces
            else np.zeros((0, 3))
        )
        self._normals_list: list[list[float]] = self._normals.tolist()

        # filters (settings) — state is created from the first sample
        self._lp_sos = butter_lowpass_sos(s.force_lowpass_hz, fs)
        self._diff_sos = butter_lowpass_sos(s.diff_lowpass_hz, fs)
        self._det_sos = butter_lowpass_sos(min(s.detect_lowpass_hz, 0.45 * fs), fs)
        self._n_diff = max(1, round(s.diff_window_s * fs))
        self._diff_scale = 1.0 / (self._n_diff / fs)
        # A difference commutes with an LTI filter: when both low-passes are equal, the
        # differentiated wrench is the difference of the low-passed one (one filter, not two).
        self._shared_lp = bool(np.allclose(self._lp_sos, self._diff_sos))
        fir = np.zeros(self._n_diff + 1)
        fir[0], fir[-1] = self._diff_scale, -self._diff_scale
        long = int(8 * fs / min(s.force_lowpass_hz, s.diff_lowpass_hz)) + self._n_diff
        self._gain_lp = noise_gain(self._lp_sos, length=long)
        self._gain_diff = noise_gain(self._diff_sos, fir, length=long)
        self._gain_det = noise_gain(self._det_sos, length=long)
        #: how far the located points run behind a moving finger: the force low-pass's
        #: delay (the gesture engine carries a swipe's end on by it)
        self.position_delay_s = group_delay_s(self._lp_sos, fs, long)

        # the touch phase follows the fast force's slope over a short window
        self._n_rate = max(1, round(RATE_WINDOW_S * fs))
        self._rate_scale = fs / self._n_rate
        self._window = max(1, round(WINDOW_S * fs))
        self._n_tare = max(1, math.ceil(s.tare_s / (self._window / fs) - 1e-9))
        self._n_settle = max(1, math.ceil(s.settle_s / (self._window / fs) - 1e-9))
        self._n_drift = max(1, math.ceil(s.drift_settle_s / (self._window / fs) - 1e-9))
        self.notices: list[Notice] = []
        self.reset()

    # --- state --------------------------------------------------------------------------------

    def reset(self) -> None:
        """Forget everything: filters, zero and contact state (a new run)."""
        # Wrenches are filtered packed, force + 1j·moment (filters.pack_pairs): three
        # complex lanes cost about what three real ones do.
        self._lp = SosFilter(self._lp_sos, 3)
        self._diff_lp = None if self._shared_lp else SosFilter(self._diff_sos, 3)
        self._delay = DelayLine(self._n_diff, 3)
        # the fast wrench: the force for detection (real); the whole wrench (packed) for
        # `fused`'s third candidate
        self._det_full = self.method == "fused" or self.trace
        self._det = SosFilter(self._det_sos, 3)
        self._det_delay = DelayLine(self._n_rate, 3)
        self._last_good: np.ndarray | None = None  # raw wrench (6,)
        self._last_t = -math.inf
        self._in_contact = False
        self._zero: np.ndarray | None = None
        self._noise_cov: np.ndarray | None = None
        self._covs_lp: list[np.ndarray] | None = None  # per surface, see project_cov
        self._covs_diff: list[np.ndarray] | None = None
        self._covs_drift: list[np.ndarray] | None = None
        self._covs_det: list[np.ndarray] | None = None
        self._packed: dict[str, list[tuple[float, float, float, float, float, float]]] = {}
        self._win_lp = np.zeros((3, self._window))  # the current, unfinished window
        self._win_raw = np.zeros((6, self._window))
        self._win_bad = np.zeros(self._window, bool)
        self._win_fill = 0
        self._zero_t = 0.0  # when the zero was last set, for the drift since then
        self._zero_segment: tuple[np.ndarray, np.ndarray] = (
            np.zeros(1, int),
            np.full((7, 1), np.nan),
        )
        self._last_window_t = float("nan")
        self._zero_list: list[float] = []
        self._tare_raw: list[np.ndarray] = []
        self._tare_means: list[list[float]] = []
        self._windows_seen = 0
        self._still_run = 0
        self._still_lo: list[float] = [0.0, 0.0, 0.0]
        self._still_hi: list[float] = [0.0, 0.0, 0.0]
        self._still_means: list[list[float]] = []

    @property
    def tared(self) -> bool:
        return self._zero is not None

    @property
    def zero(self) -> np.ndarray | None:
        """The current zero of [F_o; M_o] (6,), or None before the tare."""
        return None if self._zero is None else self._zero.copy()

    # --- the pass -----------------------------------------------------------------------------

    def push(self, t: np.ndarray, wrench: np.ndarray) -> ContactBlock:
        """Estimate contacts for k more samples. See the class docstring."""
        t = np.asarray(t, dtype=float).reshape(-1)
        wrench = np.asarray(wrench, dtype=float)
        n_sensors = len(self.profile.sensors)
        if wrench.shape != (len(t), n_sensors, 6):
            raise ValueError(
                f"wrench must have shape (k, S, 6) = ({len(t)}, {n_sensors}, 6) for desk "
                f"{self.profile.name!r}, found {wrench.shape}"
            )
        k = len(t)
        if k == 0:
            return ContactBlock.empty()
        if k == 1:
            one = self._push_one(float(t[0]), wrench)
            if one is not None:
                return one
        block = ContactBlock.blank(t)
        noticed = len(self.notices)
        # a long block goes through in pieces: the same output (streaming equals batch), but
        # each piece's arrays stay in the CPU caches between the stages
        for a in range(0, k, BATCH_CHUNK):
            piece = slice(a, a + BATCH_CHUNK)
            self._push(t[piece], wrench[piece], block.take(piece) if k > BATCH_CHUNK else block)
        if len(self.notices) - noticed > 1:  # in time order, however the stages found them
            self.notices[noticed:] = sorted(self.notices[noticed:], key=lambda n: n.t)
        return block

    def _push_one(self, t: float, wrench: np.ndarray) -> ContactBlock | None:
        """One sample on the common path, with plain floats where numpy's per-call cost would
        dominate: the same stages as :meth:`_push`, kept equal to it by the single-sample
        tests. None where the sample needs the general path: before the tare, in trace mode,
        with a separate low-pass for the differentiated force, for a bad sample (NaN,
        saturated, time not increasing, a gap) and where a zero window ends."""
        s = self.settings
        if (
            self.trace
            or self._zero is None
            or self._last_good is None
            or self._diff_lp is not None
            or self._win_fill + 1 >= self._window  # a zero window ends here
            or not (0.0 < t - self._last_t <= s.max_gap_s)
        ):
            return None
        flat = wrench.reshape(-1)
        with np.errstate(over="ignore", invalid="ignore"):
            if not float(np.square(flat) @ self._inv_range2) < 1.0:  # see _in_range
                return None
        self._last_t = t
        raw = self._map @ flat  # (6,): paper eqs. (1)–(4)
        self._last_good = raw
        # filters (see _filter_segment), on (3, 1) lanes
        packed = (raw[:3] + 1j * raw[3:])[:, None]
        det = self._det.process(packed if self._det_full else raw[:3, None])
        f_det_raw = det.real[:, 0] if self._det_full else det[:, 0]
        det_slope = (self._det_delay.step(f_det_raw) * self._rate_scale).tolist()
        lp = self._lp.process(packed, in_place=True)[:, 0]
        diff = (self._delay.step(lp) * self._diff_scale).tolist()
        # zero window (see _update_zero): only remembered, the window does not end here
        m = self._win_fill
        lp_force = lp.real
        self._win_lp[:, m] = lp_force
        self._win_raw[:, m] = raw
        self._win_bad[m] = False
        self._win_fill = m + 1
        self._last_window_t = t
        # contacts (see _contacts)
        z = self._zero_list
        lp_l = lp.tolist()
        wrench6 = [lp_l[i].real - z[i] for i in range(3)] + [
            lp_l[i].imag - z[i + 3] for i in range(3)
        ]
        det_l = det[:, 0].tolist()
        if self._det_full:
            fast = [det_l[i].real - z[i] for i in range(3)] + [
                det_l[i].imag - z[i + 3] for i in range(3)
            ]
        else:
            fast = [det_l[i] - z[i] for i in range(3)]
        fx, fy, fz = fast[:3]
        mag = math.sqrt(fx * fx + fy * fy + fz * fz)
        normals = self._normals_list
        if normals:
            along = max(n[0] * fx + n[1] * fy + n[2] * fz for n in normals)
            pressing = along >= s.min_normal_cos * mag
        else:
            pressing = False
        above = pressing and mag >= s.contact_force_n
        below = not pressing or mag < s.contact_force_n - s.release_hysteresis_n
        in_contact = above or (self._in_contact and not below)
        self._in_contact = in_contact
        block = _single_block(t, in_contact, mag)
        if in_contact:
            d6 = [d.real for d in diff] + [d.imag for d in diff]
            self._locate_one(block, wrench6, d6, fast, det_slope, t - self._zero_t)
        return block

    def _push(self, t: np.ndarray, wrench: np.ndarray, block: ContactBlock) -> None:
        """The stages for one block, written into ``block`` (blank, see ContactBlock.blank)."""
        flags, raw = self._clean(t, wrench)
        block.flags[:] = flags
        lp, det, diff, det_slope = self._filter(t, raw, flags)
        zero_starts, zeros = self._update_zero(t, lp.real, raw, flags)
        self._contacts(block, t, flags, lp, det, diff, det_slope, zero_starts, zeros)

    def _clean(self, t: np.ndarray, wrench: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Flag bad samples and hold the last good wrench over them. Returns flags, raw (6, k)."""
        k = len(t)
        flags = np.zeros(k, np.uint8)
        flat = wrench.reshape(k, -1)
        clean = self._in_range(flat)
        previous = self._last_t if self._last_t > -math.inf else t[0] - 1.0 / self.sample_rate_hz
        steps = np.empty(k)  # time steps; NaN where a time is NaN
        steps[0] = t[0] - previous
        steps[1:] = t[1:] - t[:-1]
        if clean and steps.min() > 0:  # the common case: finite, in range, time increasing
            gap = steps > self.settings.max_gap_s
            if self._last_t == -math.inf:
                gap[0] = False  # the very first sample follows nothing
            if gap.any():
                flags[gap] = FLAG_GAP
            self._last_t = float(t[-1])
            with np.errstate(invalid="ignore", over="ignore"):
                raw = self._map @ flat.T  # (6, k): paper eqs. (1)–(4) as one linear map
            self._last_good = raw[:, -1].copy()
            return flags, raw
        return self._clean_slowly(t, flat, flags)

    def _in_range(self, flat: np.ndarray) -> bool:
        """Σ (channel / rating)² < 1 for every sample: proves no channel is saturated and all
        are finite. A fast first pass: only blocks where it fails are checked channel by
        channel. In pieces small enough that the squares stay in the CPU cache."""
        squares = self._squares
        for a in range(0, len(flat), len(squares)):
            piece = flat[a : a + len(squares)]
            sq = squares[: len(piece)]
            with np.errstate(over="ignore", invalid="ignore"):  # (NaN, overflow: not in range)
                np.square(piece, out=sq)
                if not (sq @ self._inv_range2).max() < 1.0:
                    return False
        return True

    def _clean_slowly(
        self, t: np.ndarray, flat: np.ndarray, flags: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """The checks sample by sample (vectorised) for a block with something wrong in it."""
        k = len(t)
        finite = np.isfinite(flat).all(axis=1) & np.isfinite(t)
        flags[~finite] |= FLAG_NAN
        with np.errstate(invalid="ignore"):
            sat = (np.abs(flat) >= self._range_flat).any(axis=1)
        flags[finite & sat] |= FLAG_SATURATED
        # time must increase: compare with the running maximum of earlier good times
        t_clean = np.where(finite, t, -np.inf)
        prev_max = np.maximum.accumulate(np.concatenate([[self._last_t], t_clean]))[:-1]
        flags[finite & (t <= prev_max)] |= FLAG_TIME_BACK
        good = flags == 0
        if good.any():
            good_t = t[good]
            before = np.concatenate([[self._last_t], good_t[:-1]])
            gap = (good_t - before) > self.settings.max_gap_s
            if self._last_t == -math.inf:
                gap[0] = False
            flags[np.flatnonzero(good)[gap]] |= FLAG_GAP
            self._last_t = float(good_t[-1])
        with np.errstate(invalid="ignore", over="ignore"):  # bad rows are replaced below
            raw = self._map @ flat.T
        index = np.where(good, np.arange(k), -1)
        np.maximum.accumulate(index, out=index)
        held = index >= 0
        raw = np.where(held, raw[:, np.maximum(index, 0)], 0.0)
        if self._last_good is not None:
            raw[:, ~held] = self._last_good[:, None]
        elif good.any():  # bad samples before the first good one ever: back-fill it
            raw[:, ~held] = raw[:, np.flatnonzero(good)[0]][:, None]
        if good.any():
            self._last_good = raw[:, np.flatnonzero(good)[-1]].copy()
        return flags, np.ascontiguousarray(raw)

    def _filter(
        self, t: np.ndarray, raw: np.ndarray, flags: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Low-passed wrench, fast force (or wrench), differentiated wrench, fast force slope;
        wrenches packed (3, k) complex, force + 1j·moment. The filters restart after a gap."""
        if self._last_good is None:  # nothing good seen yet: nothing to filter
            z = np.zeros((3, raw.shape[1]), complex)
            det = z.copy() if self._det_full else np.zeros((3, raw.shape[1]))
            return z, det, z.copy(), np.zeros((3, raw.shape[1]))
        gaps = flags & FLAG_GAP
        if not gaps.any():
            return self._filter_segment(raw)
        starts = np.flatnonzero(gaps).tolist()
        bounds = [0, *starts, raw.shape[1]]
        parts = []
        for a, b in zip(bounds[:-1], bounds[1:], strict=True):
            if b <= a:
                continue
            if a in starts:
                self._restart_filters(raw[:, a])
                self._notice(
                    float(t[a]), "gap", "gap in sample times: filters restarted", logging.WARNING
                )
            parts.append(self._filter_segment(raw[:, a:b]))
        lp, det, diff, slope = (np.concatenate(p, axis=1) for p in zip(*parts, strict=True))
        return lp, det, diff, slope

    def _restart_filters(self, x0: np.ndarray) -> None:
        """Every filter as if ``x0`` had been the input forever (after a gap)."""
        packed = x0[:3] + 1j * x0[3:]
        self._lp.restart(packed)
        self._det.restart(packed if self._det_full else x0[:3])
        self._det_delay.restart(x0[:3])
        self._delay.restart(packed)
        if self._diff_lp is not None:
            self._diff_lp.restart(np.zeros(3, complex))

    def _filter_segment(
        self, raw: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        packed = pack_pairs(raw)  # force + 1j·moment
        det = self._det.process(packed if self._det_full else raw[:3])
        det_slope = self._det_delay.difference(det.real if self._det_full else det)
        det_slope *= self._rate_scale
        if self._diff_lp is None:
            lp = self._lp.process(packed, in_place=True)
            diff = self._delay.difference(lp)  # paper eq. (8)
            diff *= self._diff_scale
        else:
            if self._diff_lp.zi is None:
                self._diff_lp.restart(np.zeros(3, complex))
            raw_diff = self._delay.difference(packed)
            raw_diff *= self._diff_scale
            diff = self._diff_lp.process(raw_diff, in_place=True)
            lp = self._lp.process(packed, in_place=True)
        return lp, det, diff, det_slope

    # --- zero: tare, drift and objects ----------------------------------------------------------

    def _update_zero(
        self, t: np.ndarray, lp_force: np.ndarray, raw: np.ndarray, flags: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """The zero in force for each sample, as segments.

        Returns ``starts`` (n,) sample indices where a zero takes effect and ``zeros`` (6, n)
        (NaN before the tare). The zero decided at the end of a window applies from the next
        sample on, whatever the block boundaries, so streaming equals batch.
        """
        w = self._window
        m = self._win_fill
        k = len(t)
        bad = (flags & (BAD_SAMPLE | FLAG_GAP)) != 0
        if m + k < w:  # the block ends inside the current window: only remember it
            self._win_lp[:, m : m + k] = lp_force
            self._win_raw[:, m : m + k] = raw
            self._win_bad[m : m + k] = bad
            self._win_fill = m + k
            self._last_window_t = float(t[-1])
            return self._zero_segment
        if m:
            all_lp = np.concatenate([self._win_lp[:, :m], lp_force], axis=1)
            all_raw = np.concatenate([self._win_raw[:, :m], raw], axis=1)
            all_bad = np.concatenate([self._win_bad[:m], bad])
        else:  # windows start with the block: no copies
            all_lp, all_raw, all_bad = lp_force, raw, bad
        n_full = all_lp.shape[1] // w
        starts = [0]
        zeros = [self._zero_or_nan()]
        if n_full:
            cut = n_full * w
            lp_w = all_lp[:, :cut].reshape(3, n_full, w)
            spread: list[float] = (lp_w.max(axis=2) - lp_w.min(axis=2)).max(axis=0).tolist()
            means = all_raw[:, :cut].reshape(6, n_full, w).mean(axis=2)
            # a window is unusable for the zero when more than a tenth of it was held over
            bad_share = all_bad[:cut].reshape(n_full, w).mean(axis=1)
            any_bad = (bad_share > 0.1).tolist()
            ends = np.arange(1, n_full + 1) * w - 1 - m  # block index of each window's end
            t_end = np.where(ends >= 0, t[np.maximum(ends, 0)], self._last_window_t).tolist()
            mean_rows = means.T.tolist()
            # Once tared, a window that is not still only ends a still run: the loop (over
            # 0.2 s windows, not samples) visits the still ones and notes the breaks.
            still = [
                not b and sp < self.settings.still_n for b, sp in zip(any_bad, spread, strict=True)
            ]
            previous = -1
            for j in range(n_full):
                if self._zero is not None and not still[j]:
                    continue
                if self._zero is not None and j != previous + 1:
                    self._still_run = 0  # windows in between were not still
                previous = j
                before = self._zero
                self._window_done(
                    spread[j], any_bad[j], mean_rows[j], all_raw[:, j * w : (j + 1) * w], t_end[j]
                )
                if self._zero is not before:
                    starts.append(int(ends[j]) + 1)
                    zeros.append(self._zero_or_nan())
            if previous != n_full - 1:
                self._still_run = 0  # the block ended on windows that were not still
            rest = all_lp.shape[1] - cut
            self._win_lp[:, :rest] = all_lp[:, cut:]
            self._win_raw[:, :rest] = all_raw[:, cut:]
            self._win_bad[:rest] = all_bad[cut:]
            self._win_fill = rest
        self._last_window_t = float(t[-1])
        return np.array(starts), np.array(zeros).T

    def _zero_or_nan(self) -> list[float]:
        """The zero (6,) and the time it was set, as one column; NaN before the tare."""
        if self._zero is None:
            return [math.nan] * 7
        return [*self._zero_list, self._zero_t]

    def _window_done(
        self, spread: float, bad: bool, mean: list[float], raw: np.ndarray, t_end: float
    ) -> None:
        """Advance the tare / stillness state machine by one window (plain floats: it is hot)."""
        s = self.settings
        self._windows_seen += 1
        if self._zero is None:
            self._tare_window(spread, bad, mean, raw, t_end)
            return
        if bad or spread >= s.still_n:  # (only before the tare: see _update_zero)
            self._still_run = 0
            return
        z = self._zero_list
        f = (mean[0] - z[0], mean[1] - z[1], mean[2] - z[2])
        if self._still_run:
            lo = [min(a, b) for a, b in zip(self._still_lo, f, strict=True)]
            hi = [max(a, b) for a, b in zip(self._still_hi, f, strict=True)]
            if max(b - a for a, b in zip(lo, hi, strict=True)) >= s.still_n:
                self._still_run = 0  # the load moved: a new still run starts here
        if self._still_run == 0:
            lo, hi = list(f), list(f)
            self._still_means = []
        self._still_lo, self._still_hi = lo, hi
        self._still_run += 1
        self._still_means.append(mean)
        load = math.sqrt(f[0] ** 2 + f[1] ** 2 + f[2] ** 2)
        if load < s.drift_max_n and s.drift_settle_s > 0:
            # an idle, still desk: what is left is sensor drift; follow it (often, so a
            # drifting zero never builds up between touches)
            if self._still_run >= self._n_drift:
                recent = self._still_means[-self._n_drift :]
                columns = zip(*recent, strict=True)
                self._set_zero([math.fsum(c) / len(recent) for c in columns], t_end)
                self._still_run = 0
                log.debug("t=%.3f s: zero drift of %.3f N followed", t_end, load)
            return
        if self._still_run % self._n_settle:
            return
        self._set_zero(mean, t_end)
        self._still_run = 0
        if load >= s.contact_force_n:
            up = self._up()
            sign = "put on" if f[0] * up[0] + f[1] * up[1] + f[2] * up[2] >= 0 else "taken off"
            self._notice(
                t_end,
                "absorbed",
                f"a still load of {load:.1f} N (an object {sign} the desk?) held for "
                f"{s.settle_s:g} s became part of the zero",
            )
        else:
            self._notice(t_end, "drift", f"a still load of {load:.2f} N became part of the zero")

    def _tare_window(
        self, spread: float, bad: bool, mean: list[float], raw: np.ndarray, t_end: float
    ) -> None:
        s = self.settings
        if not bad and spread < s.tare_quiet_n:
            self._tare_raw.append(raw)
            self._tare_means.append(mean[:3])
            if len(self._tare_raw) > self._n_tare:
                self._tare_raw.pop(0)
                self._tare_means.pop(0)
            if np.ptp(np.array(self._tare_means), axis=0).max() >= s.tare_quiet_n:
                # each window was quiet, but the load moved between them: start again here
                self._tare_raw, self._tare_means = [raw], [mean[:3]]
        else:
            self._tare_raw, self._tare_means = [], []
        if len(self._tare_raw) >= self._n_tare:
            samples = np.concatenate(self._tare_raw, axis=1)
            self._set_zero(samples.mean(axis=1), t_end)
            self._set_noise(np.cov(samples))
            self._tare_raw, self._tare_means = [], []
            self._notice(t_end, "tare", f"tared over {s.tare_s:g} s of a quiet desk")
        elif self._windows_seen % self._n_tare == 0:
            self._notice(
                t_end,
                "tare_refused",
                f"tare refused: the desk was not quiet in the {s.tare_s:g} s before "
                f"t = {t_end:.2f} s (is someone touching or leaning on it?); retrying",
                logging.WARNING,
            )

    def _up(self) -> np.ndarray:
        return self._normals[0] if len(self._normals) else np.array([0.0, 0.0, 1.0])

    def _set_zero(self, zero: np.ndarray | list[float], t: float) -> None:
        self._zero_list = [float(z) for z in zero]
        self._zero = np.array(self._zero_list)
        self._zero_t = t
        self._zero_segment = (np.zeros(1, int), np.array(self._zero_or_nan())[:, None])

    def _set_noise(self, measured: np.ndarray) -> None:
        s = self.settings
        if s.noise_force_n > 0 or s.noise_moment_nm > 0:
            per_channel = np.tile(
                [s.noise_force_n] * 3 + [s.noise_moment_nm] * 3, len(self.profile.sensors)
            )
            cov = self._map @ np.diag(per_channel**2) @ self._map.T
        else:
            cov = np.atleast_2d(measured)
        # a floor so that a perfectly noise-free input (simulation) still gives finite weights
        cov = cov + np.eye(6) * 1e-12
        self._noise_cov = cov
        self._covs_lp = [f.project_cov(cov * self._gain_lp) for f in self._frames]
        # the zero drifts after it is set: its covariance grows as (age · rate)²
        rates = np.tile(
            [s.drift_force_n_per_min / 60.0] * 3 + [s.drift_moment_nm_per_min / 60.0] * 3,
            len(self.profile.sensors),
        )
        drift_cov = self._map @ np.diag(rates**2) @ self._map.T
        self._covs_drift = [f.project_cov(drift_cov) for f in self._frames]
        self._covs_diff = [f.project_cov(cov * self._gain_diff) for f in self._frames]
        self._covs_det = [f.project_cov(cov * self._gain_det) for f in self._frames]
        # the same, packed as plain floats for the single-sample path
        self._packed = {
            name: [pack_cov(c) for c in covs]
            for name, covs in (
                ("lp", self._covs_lp),
                ("diff", self._covs_diff),
                ("det", self._covs_det),
                ("drift", self._covs_drift),
            )
        }

    def _notice(self, t: float, kind: str, message: str, level: int = logging.INFO) -> None:
        self.notices.append(Notice(t, kind, message))
        log.log(level, "t=%.3f s: %s", t, message)

    # --- contacts -------------------------------------------------------------------------------

    def _contacts(
        self,
        block: ContactBlock,
        t: np.ndarray,
        flags: np.ndarray,
        lp: np.ndarray,
        det: np.ndarray,
        diff: np.ndarray,
        det_slope: np.ndarray,
        zero_starts: np.ndarray,
        zeros: np.ndarray,
    ) -> None:
        s = self.settings
        k = len(t)
        tared_zero = ~np.isnan(zeros[0])
        if not tared_zero.any():
            block.flags |= FLAG_NOT_TARED
            return
        # the zero is piecewise constant: subtract it segment by segment, in place
        ends = [*zero_starts[1:].tolist(), k]
        # (wrenches packed: force + 1j·moment, see _filter)
        fast = det.copy()  # the fast wrench (or force), tared
        packed_zeros = zeros[:3] + 1j * zeros[3:6]
        fast_zeros = packed_zeros if self._det_full else zeros[:3]
        tared = np.ones(k, bool)
        wrench_all = lp  # tared in place below: the low-passed wrench is not needed untared
        age = np.empty(k)  # time since the zero in force was set
        for a, b, j in zip(zero_starts.tolist(), ends, range(len(ends)), strict=True):
            if tared_zero[j]:
                fast[:, a:b] -= fast_zeros[:, j : j + 1]
                wrench_all[:, a:b] -= packed_zeros[:, j : j + 1]
                age[a:b] = t[a:b] - zeros[6, j]
            else:
                tared[a:b] = False
                age[a:b] = 0.0
        f_det = fast.real if self._det_full else fast
        block.flags[~tared] |= FLAG_NOT_TARED
        f_det_mag = np.sqrt(np.einsum("ik,ik->k", f_det, f_det))
        all_tared = bool(tared.all())
        if all_tared:
            block.force_n[:] = f_det_mag
        else:
            np.copyto(block.force_n, f_det_mag, where=tared)

        # fast path: touch-down at contact_force_n, release below it less the hysteresis,
        # and only for a force that presses into a surface (a lifted object pulls)
        if len(self._normals) == 1:
            pressing = self._normals[0] @ f_det >= s.min_normal_cos * f_det_mag
        elif len(self._normals):
            pressing = (self._normals @ f_det).max(axis=0) >= s.min_normal_cos * f_det_mag
        else:
            pressing = np.zeros(k, bool)
        above = pressing & (f_det_mag >= s.contact_force_n)
        below = ~pressing | (f_det_mag < s.contact_force_n - s.release_hysteresis_n)
        if not all_tared:
            above &= tared
            below |= ~tared
        block.in_contact[:] = _hysteresis(above, below, self._in_contact)
        self._in_contact = bool(block.in_contact[-1])
        # candidates only for good samples in contact (a bad one keeps the contact state
        # but has no position of its own); they are the costly part
        if k == 1 and not self.trace:  # one sample: plain floats beat numpy's per-call cost
            if not block.in_contact[0] or flags[0] & BAD_SAMPLE:
                return
            self._locate_one(
                block,
                _unpacked_at(wrench_all, 0).tolist(),
                _unpacked_at(diff, 0).tolist(),
                (_unpacked_at(fast, 0) if self._det_full else fast[:, 0]).tolist(),
                det_slope[:, 0].tolist(),
                float(age[0]),
            )
            return
        idx = np.flatnonzero(block.in_contact & ((flags & BAD_SAMPLE) == 0))
        if len(idx) == 0:
            return
        n = len(idx)
        wrench = _unpacked_at(wrench_all, idx)
        age2 = age[idx] ** 2

        # the phase from the fast path's slope, which does not wait for the 166 ms window
        f_det_at = np.take(f_det, idx, axis=1)
        f_det_mag_at = f_det_mag[idx]
        inv_mag = 1.0 / np.where(f_det_mag_at > 0, f_det_mag_at, 1.0)
        slope = np.einsum("ik,ik->k", f_det_at, np.take(det_slope, idx, axis=1)) * inv_mag
        phase = np.full(len(idx), PHASE_HOLD, np.int8)
        phase[slope > s.phase_rate_n_s] = PHASE_TOUCH
        phase[slope < -s.phase_rate_n_s] = PHASE_RELEASE
        block.phase[idx] = phase

        f_mag = np.sqrt(np.einsum("ik,ik->k", wrench[:3], wrench[:3]))
        method = self.method
        if self.trace:
            method = "fused"  # compute both candidates
        cand_f = cand_d = None
        if method in ("force", "switched", "fused"):
            cand_f = self._tared_candidate(wrench, self._covs_lp, age2, f_mag)
        if method in ("diff", "switched", "fused"):
            # motion: the sign of the differentiated force magnitude (paper Fig. 3, step 2)
            diff_at = np.take(diff, idx, axis=1)  # packed
            d_force = diff_at.real
            rate = np.einsum("ik,ik->k", f_det_at, d_force) * inv_mag
            motion = np.where(rate >= 0, 1.0, -1.0)
            want_d: np.ndarray | None = None  # where P_ed is needed, if not everywhere
            if self.method == "switched":
                # `switched` looks at P_ed only at small forces (paper Fig. 3, steps 3–4)
                assert cand_f is not None
                threshold = np.where(motion > 0, s.touch_threshold_n, s.release_threshold_n)
                want_d = (f_mag >= s.contact_force_n) & ((f_mag <= threshold) | ~cand_f.valid)
                d_at = np.flatnonzero(want_d) if not self.trace else np.arange(n)
                d_force = np.take(d_force, d_at, axis=1)
                d_mag = np.sqrt(np.einsum("ik,ik->k", d_force, d_force))
                # the term F_e × Ṗ_e dropped in eq. (11): a finger drifting at contact_speed_m_s
                model = (f_mag[d_at] * s.contact_speed_m_s / np.maximum(d_mag, 1e-9)) ** 2
            else:
                d_mag = np.sqrt(np.einsum("ik,ik->k", d_force, d_force))
                model = (f_mag * s.contact_speed_m_s / np.maximum(d_mag, 1e-9)) ** 2
                d_at = np.arange(n)
                if self.method == "fused" and not self.trace:
                    # the model term alone (added to both variances) makes most of P_ed far
                    # less sure than P_er while a press is held: `fused` would leave those out
                    # (DIFF_INFO_RATIO, below), so they are not computed at all
                    assert cand_f is not None
                    var_f = cand_f.var_uu + cand_f.var_vv
                    want_d = ~cand_f.valid | (
                        2.0 * np.minimum(model, VAR_CAP) <= DIFF_INFO_RATIO * var_f
                    )
                    d_at = np.flatnonzero(want_d)
                    d_mag, model = d_mag[d_at], model[d_at]
            cand_d = intersect(
                self._frames,
                _unpacked_at(diff_at, d_at),
                motion[d_at],
                self._covs_diff,
                s.min_normal_cos,
                model,
                force_norm=d_mag,
            )
            if want_d is not None and not self.trace:
                cand_d = _embed(cand_d, want_d)

        cand_q = None
        if method == "fused":  # the fast wrench: noisier, but it does not lag
            # (everywhere: it also stands in along a drawn stroke, where the zero's drift
            # makes both about as sure and the fast one does not lag behind the finger —
            # limiting it to where the force lags cost 3 points of stroke recognition)
            cand_q = self._tared_candidate(
                _unpacked_at(fast, idx), self._covs_det, age2, f_det_mag_at
            )
        if self.trace:
            assert cand_f is not None and cand_d is not None and cand_q is not None
            self.traces.append(
                CandidateTrace(
                    t=t[idx],
                    force_n=f_mag,
                    rate_n_s=rate,
                    force_point=cand_f.points(self._frames),
                    force_valid=cand_f.valid.copy(),
                    force_sigma_m=cand_f.sigma(),
                    diff_point=cand_d.points(self._frames),
                    diff_valid=cand_d.valid.copy(),  # (`fused` narrows them below)
                    diff_sigma_m=cand_d.sigma(),
                    fast_point=cand_q.points(self._frames),
                    fast_valid=cand_q.valid.copy(),
                    fast_sigma_m=cand_q.sigma(),
                )
            )
            method = self.method
        if method == "force":
            assert cand_f is not None
            self._emit(
                block, idx, cand_f.valid & (f_mag >= s.contact_force_n), cand_f, SOURCE_FORCE
            )
        elif method == "diff":
            assert cand_d is not None
            self._emit(
                block, idx, cand_d.valid & (cand_d.sigma() <= s.max_sigma_m), cand_d, SOURCE_DIFF
            )
        elif method == "switched":
            assert cand_f is not None and cand_d is not None
            gate = f_mag >= s.contact_force_n  # paper Fig. 3, step 4
            use_d = cand_d.valid & want_d  # step 3, see above
            self._emit(block, idx, gate & cand_f.valid & ~use_d, cand_f, SOURCE_FORCE)
            self._emit(block, idx, use_d, cand_d, SOURCE_DIFF)
        else:
            assert cand_f is not None and cand_d is not None and cand_q is not None
            # the fast and the low-passed candidates share their noise (one filtered from the
            # other's input), so they are not fused: the fast one stands in where it is the
            # surer (the low-passed force has not caught up yet, or has already let go)
            cand_q.valid &= ~cand_f.valid | (
                cand_q.var_uu + cand_q.var_vv < cand_f.var_uu + cand_f.var_vv
            )
            # a differentiated candidate 5 times less sure than the force's adds under 4 %
            # of the information: leave it out (and the combination to the few that matter)
            var_f = cand_f.var_uu + cand_f.var_vv
            cand_d.valid &= ~cand_f.valid | (
                cand_d.var_uu + cand_d.var_vv <= DIFF_INFO_RATIO * var_f
            )
            self._emit_fused(block, idx, [cand_f, cand_d, cand_q])
        return

    def _tared_candidate(
        self,
        wrench: np.ndarray,
        covs: list[np.ndarray] | None,
        age2: np.ndarray,
        force_norm: np.ndarray | None = None,
    ) -> Intersection:
        """A candidate from a tared (low-passed or fast) wrench: its noise, plus the drift of
        the zero since it was set (``age2``: that time, squared)."""
        return intersect(
            self._frames,
            wrench,
            1.0,
            covs,
            self.settings.min_normal_cos,
            drift_covs=self._covs_drift,
            drift_scale=age2,
            force_norm=force_norm,
        )

    def _locate_one(
        self,
        block: ContactBlock,
        wrench: list[float],
        d_wrench: list[float],
        fast: list[float],
        det_slope: list[float],
        zero_age_s: float,
    ) -> None:
        """The candidate stage of :meth:`_contacts` for one sample, on plain floats: the
        tared wrench, the differentiated one, the fast force (or wrench, for `fused`) and its
        slope.

        Kept equal to the vectorised stage by the single-sample tests."""
        s = self.settings
        fx, fy, fz = fast[:3]
        mag = math.sqrt(fx * fx + fy * fy + fz * fz)
        inv = 1.0 / mag if mag > 0 else 1.0
        rate = (fx * d_wrench[0] + fy * d_wrench[1] + fz * d_wrench[2]) * inv
        motion = 1.0 if rate >= 0 else -1.0
        sx, sy, sz = det_slope
        slope = (fx * sx + fy * sy + fz * sz) * inv
        block.phase[0] = (
            PHASE_TOUCH
            if slope > s.phase_rate_n_s
            else PHASE_RELEASE
            if slope < -s.phase_rate_n_s
            else PHASE_HOLD
        )
        f_mag = math.sqrt(wrench[0] ** 2 + wrench[1] ** 2 + wrench[2] ** 2)
        method = self.method
        cf = cd = (-1, 0.0, 0.0, VAR_CAP, VAR_CAP, 0.0)
        if method != "diff":
            cf = intersect_one(
                self._frames,
                wrench,
                1.0,
                self._packed["lp"],
                s.min_normal_cos,
                drift_covs=self._packed["drift"],
                drift_scale=zero_age_s**2,
            )
        if method != "force":
            d_mag = math.sqrt(d_wrench[0] ** 2 + d_wrench[1] ** 2 + d_wrench[2] ** 2)
            model = (f_mag * s.contact_speed_m_s / max(d_mag, 1e-9)) ** 2
            cd = intersect_one(
                self._frames, d_wrench, motion, self._packed["diff"], s.min_normal_cos, model
            )
        sig_d = math.sqrt(cd[3] + cd[4])
        f_ok, d_ok = cf[0] >= 0, cd[0] >= 0
        chosen, source = None, 0
        if method == "force":
            if f_ok and f_mag >= s.contact_force_n:
                chosen, source = cf, SOURCE_FORCE
        elif method == "diff":
            if d_ok and sig_d <= s.max_sigma_m:
                chosen, source = cd, SOURCE_DIFF
        elif method == "switched":
            if f_mag >= s.contact_force_n:
                threshold = s.touch_threshold_n if motion > 0 else s.release_threshold_n
                if d_ok and (f_mag <= threshold or not f_ok):
                    chosen, source = cd, SOURCE_DIFF
                elif f_ok:
                    chosen, source = cf, SOURCE_FORCE
        else:
            cq = intersect_one(
                self._frames,
                fast,
                1.0,
                self._packed["det"],
                s.min_normal_cos,
                drift_covs=self._packed["drift"],
                drift_scale=zero_age_s**2,
            )
            if cf[0] >= 0 and cq[0] >= 0 and not (cq[3] + cq[4] < cf[3] + cf[4]):
                cq = (-1, 0.0, 0.0, VAR_CAP, VAR_CAP, 0.0)  # see the vectorised stage
            if cf[0] >= 0 and cd[0] >= 0 and cd[3] + cd[4] > DIFF_INFO_RATIO * (cf[3] + cf[4]):
                cd = (-1, 0.0, 0.0, VAR_CAP, VAR_CAP, 0.0)  # see the vectorised stage
            fused, members = _fuse_one([cf, cd, cq])
            if fused[0] >= 0 and math.sqrt(fused[3] + fused[4]) <= s.max_sigma_m:
                chosen = fused
                if members > 1:
                    source = SOURCE_FUSED
                else:
                    source = (
                        SOURCE_DIFF
                        if cd[0] == fused[0] and cf[0] != fused[0] and (cq[0] != fused[0])
                        else SOURCE_FORCE
                    )
        if chosen is None:
            return
        index, u, v, var_u, var_v = chosen[:5]
        surface = self._frames[index].surface
        o, ua, va = surface.origin, surface.u_axis, surface.v_axis
        px = float(o[0] + u * ua[0] + v * va[0])
        py = float(o[1] + u * ua[1] + v * va[1])
        pz = float(o[2] + u * ua[2] + v * va[2])
        block.located[0] = True
        block.surface[0] = index
        block.x[0], block.y[0], block.z[0] = px, py, pz
        block.sigma_m[0] = math.sqrt(var_u + var_v)
        block.source[0] = source

    def _emit(
        self,
        block: ContactBlock,
        idx: np.ndarray,
        use: np.ndarray,
        cand: Intersection,
        source: int | np.ndarray,
    ) -> None:
        """Write the candidate's samples ``use`` (over ``idx``) into the block."""
        if not use.any():
            return
        pick = np.flatnonzero(use)
        at = idx[pick]
        block.located[at] = True
        block.surface[at] = cand.surface[pick]
        if len(self._frames) == 1 and self._frames[0].desk_xy:  # one horizontal board
            origin = self._frames[0].surface.origin
            block.x[at] = cand.uv[0][pick] + origin[0]
            block.y[at] = cand.uv[1][pick] + origin[1]
            block.z[at] = origin[2]
        else:
            x, y, z = cand.points(self._frames, pick)
            block.x[at] = x
            block.y[at] = y
            block.z[at] = z
        block.sigma_m[at] = np.sqrt(cand.var_uu[pick] + cand.var_vv[pick])
        block.source[at] = source if np.isscalar(source) else source[pick]  # type: ignore[index]

    def _emit_fused(self, block: ContactBlock, idx: np.ndarray, cands: list[Intersection]) -> None:
        """Inverse-covariance combination of the candidates that lie on the surface of the
        surest one (force, differentiated, fast; see :func:`_fuse`)."""
        max_sigma = self.settings.max_sigma_m
        first = cands[0]
        others = np.logical_or.reduce([c.valid for c in cands[1:]])
        # where the low-passed force's candidate is alone (most samples of a held press) it
        # is the result as it is; only the other samples are fused
        alone = first.valid & ~others
        sure = first.var_uu + first.var_vv <= max_sigma * max_sigma
        self._emit(block, idx, alone & sure, first, SOURCE_FORCE)
        at = np.flatnonzero(others)
        if len(at) == 0:
            return
        some = [c.take(at) for c in cands]
        fused, members = _fuse(some)
        use = fused.valid & (fused.sigma() <= max_sigma)
        # one candidate alone: say which (the differentiated one, or one from the force)
        only_diff = (members == 1) & some[1].valid & (some[1].surface == fused.surface)
        source = np.where(members > 1, SOURCE_FUSED, np.where(only_diff, SOURCE_DIFF, SOURCE_FORCE))
        self._emit(block, idx[at], use, fused, source.astype(np.int8))


Candidate = tuple[int, float, float, float, float, float]  # surface, u, v, var_u, var_v, cov


def _fuse_one(cands: list[Candidate]) -> tuple[Candidate, int]:
    """:func:`_fuse` for one sample on plain floats."""
    valid = [c for c in cands if c[0] >= 0]
    if not valid:
        return (-1, 0.0, 0.0, VAR_CAP, VAR_CAP, 0.0), 0
    surest = min(valid, key=lambda c: math.sqrt(c[3] + c[4]))
    a = b = c_ = ru = rv = 0.0
    members = 0
    for cand in valid:
        if cand[0] != surest[0]:
            continue
        det = max(cand[3] * cand[4] - cand[5] * cand[5], DET_FLOOR * cand[3] * cand[4], 1e-300)
        ia, ib, ic = cand[4] / det, -cand[5] / det, cand[3] / det
        a, b, c_ = a + ia, b + ib, c_ + ic
        ru += ia * cand[1] + ib * cand[2]
        rv += ib * cand[1] + ic * cand[2]
        members += 1
    det = max(a * c_ - b * b, DET_FLOOR * a * c_, 1e-300)
    fused = (
        surest[0],
        (c_ * ru - b * rv) / det,
        (a * rv - b * ru) / det,
        min(c_ / det, VAR_CAP),
        min(a / det, VAR_CAP),
        -b / det,
    )
    return fused, members


def _single_block(t: float, in_contact: bool, force_n: float) -> ContactBlock:
    """A one-sample block, not yet located."""
    return ContactBlock(
        t=np.array([t]),
        in_contact=np.array([in_contact]),
        located=np.zeros(1, bool),
        surface=np.full(1, -1, np.int16),
        x=np.zeros(1),
        y=np.zeros(1),
        z=np.zeros(1),
        force_n=np.array([force_n]),
        source=np.zeros(1, np.int8),
        phase=np.zeros(1, np.int8),
        sigma_m=np.full(1, UNCERTAINTY_CAP_M),
        flags=np.zeros(1, np.uint8),
    )


def _unpacked_at(packed: np.ndarray, at: np.ndarray | int) -> np.ndarray:
    """The wrench [F; M] (6, n) at the samples ``at`` of a packed one (3, k), F + 1j·M;
    (6,) for one sample."""
    if isinstance(at, int):
        return np.concatenate([packed[:, at].real, packed[:, at].imag])
    # np.take, not packed[:, at]: numpy's fancy indexing of a 2-D array is several times
    # slower than a take along one axis
    taken = np.take(packed, at, axis=1)
    out = np.empty((6, len(at)))
    out[:3] = taken.real
    out[3:] = taken.imag
    return out


def _embed(part: Intersection, mask: np.ndarray) -> Intersection:
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


def _fuse(cands: list[Intersection]) -> tuple[Intersection, np.ndarray]:
    """p = (Σ Σ_i⁻¹)⁻¹ Σ Σ_i⁻¹ p_i over the valid candidates on the surface of the surest one,
    per sample, 2×2 in closed form. Returns the fused candidate and how many were fused.
    (:func:`_fuse_one` is the same for one sample.)"""
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
        # the information Σ_i⁻¹ = [[ia, ib], [ib, ic]]; zero for a candidate not taken
        product = cand.var_uu * cand.var_vv
        det = np.maximum(product - cand.cov_uv * cand.cov_uv, DET_FLOOR * product)
        weight = take / np.maximum(det, 1e-300)
        ia, ib, ic = cand.var_vv * weight, -cand.cov_uv * weight, cand.var_uu * weight
        cu, cv = cand.uv
        a, b, c_ = a + ia, b + ib, c_ + ic
        ru = ru + ia * cu + ib * cv
        rv = rv + ib * cu + ic * cv
    inv_det = 1.0 / np.maximum(np.maximum(a * c_ - b * b, DET_FLOOR * a * c_), 1e-300)
    uv = np.stack([(c_ * ru - b * rv) * inv_det, (a * rv - b * ru) * inv_det])
    none = ~valid
    uv[:, none] = 0.0
    return Intersection(
        valid,
        surface,
        uv,
        np.where(valid, np.minimum(c_ * inv_det, VAR_CAP), VAR_CAP),
        np.where(valid, np.minimum(a * inv_det, VAR_CAP), VAR_CAP),
        np.where(valid, -b * inv_det, 0.0),
    ), members


def _hysteresis(on: np.ndarray, off: np.ndarray, state: bool) -> np.ndarray:
    """Vectorised two-threshold switch: set where ``on``, cleared where ``off``, else held."""
    k = len(on)
    if k == 1:
        return np.array([bool(on[0]) or (state and not off[0])])
    decided = np.flatnonzero(on | off)
    if len(decided) == 0:
        return np.full(k, state)
    value = on[decided]  # what each decided sample sets
    before = np.empty(len(value), bool)
    before[0] = state
    before[1:] = value[:-1]
    flips = np.flatnonzero(value != before)  # the decided samples that change the state
    # runs of a constant state between the flips, written out with one np.repeat
    bounds = np.concatenate(([0], decided[flips], [k]))
    values = np.concatenate(([state], value[flips]))
    return np.repeat(values, np.diff(bounds))


def estimate(profile: DeskProfile, recording: Recording, method: str | None = None) -> ContactBlock:
    """Batch estimation of a whole recording (identical to streaming it in any blocks)."""
    if recording.sensor_names != profile.sensor_names:
        raise ValueError(
            f"the recording's sensors {recording.sensor_names} are not the desk's "
            f"{profile.sensor_names}"
        )
    return ContactEstimator(profile, method=method).push(recording.t, recording.wrench)
