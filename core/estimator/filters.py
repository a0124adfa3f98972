"""The estimator's filters designed: second-order sections, and what they do to noise and
delay.

The filters run sample by sample in :mod:`hapticdesk.estimator.kernel_filters` (scipy's ``sosfilt``
recursion, its state set to steady state on the first sample and after a gap); here they
are designed with numpy alone, step for step as scipy.signal designs them (equal to the bit,
tests/core/test_core_filters.py), so that estimating imports no scipy.signal (over a second
of start-up on a loaded machine).
"""

from __future__ import annotations

import math

import numpy as np


def butter_lowpass_sos(cutoff_hz: float, sample_rate_hz: float) -> np.ndarray:
    """Second-order Butterworth low-pass as one second-order section [b0, b1, b2, 1, a1, a2]
    (stable at any cut-off/rate ratio), designed as ``scipy.signal.butter(2, cutoff_hz,
    fs=sample_rate_hz, output="sos")`` designs it, step for step (to the bit): the analogue
    prototype's poles −exp(±iπ/4) moved to the prewarped cut-off, the bilinear transform,
    the double zero at z = −1."""
    nyquist = sample_rate_hz / 2.0
    if not 0.0 < cutoff_hz < nyquist:
        raise ValueError(
            f"low-pass cut-off must lie between 0 and the Nyquist frequency {nyquist:g} Hz, "
            f"found {cutoff_hz:g} Hz"
        )
    wn = 2.0 * cutoff_hz / sample_rate_hz  # (as a fraction of Nyquist, scipy's fs = 2)
    warped = 4.0 * math.tan(math.pi * wn / 2.0)
    poles = warped * -np.exp(1j * np.pi * np.arange(-1, 2, 2) / 4)
    gain = warped**2 * np.real(1.0 / np.prod(4.0 - poles))
    b = gain * np.poly([-1.0, -1.0])
    a = np.poly((4.0 + poles) / (4.0 - poles))
    return np.array([[*np.real(b), *np.real(a)]])


def sosfilt_zi(sos: np.ndarray) -> np.ndarray:
    """Each section's two memories (ns, 2) in steady state for a unit step, computed as
    ``scipy.signal.sosfilt_zi`` computes them (to the bit): a section's state solves
    (I − Aᵀ) z = b[1:] − a[1:]·b0 (A its companion matrix), scaled by the DC gain of the
    sections before it."""
    zi = np.empty((len(sos), 2))
    scale = 1.0
    for j, section in enumerate(np.asarray(sos, dtype=float)):
        b, a = section[:3], section[3:]
        b, a = b / a[0], a / a[0]
        companion = np.array([[-a[1], -a[2]], [1.0, 0.0]])
        zi[j] = scale * np.linalg.solve(np.eye(2) - companion.T, b[1:] - a[1:] * b[0])
        scale *= b.sum() / a.sum()
    return zi


def impulse_response(sos: np.ndarray, length: int) -> np.ndarray:
    """The first ``length`` samples of the sections' impulse response."""
    impulse = np.zeros(length)
    impulse[0] = 1.0
    return _sosfilt(sos, impulse)


def noise_gain(sos: np.ndarray, extra_fir: np.ndarray | None = None, length: int = 0) -> float:
    """Variance gain Σ h² of the filter for white noise (optionally after an FIR stage)."""
    n = max(length or 1, 64)
    impulse = np.zeros(n)
    impulse[0] = 1.0
    if extra_fir is not None:
        impulse = np.convolve(impulse, extra_fir)[:n]
    h = _sosfilt(sos, impulse)
    return float(np.sum(h * h))


def _sosfilt(sos: np.ndarray, x: np.ndarray) -> np.ndarray:
    """scipy's ``sosfilt`` recursion (transposed direct form II, as the kernel runs it; the
    same values to the bit) over a design's few thousand samples, zero initial state: plain
    Python, once per estimator, never on data. A section at a time over all the samples (the
    same arithmetic as a sample at a time through every section, in a third of the time)."""
    values = x.tolist()
    for b0, b1, b2, _, a1, a2 in np.asarray(sos, dtype=float).tolist():
        z0 = z1 = 0.0
        out = []
        for value in values:
            y = b0 * value + z0
            z0 = b1 * value - a1 * y + z1
            z1 = b2 * value - a2 * y
            out.append(y)
        values = out
    return np.array(values, dtype=float)


def group_delay_s(sos: np.ndarray, sample_rate_hz: float, length: int) -> float:
    """The low-pass's delay at low frequencies, seconds: the centroid of its impulse response
    over ``length`` samples (how far a ramp lags behind once the filter has settled)."""
    h = impulse_response(sos, length)
    return float(np.sum(np.arange(length) * h) / np.sum(h)) / sample_rate_hz
