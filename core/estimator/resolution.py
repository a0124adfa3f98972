"""The sensors' resolution, learned from their readings: each channel's smallest change.

A sensor reports in steps (an ADC count times a scale; 1/2000 of the rating for the paper's
sensors, Table 2). Where its noise is well below one step, the noise measured at the tare
misses two errors: at rest a channel sits on one step, so the tare sees almost no noise,
though a reading in motion is off by up to half a step (variance step²/12, and slow: a force
that changes by less than a step per sample keeps its rounding error for many samples, so
the low-pass does not average it away); and the zero itself is off by up to half a step on
every channel for as long as it is kept. Where the noise is a step or more it dithers the
rounding: the measured noise already holds the step²/12 and the tare's mean is true.
:func:`rounding_deficit` is the part of the rounding the measured noise lacks.

The zero's rounding offset (:func:`zero_rounding`): a noise that only partly dithers the
steps leaves the mean of still readings off too (up to half a step with no noise, under
1e-4 step from 0.6 step of noise), one error for every sample until the next tare. It is
measured from each channel's noise (its first ``REST_NOISE_S`` of readings out of contact,
summed in the kernel's ``_learn_steps``) and added to the located point's 1-σ, not to the
candidates' weights (every candidate shares it: the differentiated force too, while the eq.
(8) window reaches back to the rest before a touch), so positions do not change.

A channel's step is the smallest non-zero change between two consecutive good readings:
readings on a grid change by whole steps. Readings off a grid (floats, a CSV with many
decimals, the gauges of a sensor decoded through its calibration matrix) change by far less
than their noise, so their "step" adds nothing. A channel stops learning after
``CONFIRM_CHANGES`` changes; a quiet one learns its step at the first touches (until then it
has none, 0). Once tared, a step that is new or shrank by more than ``STEP_CHANGE`` makes the
covariances anew, used from the sample whose reading taught it (``_learn_steps`` and
``steps_changed`` in :mod:`hapticdesk.estimator.kernel_channels`).

Measured (``python scripts/tap_accuracy.py --desk paper --noise N``, 1,000 edge taps): a
sensor whose noise no longer dithers its steps (below about 0.3 N on the paper desk's total
F_z) placed taps from the zero's offset and the differentiated force's rounding with a
confidence they did not have; see docs/stability.md.
"""

from __future__ import annotations

import numpy as np

# changes a channel's smallest change is taken over before it counts as its step: a quiet
# channel pressed quickly moves by several steps at a time at first, a held press by one
CONFIRM_CHANGES = 200
# a step that shrank by more than this share since the covariances were made remakes them
STEP_CHANGE = 0.1


def rounding_deficit(wrench_map: np.ndarray, step: np.ndarray, measured: np.ndarray) -> np.ndarray:
    """The part of the rounding's covariance (6, 6) the ``measured`` noise (6, 6) lacks: the
    positive part of M diag(step²/12) Mᵀ − measured. Nothing where the noise dithers the
    rounding (the rounding is then in the measured noise), all of it where the channels sat
    on one step at the tare."""
    rounding = wrench_map @ (wrench_map.T * (step**2 / 12.0)[:, None])
    gap = rounding - measured
    values, vectors = np.linalg.eigh((gap + gap.T) / 2.0)
    return (vectors * np.clip(values, 0.0, None)) @ vectors.T


# rest readings (seconds of them, not in contact) whose changes measure each channel's noise
REST_NOISE_S = 2.0
# a channel whose rest variance is at least this many step² is dithered by its noise: the
# mean of its readings is true (its rounding bias is under 1e-4 step)
DITHERED = 0.5
# harmonics of the rounding error summed in :func:`bias_variance` (the rest: their sum at ρ = 0,
# damped as the last)
_HARMONICS = np.arange(1, 51)
_TAIL = np.pi**2 / 6.0 - float(np.sum(1.0 / _HARMONICS**2))


