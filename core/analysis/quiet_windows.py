"""A recording's quiet windows (nobody touches, nothing rings) and what they measure: each
channel's noise and drift.

The recording is cut into windows of ``QUIET_WINDOW_S``; each window's resultant wrench
(F_o, M_o) is detrended (a line fit) and its spread compared with the noise floor, the
``FLOOR_PERCENTILE``-th percentile of the spreads over all windows. Windows within
``QUIET_FACTOR`` of the floor in every component (and without bad samples) are quiet.
**Noise** is the pooled standard deviation of the detrended quiet windows (its 3σ the paper's
"amplitude", 0.4 N on the total F_z, §3.1); **drift** the least-squares slope of the quiet
windows' means over time, per minute, with its standard error. Used by
:mod:`hapticdesk.analysis.characterize`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

QUIET_WINDOW_S = 0.5
FLOOR_PERCENTILE = 5.0  # works while at least 5 % of the recording is quiet
QUIET_FACTOR = 1.2  # a pure-noise window's σ scatters by ≈3 % (600 samples): 1.2 is ~6 sd
MIN_DRIFT_SPAN_S = 10.0


@dataclass(frozen=True)
class ChannelNoise:
    """Noise of one channel in the quiet windows: σ and its 3σ "amplitude"."""

    channel: str
    unit: str
    sigma: float
    amplitude: float


@dataclass(frozen=True)
class ChannelDrift:
    """Drift rate of one channel (per minute) with its standard error."""

    channel: str
    unit: str
    rate_per_min: float
    stderr_per_min: float


@dataclass(frozen=True)
class QuietWindows:
    """The recording cut into windows of ``length`` samples: per window its mid time ``t``,
    the resultant's and the sensor channels' means and detrended variances, and ``quiet``
    (bool) where nobody touched and nothing rang."""

    length: int
    t: np.ndarray  # (W,)
    resultant_mean: np.ndarray  # (W, 6)
    resultant_var: np.ndarray  # (W, 6)
    channel_mean: np.ndarray  # (W, C)
    channel_var: np.ndarray  # (W, C)
    quiet: np.ndarray  # (W,) bool

    @property
    def count(self) -> int:
        """How many windows are quiet."""
        return int(np.count_nonzero(self.quiet))


def find_quiet_windows(
    t: np.ndarray,
    resultant: np.ndarray,
    channels: np.ndarray,
    good: np.ndarray,
    length: int,
    fs: float,
) -> QuietWindows:
    """Cut the recording (``t`` (k,), ``resultant`` (k, 6), sensor ``channels`` (k, C),
    ``good`` (k,) samples without NaN or inf) into windows of ``length`` samples and find
    the quiet ones: detrended spread against the noise floor."""
    k = len(t)
    n_win = k // length
    cut = n_win * length
    res = _window_stats(resultant[:cut], n_win, length)
    ch = _window_stats(channels[:cut], n_win, length)
    if np.isfinite(t).all():
        window_t = t[:cut].reshape(n_win, length).mean(axis=1)
    else:
        window_t = (np.arange(n_win) + 0.5) * length / fs
    clean = good[:cut].reshape(n_win, length).all(axis=1)
    spread = np.sqrt(res.var)
    if not clean.any():
        quiet = np.zeros(n_win, bool)
    else:
        floor = np.percentile(spread[clean], FLOOR_PERCENTILE, axis=0)
        # a channel whose noise is below its resolution is constant when quiet: allow for
        # the rounding error of the arithmetic instead of dividing by zero
        tiny = 1e-9 * (np.abs(res.mean).max(axis=0) + 1.0)
        quiet = clean & (spread <= QUIET_FACTOR * np.maximum(floor, tiny)).all(axis=1)
    return QuietWindows(
        length=length,
        t=window_t,
        resultant_mean=res.mean,
        resultant_var=res.var,
        channel_mean=ch.mean,
        channel_var=ch.var,
        quiet=quiet,
    )


def resultant_sigma(resultant: np.ndarray, windows: QuietWindows) -> np.ndarray | None:
    """The resultant's noise σ per component (None without a quiet window), at least the
    rounding error of its resolution (a component whose noise is below its resolution
    reads σ = 0 but is still uncertain by step/√12)."""
    if not windows.count:
        return None
    steps_res = np.abs(np.diff(resultant, axis=0))
    steps_res[steps_res == 0] = np.inf
    step = np.where(np.isfinite(steps_res.min(axis=0)), steps_res.min(axis=0), 0.0)
    return np.sqrt(windows.resultant_var[windows.quiet].mean(axis=0) + step**2 / 12.0)


class _WindowStats(NamedTuple):
    """Per window and channel (W, C): the mean and the variance about a fitted line."""

    mean: np.ndarray
    var: np.ndarray


def _window_stats(x: np.ndarray, n_win: int, n_w: int) -> _WindowStats:
    """Per window and channel: the mean and the variance about a fitted line (ddof 2)."""
    xw = x.reshape(n_win, n_w, -1)
    mean = xw.mean(axis=1)
    centred = xw - mean[:, None, :]
    ramp = np.arange(n_w) - (n_w - 1) / 2.0
    ramp2 = float(ramp @ ramp)
    slope = np.einsum("j,wjc->wc", ramp, centred) / ramp2
    ss = np.einsum("wjc,wjc->wc", centred, centred) - slope**2 * ramp2
    return _WindowStats(mean, np.maximum(ss, 0.0) / (n_w - 2))


def channel_noise(names: list[str], units: list[str], var: np.ndarray) -> list[ChannelNoise]:
    """σ and 3σ per channel, pooled over the quiet windows' detrended variances ``var``."""
    sigma = np.sqrt(var.mean(axis=0))
    return [
        ChannelNoise(n, u, float(s), float(3.0 * s))
        for n, u, s in zip(names, units, sigma.tolist(), strict=True)
    ]


def channel_drift(
    names: list[str], units: list[str], t: np.ndarray, means: np.ndarray
) -> list[ChannelDrift]:
    """Least-squares slope of the window means over time, per channel, with its stderr."""
    tc = t - t.mean()
    stt = float(tc @ tc)
    centred = means - means.mean(axis=0)
    slope = tc @ centred / stt
    resid = centred - tc[:, None] * slope
    dof = max(len(t) - 2, 1)
    stderr = np.sqrt((resid * resid).sum(axis=0) / dof / stt)
    return [
        ChannelDrift(n, u, float(60.0 * s), float(60.0 * e))
        for n, u, s, e in zip(names, units, slope.tolist(), stderr.tolist(), strict=True)
    ]


def quiet_baseline(t: np.ndarray, windows: QuietWindows, resultant: np.ndarray) -> np.ndarray:
    """The unloaded level of each resultant component over time: interpolated between the
    quiet windows (so drift and objects left on the desk are not taken for a load)."""
    quiet_t = windows.t[windows.quiet]
    quiet_means = windows.resultant_mean[windows.quiet]
    if len(quiet_t) == 0:
        return np.median(resultant, axis=0)[None, :]
    return np.stack([np.interp(t, quiet_t, quiet_means[:, c]) for c in range(6)], axis=1)
