"""The estimator's filters designed: second-order sections, and what they do to noise and
delay.

The filters run sample by sample in :mod:`hapticdesk.estimator.kernel` (scipy's ``sosfilt``
recursion, its state set to steady state on the first sample and after a gap); here they
are designed (scipy.signal, imported only where a filter is designed).
"""

from __future__ import annotations

import numpy as np
from scipy import signal


def butter_lowpass_sos(cutoff_hz: float, sample_rate_hz: float, order: int = 2) -> np.ndarray:
    """Butterworth low-pass as second-order sections (stable at any cut-off/rate ratio)."""
    nyquist = sample_rate_hz / 2.0
    if not 0.0 < cutoff_hz < nyquist:
        raise ValueError(
            f"low-pass cut-off must lie between 0 and the Nyquist frequency {nyquist:g} Hz, "
            f"found {cutoff_hz:g} Hz"
        )
    return np.ascontiguousarray(signal.butter(order, cutoff_hz, fs=sample_rate_hz, output="sos"))


def noise_gain(sos: np.ndarray, extra_fir: np.ndarray | None = None, length: int = 0) -> float:
    """Variance gain Σ h² of the filter for white noise (optionally after an FIR stage)."""
    n = length or 1
    impulse = np.zeros(max(n, 64))
    impulse[0] = 1.0
    if extra_fir is not None:
        impulse = np.convolve(impulse, extra_fir)[: len(impulse)]
    h = signal.sosfilt(sos, impulse)
    return float(np.sum(h * h))


def group_delay_s(sos: np.ndarray, sample_rate_hz: float, length: int) -> float:
    """The low-pass's delay at low frequencies, seconds: the centroid of its impulse response
    over ``length`` samples (how far a ramp lags behind once the filter has settled)."""
    impulse = np.zeros(length)
    impulse[0] = 1.0
    h = signal.sosfilt(sos, impulse)
    return float(np.sum(np.arange(length) * h) / np.sum(h)) / sample_rate_hz