def bias_variance(rho: np.ndarray | float) -> np.ndarray:
    """Variance, in step², of the error of the mean of rounded readings of a still value
    anywhere between two steps, under Gaussian noise of ``rho`` steps (σ/step): the rounding
    error's Fourier series (the harmonic k at q/(πk), damped by the noise as
    exp(−2π²k²ρ²)) squared and averaged over where the value lies. 1/12 at ρ = 0 (the
    reading sits on one step: off by up to half a step), under 1e-4 from ρ = 0.6."""
    rho = np.asarray(rho, dtype=float)
    damped = np.exp(-4.0 * np.pi**2 * np.multiply.outer(rho**2, _HARMONICS**2))
    tail = _TAIL * damped[..., -1]
    return (np.sum(damped / _HARMONICS**2, axis=-1) + tail) / (2.0 * np.pi**2)


def rest_variance(rho: np.ndarray | float) -> np.ndarray:
    """A rounded channel's variance at rest, in step², under noise of ``rho`` steps: noise +
    rounding − the bias its mean keeps (averaged over where the value lies between steps);
    0 at ρ = 0, rising."""
    rho = np.asarray(rho, dtype=float)
    return rho**2 + 1.0 / 12.0 - bias_variance(rho)


def zero_rounding_channels(step: np.ndarray, rest_var: np.ndarray) -> np.ndarray:
    """The variance (C,) of each channel's zero rounding offset: the error the tare keeps on
    channels quieter than their step (``step`` (C,), 0: none) whose noise does not dither
    the rounding out of the mean (0 elsewhere). One error for every sample until the next
    tare, so no averaging lowers it; the differentiated force shares it while its eq. (8)
    window reaches back to the rest before a touch (its old end is then the tare's reading).

    The noise in steps (ρ) is pooled over the quiet channels (rest variance ``rest_var``
    (C,), under ``DITHERED`` step², inverted through the rest variance a rounded channel
    has at ρ): one channel's variance depends on where its value lies between two steps, the
    mean over channels does not. Measured on the 120-desk sweep's light taps: per channel
    it overstated the error 1.2-2.2 times in σ (six desks)."""
    quiet = (step > 0) & (rest_var < DITHERED * step**2)
    if not quiet.any():
        return np.zeros(len(step))
    pooled = float(np.mean(rest_var[quiet] / step[quiet] ** 2))
    grid = np.linspace(0.0, 1.0, 1001)
    rho = np.interp(pooled, rest_variance(grid), grid)
    return np.where(quiet, bias_variance(rho) * step**2, 0.0)


def zero_rounding(wrench_map: np.ndarray, step: np.ndarray, rest_var: np.ndarray) -> np.ndarray:
    """The covariance (6, 6) of the zero's rounding offset where every channel moves under
    the press (:func:`zero_rounding_channels` through the map): the bound the kernel's
    offset reaches; a channel a press moves less keeps less of it (:func:`moved_share`)."""
    variance = zero_rounding_channels(step, rest_var)
    return wrench_map @ (wrench_map.T * variance[:, None])


def moved_share(change: np.ndarray | float, step: np.ndarray | float) -> np.ndarray:
    """The share of a channel's zero rounding offset a press that moves the channel by
    ``change`` keeps. The tared reading's error is b(x₀ + Δ) − b(x₀), b the rounding's
    bias: a channel the press does not move keeps its bias, which the tare then cancels.
    With no noise its variance is d(1 − d)·step² (d the fraction of a step of Δ), ≈ |Δ|·step
    for a small Δ, the bias's own step²/12 from d ≈ 0.09; a noise makes b smoother and the
    share smaller. So min(1, 12 |Δ| / step): never below the truth for a small change, and
    at most the whole offset (a channel moved across steps averages the press's own rounding,
    which rounding_deficit counts). Mirrored per channel in the kernel's rounding_floor."""
    ratio = np.abs(np.asarray(change, dtype=float)) / np.asarray(step, dtype=float)
    return np.minimum(1.0, 12.0 * ratio)
