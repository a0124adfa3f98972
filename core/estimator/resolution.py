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

import functools
import math

import numpy as np

from hapticdesk.estimator.kernel_rounding import likeliest_noise

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
# below this noise (in steps) the rounding's bias is taken as its no-noise sawtooth (the
# harmonics beyond SHARE_HARMONICS, damped as exp(-4π²k²ρ²), would still count)
NO_NOISE_RHO = 0.02
# harmonics of the bias summed in :func:`moved_share` (and the kernel's rounding_floor)
SHARE_HARMONICS = 16
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


def zero_rounding_noise(step: np.ndarray, rest_var: np.ndarray, rest_n: int) -> np.ndarray:
    """The noise (C,), in steps (ρ), of the channels quieter than their step (``step`` (C,),
    0: none) whose noise does not dither the rounding out of the mean (0 elsewhere).

    One channel's rest variance (``rest_var`` (C,), from the squared changes of ``rest_n``
    consecutive readings) says more about where its value lies between two steps than about
    its noise: near a step's middle it flickers between two steps at almost any noise, near
    a step it hardly changes. So ρ is that of all the quiet channels together: the one whose
    values, anywhere between steps alike, make their changes likeliest (each channel's
    squared changes in step² as a Poisson count of mean 2·rest_n·var(ρ, x), x the value's
    place between steps; kernel_rounding.likeliest_noise). The mean variance over the channels
    inverted through :func:`rest_variance` says the same on average but scatters: a few
    channels near a step's middle make most of it (on the eight-legged example desk it read
    ρ 0.08 to 0.13 from one recording to another, its noise being 0.124)."""
    quiet = _quiet(step, rest_var)
    if not quiet.any() or rest_n <= 0:
        return np.zeros(len(step))
    counts = 2.0 * rest_n * rest_var[quiet] / step[quiet] ** 2
    bound = np.empty((len(_RHO_GRID), len(counts) + 1))
    scratch = np.empty((6, len(counts)))
    rho = float(_RHO_GRID[likeliest_noise(counts, *_count_means(rest_n), bound, scratch)])
    return np.where(quiet, rho, 0.0)


# the noises (in steps) and places between two steps the likelihoods are worked out on (the
# first as good as none: channels none of which changed at rest keep bias_variance(0) = 1/12)
_RHO_GRID = np.concatenate([[1e-4], np.linspace(0.005, 0.7, 140)])
# (from a step to halfway to the next: the other half mirrors it)
_PLACES = (np.arange(50) + 0.5) / 100


_erfc = np.frompyfunc(math.erfc, 1, 1)


def _normal_cdf(z: np.ndarray) -> np.ndarray:
    """The standard normal's distribution function at ``z``, erfc(−z/√2)/2 (scipy.special's
    ndtr, whose import alone was 0.2 s of a command's start-up, for a table made once)."""
    return 0.5 * np.asarray(_erfc(-z / math.sqrt(2.0)), dtype=np.float64)


@functools.cache
def _reading_variances() -> np.ndarray:
    """(noise, place): the variance, in step², of readings rounded to whole steps of a value
    at ``_PLACES`` between two steps under Gaussian noise of ``_RHO_GRID`` steps."""
    k = np.arange(-4, 6)[:, None, None]  # (the readings within 4 steps of the value)
    rho, x = _RHO_GRID[None, :, None], _PLACES[None, None, :]
    cdf = _normal_cdf((np.arange(-4, 7)[:, None, None] - 0.5 - x) / rho)
    p = cdf[1:] - cdf[:-1]
    mean = np.sum(k * p, axis=0)
    return np.sum(k * k * p, axis=0) - mean**2


@functools.cache
def _count_means(rest_n: int) -> tuple[np.ndarray, np.ndarray]:
    """(noise, place): the mean squared change, in step², of ``rest_n`` consecutive readings
    and its log (once a process for each ``rest_n``: a desk's is the same at every tare)."""
    mean = 2.0 * rest_n * _reading_variances() + 1e-9
    return mean, np.log(mean)


def _quiet(step: np.ndarray, rest_var: np.ndarray) -> np.ndarray:
    """(C,) bool: the channels with a step whose rest variance does not dither it."""
    return (step > 0) & (rest_var < DITHERED * step**2)


def zero_rounding_channels(
    step: np.ndarray, rest_var: np.ndarray, rest_n: int, rho: np.ndarray | None = None
) -> np.ndarray:
    """The variance (C,) of each channel's zero rounding offset: the error the tare keeps on
    channels quieter than their step whose noise (:func:`zero_rounding_noise`; ``rho`` if
    made already) does not dither the rounding out of the mean (0 elsewhere). One error for
    every sample until the next tare, so no averaging lowers it; the differentiated force
    shares it while its eq. (8) window reaches back to the rest before a touch (its old end
    is then the tare's reading)."""
    if rho is None:
        rho = zero_rounding_noise(step, rest_var, rest_n)
    return np.where(_quiet(step, rest_var), bias_variance(rho) * step**2, 0.0)


def zero_rounding(
    wrench_map: np.ndarray, step: np.ndarray, rest_var: np.ndarray, rest_n: int
) -> np.ndarray:
    """The covariance (6, 6) of the zero's rounding offset where every channel moves under
    the press (:func:`zero_rounding_channels` through the map): the bound the kernel's
    offset reaches; a channel a press moves less keeps less of it (:func:`moved_share`)."""
    variance = zero_rounding_channels(step, rest_var, rest_n)
    return wrench_map @ (wrench_map.T * variance[:, None])


def moved_share(
    change: np.ndarray | float, step: np.ndarray | float, rho: np.ndarray | float = 0.0
) -> np.ndarray:
    """The share of a channel's zero rounding offset a press that moves the channel by
    ``change`` keeps, under a noise of ``rho`` steps. The tared reading's error is
    b(x₀ + Δ) − b(x₀), b the rounding's bias (harmonic k of amplitude exp(−2π²k²ρ²)/(πk)):
    over where x₀ lies its variance is Σ w_k·4 sin²(πkd) against the offset's Σ w_k, w_k =
    exp(−4π²k²ρ²)/k², d = |Δ|/step. A channel the press does not move keeps none (the tare
    cancels its bias); a small change keeps ≈ 4π²d²·Σ k²w_k/Σ w_k, quadratic in d under
    noise (12 d(1 − d), linear, with none: ``rho`` under ``NO_NOISE_RHO``); at most the
    whole offset, reached before half a step and kept beyond (a channel moved across steps
    averages the press's own rounding, which rounding_deficit counts). Mirrored per channel
    in the kernel's rounding_floor."""
    d = np.minimum(np.abs(np.asarray(change, dtype=float)) / np.asarray(step, dtype=float), 0.5)
    rho = np.broadcast_to(np.asarray(rho, dtype=float), d.shape)
    k = np.arange(1, SHARE_HARMONICS + 1)
    w = np.exp(-4.0 * np.pi**2 * np.multiply.outer(rho**2, k**2)) / k**2
    harmonic = np.sum(w * 4.0 * np.sin(np.pi * np.multiply.outer(d, k)) ** 2, axis=-1)
    share = np.where(rho < NO_NOISE_RHO, 12.0 * d * (1.0 - d), harmonic / np.sum(w, axis=-1))
    return np.minimum(1.0, share)
