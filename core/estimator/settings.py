"""The estimator's settings: everything fixed for one desk, derived once from its profile.

The user's :class:`EstimationSettings` (thresholds, cut-offs, durations) become what the
stages compute with: the channels→wrench matrix, the channels' limits, the surfaces prepared
for intersection, the filters' second-order sections and noise gains, window lengths in
samples. Frozen, apart from every stage's state (STYLE.md 7, 13); flattened once into the
kernel's parameter arrays by :mod:`hapticdesk.estimator.params`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from hapticdesk.estimator.filters import (
    butter_lowpass_sos,
    group_delay_s,
    impulse_response,
    noise_gain,
)
from hapticdesk.estimator.geometry import SurfaceFrame
from hapticdesk.estimator.sway import SwaySettings
from hapticdesk.files.profile import DeskProfile, EstimationSettings

WINDOW_S = 0.2  # tare and stillness are judged on windows of this length
RATE_WINDOW_S = 0.05  # slope of the fast force for the touch/hold/release phase
# slope of the fast force for the release prediction: shorter, so a tap's quick fall is not
# averaged with its hold (its noise, ≈ 3 N/s here, is still far below the
# 10 N/s of release_slope_n_s)
RELEASE_WINDOW_S = 0.02
# With the sway compensated (stage 2b), a window's spread is taken of means over about this
# long: the correction, a second derivative, adds broadband noise up to ~150 Hz at about
# (force low-pass / sway frequency)² of the channels' own (the idle paper desk's window
# spread 0.03 N -> 0.09 N), and at twice the paper's noise no window stayed under `still_n`,
# so the drift was never followed. A 20 ms mean keeps the load's own motion (below the 4.8 Hz
# low-pass, and the 6 Hz sway that is left: 98 %) and drops most of that noise.
SWAY_STILL_MEAN_S = 0.02
UNRATED_LIMIT = 1e12  # a channel without a rating counts as saturated beyond this
# A reading that jumps from a calm wrench is held (kernel_channels.held_over): a corrupt
# reading (an HX711's odd garbage word, a bit error on a line) made a tap nobody made (+50 N on
# one channel at idle, the paper's desk). Held are jumps of which the fast low-pass passes at
# least this share of the contact threshold: smaller ones cannot start a contact.
JUMP_SHARE = 0.5
# ... for up to this long (at least one sample) while it stays away: two corrupt readings in a
# row, held for one sample only, made the same tap (+50 and +100 N on the paper desk's F_z).
# A real change lasts: the sample after the hold is taken whatever it is, so a real step lands
# this late (3 samples at 1.2 kHz, 2 at 1 kHz, 1 at 500 Hz and below) and nothing else changes.
JUMP_HOLD_S = 0.0025
JUMP_ARM_MIN_M = 0.1  # a moment's jump counts over the legs' reach, at least this (one sensor)


@dataclass(frozen=True, eq=False)
class EstimatorSettings:
    """One desk's fixed quantities for every stage (see the module docstring)."""

    user: EstimationSettings  # the profile's settings, with the chosen method
    method: str
    trace: bool  # keep every candidate (CandidateTrace): all three are computed
    sample_rate_hz: float
    n_sensors: int
    moment_channels: np.ndarray  # (C,) bool: the raw channels that measure a moment
    wrench_map: np.ndarray  # (6, C): the channels to [F_o; M_o], paper eqs. (1)–(4)
    range_flat: np.ndarray  # (C,) each channel's limit: at or beyond it, it is saturated
    frames: list[SurfaceFrame]
    normals: np.ndarray  # (n_surfaces, 3)
    # the zero's rounding floor's desk-fixed parts (candidates.Covariances, kernel_rounding.py):
    # the wrench's least-norm spread over the channels (C, 6), and per surface each channel's
    # column of the map in (F'z, M'x, M'y), g, as (gz², gz·gx, gz·gy, gx², gy²) (S, C, 5)
    channel_spread: np.ndarray
    floor_terms: np.ndarray
    lp_sos: np.ndarray  # the conventional low-pass
    diff_sos: np.ndarray  # the differentiated wrench's low-pass
    det_sos: np.ndarray  # the fast (detection) low-pass
    n_diff: int  # samples of the pseudo-differentiation, paper eq. (8)
    diff_scale: float  # 1 / (n·T_s)
    shared_lp: bool  # both low-passes equal: the difference of the low-passed wrench suffices
    gain_lp: float  # white-noise variance gains of the filters
    gain_diff: float
    gain_det: float
    position_delay_s: float
    det_delay_s: float  # how far the fast low-pass runs behind a ramp (the release prediction)
    n_rate: int  # samples of the fast force's slope
    rate_scale: float
    n_release: int  # samples of its slope for the release prediction (≤ n_rate)
    release_scale: float
    window: int  # samples per tare/stillness window
    still_block: int  # samples averaged before a window's spread is taken (a divisor of it)
    n_tare: int  # windows of a tare
    n_settle: int  # windows a still load is held before it joins the zero
    n_drift: int  # windows an idle desk rests before its drift is followed
    n_object: int  # windows a load as still as the idle desk is held before it joins the zero
    det_full: bool  # the fast low-pass filters the whole wrench (`fused`, trace), not the force
    sway: SwaySettings | None  # the legs-as-accelerometer compensation, or None (off)
    jump_n: float  # a force's change in one sample beyond which a calm reading is held
    jump_arm_m: float  # ... a moment's, over this arm
    jump_hold_n: int  # samples in a row a jump is held at most (JUMP_HOLD_S)

    @classmethod
    def of(cls, profile: DeskProfile, user: EstimationSettings, trace: bool) -> EstimatorSettings:
        """Derive the settings for ``profile`` and the (method-resolved) ``user`` settings."""
        s = user
        fs = profile.sample_rate_hz
        filters = _FilterBank.of(s, fs)
        n_rate = max(1, round(RATE_WINDOW_S * fs))
        n_release = min(n_rate, max(1, round(RELEASE_WINDOW_S * fs)))
        window = max(1, round(WINDOW_S * fs))
        sway = SwaySettings.of(profile, s)
        det_hz = _detect_hz(s, fs)

        def windows(seconds: float) -> int:
            return max(1, math.ceil(seconds / (window / fs) - 1e-9))

        wrench_map = np.ascontiguousarray(profile.wrench_map())
        frames = [SurfaceFrame.of(surf) for surf in profile.surfaces]
        return cls(
            user=s,
            method=s.method,
            trace=trace,
            sample_rate_hz=fs,
            n_sensors=len(profile.sensors),
            moment_channels=profile.moment_channels(),
            wrench_map=wrench_map,
            range_flat=_range_flat(profile),
            frames=frames,
            normals=(
                np.array([surf.normal for surf in profile.surfaces])
                if profile.surfaces
                else np.zeros((0, 3))
            ),
            channel_spread=np.linalg.pinv(wrench_map),
            floor_terms=_floor_terms(frames, wrench_map),
            **filters._asdict(),
            n_rate=n_rate,
            rate_scale=fs / n_rate,
            n_release=n_release,
            release_scale=fs / n_release,
            window=window,
            n_tare=windows(s.tare_s),
            n_settle=windows(s.settle_s),
            n_drift=windows(s.drift_settle_s),
            n_object=windows(s.object_settle_s) if s.object_settle_s > 0 else 0,
            det_full=s.method == "fused" or trace,
            sway=sway,
            still_block=_divisor_near(window, SWAY_STILL_MEAN_S * fs) if sway else 1,
            # the fast low-pass's largest response to a one-sample pulse (it peaks within
            # half a period of its cut-off): how much of a corrupt reading reaches the detector
            jump_n=JUMP_SHARE
            * s.contact_force_n
            / float(np.max(np.abs(impulse_response(filters.det_sos, 4 + int(fs / det_hz)))))
            if s.hold_jumps
            else math.inf,  # (none held: no change is that large)
            jump_arm_m=max(
                JUMP_ARM_MIN_M, *(float(np.linalg.norm(x.position)) for x in profile.sensors)
            ),
            jump_hold_n=max(1, int(JUMP_HOLD_S * fs + 1e-9)),
        )

    def up(self) -> np.ndarray:
        """The first surface's normal (the desk's up), or +z."""
        return self.normals[0] if len(self.normals) else np.array([0.0, 0.0, 1.0])


