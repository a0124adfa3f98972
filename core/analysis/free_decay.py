"""A desk's natural frequencies from its free decay: where it rings freely after a knock or a
quick release, and the clear peaks of those stretches' summed spectrum.

A *free-decay segment* starts after each excitation ends — the desk is loaded (the force,
low-passed at ``LOAD_LOWPASS_HZ``, is ``LOADED_N`` or more off its quiet baseline) or the
force changes sharply (by more than ``SHARP_SIGMAS`` noise σ within ``SHARP_LAG_S``) — and
lasts until the next excitation, ``MAX_SEGMENT_S`` at most. Each segment's six resultant
components, scaled by their noise σ, are detrended, Hann-windowed and zero-padded; their
power spectra are summed (an energy-weighted average, Welch-like over the segments). Peaks
at least ``PEAK_FLOOR_RATIO`` times the spectrum's median are the modes, their frequency
refined by a parabola through the log power of the three bins around the peak. Used by
:mod:`hapticdesk.analysis.characterize`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import signal

LOAD_LOWPASS_HZ = 1.5  # well below any desk mode: what remains is the load, not the ringing
LOADED_N = 0.5  # a quarter of the paper's 2 N contact force
SHARP_LOWPASS_HZ = 50.0
SHARP_LAG_S = 0.02
SHARP_SIGMAS = 8.0
GUARD_S = 0.05  # skip the end of the excitation itself
MIN_SEGMENT_S = 0.5  # shorter ones hold too few periods of a mode
MAX_SEGMENT_S = 4.0
MIN_SEGMENT_ENERGY = 1.3  # a component's variance over its noise's: something rings
SPECTRUM_RESOLUTION_HZ = 0.125  # zero-padding: the FFT's bin width
MIN_MODE_HZ = 1.0
PEAK_FLOOR_RATIO = 6.0  # noise-only spectra (χ² of ≥ 12 dof) stay far below
MAX_MODES = 6


@dataclass(frozen=True)
class Mode:
    """A spectral peak of the free decay: frequency, power relative to the strongest peak,
    and its height over the spectrum's median (the noise floor)."""

    frequency_hz: float
    relative_power: float
    peak_over_floor: float


@dataclass(frozen=True)
class DecaySpectrum:
    """The segments' summed power spectrum (``power`` at ``frequencies_hz``) and how many
    segments rang above the noise (``segments_used``)."""

    frequencies_hz: np.ndarray
    power: np.ndarray
    segments_used: int


@dataclass(frozen=True)
class FoundModes:
    """The spectrum's clear peaks, lowest first, and how many were left out as harmonics."""

    modes: list[Mode]
    harmonics: int


def _lowpass(x: np.ndarray, cutoff_hz: float, fs: float) -> np.ndarray:
    """Zero-phase Butterworth low-pass along time (analysis, not streaming)."""
    sos = signal.butter(2, min(cutoff_hz, 0.4 * fs), fs=fs, output="sos")
    return signal.sosfiltfilt(sos, x, axis=0, padlen=min(len(x) - 1, 3 * (2 * len(sos) + 1)))


def free_decay_segments(
    deviation: np.ndarray, good: np.ndarray, fs: float, sigma: np.ndarray | None
) -> list[tuple[int, int]]:
    """[start, stop) sample ranges where the desk rings freely after an excitation."""
    force = deviation[:, :3]
    loaded = np.linalg.norm(_lowpass(force, LOAD_LOWPASS_HZ, fs), axis=1) >= LOADED_N
    smooth = _lowpass(force, SHARP_LOWPASS_HZ, fs)
    lag = max(1, round(SHARP_LAG_S * fs))
    change = np.zeros(len(force))
    change[lag:] = np.linalg.norm(smooth[lag:] - smooth[:-lag], axis=1)
    threshold = LOADED_N
    if sigma is not None:
        # σ of the lagged difference of the smoothed noise: white noise through the low-pass
        # keeps cutoff/(fs/2) of its variance, and a difference of two samples doubles it
        kept = min(SHARP_LOWPASS_HZ, 0.4 * fs) / (fs / 2.0)
        threshold = max(
            threshold, SHARP_SIGMAS * float(np.linalg.norm(sigma[:3])) * math.sqrt(2 * kept)
        )
    excited = loaded | (change >= threshold) | ~good
    edges = np.diff(excited.astype(np.int8), prepend=0, append=0)
    starts = np.flatnonzero(edges == 1)
    ends = np.flatnonzero(edges == -1)  # first sample after each excitation
    guard = round(GUARD_S * fs)
    shortest, longest = round(MIN_SEGMENT_S * fs), round(MAX_SEGMENT_S * fs)
    segments = []
    for j, end in enumerate(ends.tolist()):
        a = end + guard
        b = int(starts[j + 1]) if j + 1 < len(starts) else len(force)
        b = min(b, a + longest)
        if b - a >= shortest:
            segments.append((a, b))
    return segments