class _FilterBank(NamedTuple):
    """The filters of one desk's settings (:class:`EstimatorSettings`' fields of the same
    names)."""

    lp_sos: np.ndarray
    diff_sos: np.ndarray
    det_sos: np.ndarray
    n_diff: int
    diff_scale: float
    shared_lp: bool
    gain_lp: float
    gain_diff: float
    gain_det: float
    position_delay_s: float
    det_delay_s: float

    @classmethod
    def of(cls, s: EstimationSettings, fs: float) -> _FilterBank:
        """Designed from the user's cut-offs at ``fs`` Hz."""
        lp_sos = butter_lowpass_sos(s.force_lowpass_hz, fs)
        diff_sos = butter_lowpass_sos(s.diff_lowpass_hz, fs)
        det_sos = butter_lowpass_sos(_detect_hz(s, fs), fs)
        n_diff = max(1, round(s.diff_window_s * fs))
        diff_scale = 1.0 / (n_diff / fs)
        fir = np.zeros(n_diff + 1)
        fir[0], fir[-1] = diff_scale, -diff_scale
        long = int(8 * fs / min(s.force_lowpass_hz, s.diff_lowpass_hz)) + n_diff
        return cls(
            lp_sos=lp_sos,
            diff_sos=diff_sos,
            det_sos=det_sos,
            n_diff=n_diff,
            diff_scale=diff_scale,
            # a difference commutes with an LTI filter: when both low-passes are equal, the
            # differentiated wrench is the difference of the low-passed one
            shared_lp=bool(np.allclose(lp_sos, diff_sos)),
            gain_lp=noise_gain(lp_sos, length=long),
            gain_diff=noise_gain(diff_sos, fir, length=long),
            gain_det=noise_gain(det_sos, length=long),
            # how far the located points run behind a moving finger: the force low-pass's
            # delay (the gesture engine carries a swipe's end on by it)
            position_delay_s=group_delay_s(lp_sos, fs, long),
            det_delay_s=group_delay_s(det_sos, fs, long),
        )


def _detect_hz(s: EstimationSettings, fs: float) -> float:
    """The fast low-pass's cut-off: the user's, or under the Nyquist frequency at a low rate."""
    return min(s.detect_lowpass_hz, 0.45 * fs)


def _floor_terms(frames: list[SurfaceFrame], wrench_map: np.ndarray) -> np.ndarray:
    """(S, C, 5): per surface each channel's column of the map in (F'z, M'x, M'y), g, as
    (gz², gz·gx, gz·gy, gx², gy²): what one channel's offset gives eq. (5)'s point."""
    g = np.array([f.transform[2:5] @ wrench_map for f in frames]).reshape(
        -1, 3, wrench_map.shape[1]
    )
    gz, gx, gy = g[:, 0], g[:, 1], g[:, 2]
    return np.stack([gz * gz, gz * gx, gz * gy, gx * gx, gy * gy], axis=-1)


def _range_flat(profile: DeskProfile) -> np.ndarray:
    """Each channel's limit (C,): an unrated channel counts as rated at UNRATED_LIMIT, so
    that no finite reading can overflow the resultant wrench (and put infinity into the
    filters)."""
    limits = profile.channel_limits()
    if limits is None:
        limits = np.full(profile.channel_count, np.inf)
    return np.where(np.isfinite(limits), limits, UNRATED_LIMIT)


def _divisor_near(n: int, target: float) -> int:
    """The divisor of ``n`` nearest to ``target`` (at least 1)."""
    divisors = [d for d in range(1, n + 1) if n % d == 0]
    return min(divisors, key=lambda d: abs(d - target))