def decay_spectrum(
    resultant: np.ndarray, segments: list[tuple[int, int]], fs: float, sigma: np.ndarray | None
) -> DecaySpectrum:
    """Summed power spectra of the segments' six components in units of their noise σ."""
    nfft = 1 << math.ceil(math.log2(max(fs / SPECTRUM_RESOLUTION_HZ, 2.0 * MAX_SEGMENT_S * fs)))
    freqs = np.fft.rfftfreq(nfft, 1.0 / fs)
    total = np.zeros(len(freqs))
    used = 0
    for a, b in segments:
        x = signal.detrend(resultant[a:b], axis=0)
        if sigma is not None and (sigma > 0).all():
            x = x / sigma
            if float((x * x).mean(axis=0).max()) < MIN_SEGMENT_ENERGY:
                continue  # nothing rings here beyond the noise
        else:  # no noise measure: each component counts by its own spread
            spread = x.std(axis=0)
            x = x / np.where(spread > 0, spread, 1.0)
        window = signal.windows.hann(b - a, sym=False)
        spectrum = np.fft.rfft(x * window[:, None], n=nfft, axis=0)
        total += (np.abs(spectrum) ** 2).sum(axis=1) / float(window @ window)
        used += 1
    return DecaySpectrum(freqs, total, used)


def spectral_modes(spectrum: DecaySpectrum, fs: float) -> FoundModes:
    """The spectrum's clear peaks above MIN_MODE_HZ, lowest frequency first, and how many
    peaks were left out as harmonics."""
    freqs, power = spectrum.frequencies_hz, spectrum.power
    band = (freqs >= MIN_MODE_HZ) & (freqs <= 0.95 * fs / 2)
    idx = np.flatnonzero(band)
    if len(idx) < 3:
        return FoundModes([], 0)
    p = power[idx]
    floor = float(np.median(p))
    if not floor > 0:
        return FoundModes([], 0)
    bin_hz = float(freqs[1] - freqs[0])
    found, props = signal.find_peaks(
        p,
        height=PEAK_FLOOR_RATIO * floor,
        prominence=0.5 * PEAK_FLOOR_RATIO * floor,
        distance=max(1, round(0.5 / bin_hz)),
    )
    if len(found) == 0:
        return FoundModes([], 0)
    top = float(props["peak_heights"].max())
    modes: list[Mode] = []
    harmonics = 0
    for j in found[np.argsort(props["peak_heights"])[::-1]].tolist():  # strongest first
        offset = 0.0
        if 0 < j < len(p) - 1:  # a parabola through the log power of three bins
            lm, l0, lp = np.log(p[j - 1 : j + 2])
            den = lm - 2 * l0 + lp
            offset = 0.5 * (lm - lp) / den if den < 0 else 0.0
        f = float(freqs[idx[j]] + offset * bin_hz)
        # a multiple of a stronger, lower peak is distortion (the sensors' resolution
        # rounds a small sinusoid into a square-ish wave), not a mode of the desk
        if any(_is_harmonic(f, m.frequency_hz, bin_hz) for m in modes):
            harmonics += 1
            continue
        modes.append(Mode(f, float(p[j] / top), float(p[j] / floor)))
        if len(modes) == MAX_MODES:
            break
    return FoundModes(sorted(modes, key=lambda m: m.frequency_hz), harmonics)


def _is_harmonic(f: float, base: float, bin_hz: float) -> bool:
    n = round(f / base)
    return n >= 2 and abs(f - n * base) <= max(2 * bin_hz, 0.01 * f)
