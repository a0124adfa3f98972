"""Characterising a desk (or one sensor on the bench) from a recording: what a new desk needs.

From a recording of a quiet desk knocked now and then (no ground truth needed):

- **Quiet windows** are found automatically: the recording is cut into windows of
  ``QUIET_WINDOW_S``; each window's resultant wrench (F_o, M_o) is detrended (a line fit) and
  its spread compared with the noise floor, the ``FLOOR_PERCENTILE``-th percentile of the
  spreads over all windows. Windows within ``QUIET_FACTOR`` of the floor in every component
  (and without bad samples) are quiet: nobody touches, nothing rings.
- **Noise** per channel: the standard deviation of the detrended quiet windows, pooled; its
  3σ is the "amplitude" the paper quotes (0.4 N on the total F_z, §3.1). Per sensor channel
  and for the resultant (the desk's total force and moment).
- **Drift** per channel: the least-squares slope of the quiet windows' means over time, in
  units per minute, with its standard error (needs quiet windows spanning ``MIN_DRIFT_SPAN_S``).
  An object put down or taken away during the recording shows as drift.
- **Natural frequencies**: the desk rings freely after a knock or a quick release. A
  *free-decay segment* starts after each excitation ends — the desk is loaded (the force,
  low-passed at ``LOAD_LOWPASS_HZ``, is ``LOADED_N`` or more off its quiet baseline) or the
  force changes sharply (by more than ``SHARP_SIGMAS`` noise σ within ``SHARP_LAG_S``) — and
  lasts until the next excitation, ``MAX_SEGMENT_S`` at most. Each segment's six resultant
  components, scaled by their noise σ, are detrended, Hann-windowed and zero-padded; their
  power spectra are summed (an energy-weighted average, Welch-like over the segments). Peaks
  at least ``PEAK_FLOOR_RATIO`` times the spectrum's median are the modes, their frequency
  refined by a parabola through the log power of the three bins around the peak.
- **Cut-off**: ``CUTOFF_RATIO`` × the lowest mode, the paper's ratio (4.77 Hz for 5.9 Hz,
  §3.2), so the conventional and differentiating low-passes do not excite the resonance.

A profile with one sensor and no surfaces (a sensor on the bench) works the same way.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
from scipy import signal

from hapticdesk.analysis.inertia_fit import InertiaFit, fit_inertia
from hapticdesk.errors import ConfigError
from hapticdesk.files.profile import LOWPASS_PER_NATURAL_FREQUENCY, DeskProfile
from hapticdesk.files.recording import Recording
from hapticdesk.files.rigid_body import is_body_inertia

QUIET_WINDOW_S = 0.5
FLOOR_PERCENTILE = 5.0  # works while at least 5 % of the recording is quiet
QUIET_FACTOR = 1.2  # a pure-noise window's σ scatters by ≈3 % (600 samples): 1.2 is ~6 sd
MIN_DRIFT_SPAN_S = 10.0
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
CUTOFF_RATIO = LOWPASS_PER_NATURAL_FREQUENCY  # paper §3.2: 4.77 Hz below the 5.9 Hz mode

#: the sample rates characterize works at (10 Hz: a mode above 1 Hz still has samples to show
#: in; 100 kHz: the zero-padded spectrum of a segment stays under a million bins)
MIN_RATE_HZ = 10.0
MAX_RATE_HZ = 100_000.0
#: a reading beyond this (N or N·m) is no sensor's: left out like NaN, so that the
#: statistics cannot overflow
MAX_READING = 1e12

RESULTANT = ("total_fx", "total_fy", "total_fz", "total_mx", "total_my", "total_mz")


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
class Mode:
    """A spectral peak of the free decay: frequency, power relative to the strongest peak,
    and its height over the spectrum's median (the noise floor)."""

    frequency_hz: float
    relative_power: float
    peak_over_floor: float


@dataclass
class Characterization:
    """What :func:`characterize` measured; a field is empty/None with a ``*_reason`` when the
    recording did not allow it."""

    samples: int
    duration_s: float
    sample_rate_hz: float
    window_s: float
    quiet_windows: int
    quiet_s: float
    noise: list[ChannelNoise] = field(default_factory=list)
    total_noise: list[ChannelNoise] = field(default_factory=list)
    noise_reason: str = ""
    drift: list[ChannelDrift] = field(default_factory=list)
    total_drift: list[ChannelDrift] = field(default_factory=list)
    drift_reason: str = ""
    segments: int = 0
    modes: list[Mode] = field(default_factory=list)
    modes_reason: str = ""
    lowest_mode_hz: float | None = None
    suggested_cutoff_hz: float | None = None
    notes: list[str] = field(default_factory=list)
    # the desk's moments of inertia, for a desk with several accelerometers (inertia_fit)
    inertia: InertiaFit | None = None
    inertia_kg_m2: list[float] | None = None  # the three to give the profile
    spectrum_hz: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    spectrum: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)

    def noise_of(self, channel: str) -> ChannelNoise:
        """The noise of a sensor channel (``fl_fz``) or of the resultant (``total_fz``)."""
        for item in (*self.noise, *self.total_noise):
            if item.channel == channel:
                return item
        raise KeyError(channel)

    def profile_values(self) -> dict[str, dict[str, float | list[float]]]:
        """The measured values in the profile's terms (``desk:`` and ``estimation:``)."""
        desk: dict[str, float | list[float]] = {}
        estimation: dict[str, float | list[float]] = {}
        if self.lowest_mode_hz is not None and self.suggested_cutoff_hz is not None:
            desk["natural_frequency_hz"] = round(self.lowest_mode_hz, 2)
            # named, not left to be derived from the natural frequency: a profile that names
            # its cut-offs would otherwise keep its old ones
            estimation["force_lowpass_hz"] = self.suggested_cutoff_hz
            estimation["diff_lowpass_hz"] = self.suggested_cutoff_hz
        for key, kind, items, attr in (
            ("noise_force_n", "N", self.noise, "sigma"),
            ("noise_moment_nm", "N·m", self.noise, "sigma"),
            ("drift_force_n_per_min", "N", self.drift, "rate_per_min"),
            ("drift_moment_nm_per_min", "N·m", self.drift, "rate_per_min"),
        ):
            values = [getattr(x, attr) for x in items if x.unit == kind]
            if values:  # RMS over the channels: the profile has one number per kind
                estimation[key] = float(f"{math.sqrt(np.mean(np.square(values))):.3g}")
        if self.inertia_kg_m2 is not None:
            desk["inertia_kg_m2"] = self.inertia_kg_m2
        out = {}
        if desk:
            out["desk"] = desk
        if estimation:
            out["estimation"] = estimation
        return out

    def snippet(self) -> str | None:
        """The profile lines to paste (YAML flow style), or None when nothing was measured."""
        values = self.profile_values()
        if not values:
            return None
        lines = []
        for section, items in values.items():
            inner = ", ".join(f"{k}: {_yaml_number(v)}" for k, v in items.items())
            lines.append(f"{section}: {{{inner}}}")
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-ready values (no arrays, no NaN)."""
        out = asdict(self)
        del out["spectrum_hz"], out["spectrum"]
        out["snippet"] = self.snippet()
        out["profile"] = self.profile_values()
        return out


def characterize(
    profile: DeskProfile, recording: Recording, where: str = "recording"
) -> Characterization:
    """Measure noise, drift and natural frequencies of the desk in ``recording`` (module doc).

    Raises :class:`ConfigError` at ``where`` (the recording's file name) when the recording
    is too short or its times or values are unusable.
    """
    # NaN and inf are flagged and left out below; what arithmetic makes of the rest (a
    # window of large values) is judged by the results, not printed as numpy's warnings
    with np.errstate(over="ignore", invalid="ignore", divide="ignore", under="ignore"):
        return _characterize(profile, recording, where)


def _characterize(profile: DeskProfile, recording: Recording, where: str) -> Characterization:
    t = np.asarray(recording.t, dtype=float)
    k = len(t)
    needs = f"characterize needs at least {2 * QUIET_WINDOW_S:g} s"
    if k < 2:
        raise ConfigError(where, f"{k} sample(s): too short, {needs}")
    flat = recording.wrench.reshape(k, -1)
    steps = np.diff(t)
    good_steps = steps[np.isfinite(steps) & (steps > 0)]
    if len(good_steps) == 0:
        raise ConfigError(
            where,
            "no sample time is after the one before it: cannot characterize (expected "
            "increasing times in seconds)",
        )
    period_s = float(np.median(good_steps))
    fs = 1.0 / period_s
    if not MIN_RATE_HZ <= fs <= MAX_RATE_HZ:
        raise ConfigError(
            where,
            f"the sample times are {period_s:.6g} s apart (median): {fs:.6g} Hz; characterize "
            f"expects {MIN_RATE_HZ:g} Hz to {MAX_RATE_HZ:g} Hz (the profile says "
            f"{profile.sample_rate_hz:g} Hz; are the times in seconds?)",
        )
    n_w = max(4, round(QUIET_WINDOW_S * fs))
    if k < 2 * n_w:
        raise ConfigError(where, f"too short: {k} samples, {needs}")
    notes = []
    if abs(fs - profile.sample_rate_hz) > 0.02 * profile.sample_rate_hz:
        notes.append(
            f"the recording is sampled at {fs:.1f} Hz, the profile says "
            f"{profile.sample_rate_hz:g} Hz; the recording's times are used"
        )
    good = (np.abs(flat) <= MAX_READING).all(axis=1) & np.isfinite(t)  # (False for NaN)
    if not good.any():
        raise ConfigError(
            where,
            f"no sample has usable forces and moments (all hold NaN, inf or a value beyond "
            f"{MAX_READING:g}): cannot characterize",
        )
    if not good.all():
        notes.append(
            f"{int(np.count_nonzero(~good))} samples with NaN, inf or a value beyond "
            f"{MAX_READING:g} are left out"
        )
        flat = _hold_last_good(flat, good)
    resultant = flat @ profile.wrench_map().T  # (k, 6): paper eqs. (1)–(4)

    channels = profile.channel_names()  # (a load cell's one, a six-axis sensor's six)
    units = ["N", "N", "N", "N·m", "N·m", "N·m"]
    sensor_units = ["N·m" if moment else "N" for moment in profile.moment_channels()]

    # --- quiet windows: detrended spread against the noise floor ------------------------
    n_win = k // n_w
    cut = n_win * n_w
    res_mean, res_var = _window_stats(resultant[:cut], n_win, n_w)
    ch_mean, ch_var = _window_stats(flat[:cut], n_win, n_w)
    window_t = t[:cut].reshape(n_win, n_w).mean(axis=1) if np.isfinite(t).all() else None
    if window_t is None:
        window_t = (np.arange(n_win) + 0.5) * n_w / fs
    clean = good[:cut].reshape(n_win, n_w).all(axis=1)
    spread = np.sqrt(res_var)
    floor = np.percentile(spread[clean], FLOOR_PERCENTILE, axis=0) if clean.any() else None
    if floor is None:
        quiet = np.zeros(n_win, bool)
    else:
        # a channel whose noise is below its resolution is constant when quiet: allow for
        # the rounding error of the arithmetic instead of dividing by zero
        tiny = 1e-9 * (np.abs(res_mean).max(axis=0) + 1.0)
        quiet = clean & (spread <= QUIET_FACTOR * np.maximum(floor, tiny)).all(axis=1)
    n_quiet = int(np.count_nonzero(quiet))
    result = Characterization(
        samples=k,
        duration_s=float(t[-1] - t[0]) if k else 0.0,
        sample_rate_hz=fs,
        window_s=n_w / fs,
        quiet_windows=n_quiet,
        quiet_s=n_quiet * n_w / fs,
        notes=notes,
    )

    # --- noise and drift ------------------------------------------------------------------
    if n_quiet == 0:
        result.noise_reason = "no quiet window found: record the desk untouched for a while"
        result.drift_reason = result.noise_reason
    else:
        result.noise = _noise(channels, sensor_units, ch_var[quiet])
        result.total_noise = _noise(list(RESULTANT), units, res_var[quiet])
        constant = [n.channel for n in result.noise if n.sigma == 0.0]
        if constant:
            notes.append(
                f"{', '.join(constant)} did not change in the quiet windows: their noise is "
                "below their resolution (σ reads 0)"
            )
        span = float(window_t[quiet][-1] - window_t[quiet][0])
        if n_quiet < 3 or span < MIN_DRIFT_SPAN_S:
            result.drift_reason = (
                f"quiet windows span {span:.1f} s; drift needs at least {MIN_DRIFT_SPAN_S:g} s"
            )
        else:
            result.drift = _drift(channels, sensor_units, window_t[quiet], ch_mean[quiet])
            result.total_drift = _drift(list(RESULTANT), units, window_t[quiet], res_mean[quiet])

    # --- natural frequencies from free decay ---------------------------------------------
    sigma = None
    if n_quiet:
        # the noise σ, at least the rounding error of the resolution (a channel whose noise
        # is below its resolution reads σ = 0 but is still uncertain by step/√12)
        steps_res = np.abs(np.diff(resultant, axis=0))
        steps_res[steps_res == 0] = np.inf
        step = np.where(np.isfinite(steps_res.min(axis=0)), steps_res.min(axis=0), 0.0)
        sigma = np.sqrt(res_var[quiet].mean(axis=0) + step**2 / 12.0)
    baseline = _baseline(t, window_t[quiet], res_mean[quiet], resultant)
    segments = _free_decay_segments(resultant - baseline, good, fs, sigma)
    freqs, power, used = _decay_spectrum(resultant, segments, fs, sigma)
    result.segments = used
    result.spectrum_hz, result.spectrum = freqs, power
    if used == 0:
        result.modes_reason = (
            "no free decay found: knock the desk sideways (or tap it) a few times, "
            f"leaving at least {MIN_SEGMENT_S + GUARD_S:g} s of quiet after each"
        )
    else:
        result.modes, harmonics = _peaks(freqs, power, fs)
        if harmonics:
            notes.append(f"{harmonics} spectral peak(s) at multiples of a mode left out")
        if not result.modes:
            result.modes_reason = "the free decay shows no clear spectral peak"
    if result.modes:
        lowest = result.modes[0].frequency_hz
        result.lowest_mode_hz = lowest
        result.suggested_cutoff_hz = round(CUTOFF_RATIO * lowest, 2)

    # --- the moments of inertia, with several accelerometers ------------------------------
    if len(profile.accelerometers) > 1:
        fit = fit_inertia(profile, recording, baseline, fs)
        result.inertia = fit
        if any(m is not None for m in fit.moments):
            moments = fit.with_profile(profile)
            if is_body_inertia(moments):
                result.inertia_kg_m2 = moments
            else:  # (a fitted moment too small for the others: a fit to distrust)
                result.notes.append(
                    f"the fitted moments of inertia {moments} are no body's (one exceeds the "
                    "other two's sum): not suggested; record firmer presses near the ends"
                )
    return result


def _yaml_number(value: float | list[float]) -> str:
    """A value of the snippet in YAML flow style."""
    if isinstance(value, list):
        return "[" + ", ".join(f"{v:g}" for v in value) + "]"
    return f"{value:g}"


def _hold_last_good(x: np.ndarray, good: np.ndarray) -> np.ndarray:
    """Replace bad rows by the last good one (the first good one before any)."""
    if not good.any():
        return np.zeros_like(x)
    index = np.where(good, np.arange(len(x)), -1)
    np.maximum.accumulate(index, out=index)
    index[index < 0] = int(np.flatnonzero(good)[0])
    return x[index]


def _window_stats(x: np.ndarray, n_win: int, n_w: int) -> tuple[np.ndarray, np.ndarray]:
    """Per window and channel: the mean and the variance about a fitted line (ddof 2)."""
    xw = x.reshape(n_win, n_w, -1)
    mean = xw.mean(axis=1)
    centred = xw - mean[:, None, :]
    ramp = np.arange(n_w) - (n_w - 1) / 2.0
    ramp2 = float(ramp @ ramp)
    slope = np.einsum("j,wjc->wc", ramp, centred) / ramp2
    ss = np.einsum("wjc,wjc->wc", centred, centred) - slope**2 * ramp2
    return mean, np.maximum(ss, 0.0) / (n_w - 2)


def _noise(names: list[str], units: list[str], var: np.ndarray) -> list[ChannelNoise]:
    sigma = np.sqrt(var.mean(axis=0))
    return [
        ChannelNoise(n, u, float(s), float(3.0 * s))
        for n, u, s in zip(names, units, sigma.tolist(), strict=True)
    ]


def _drift(
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


def _baseline(
    t: np.ndarray, quiet_t: np.ndarray, quiet_means: np.ndarray, resultant: np.ndarray
) -> np.ndarray:
    """The unloaded level of each resultant component over time: interpolated between the
    quiet windows (so drift and objects left on the desk are not taken for a load)."""
    if len(quiet_t) == 0:
        return np.median(resultant, axis=0)[None, :]
    return np.stack([np.interp(t, quiet_t, quiet_means[:, c]) for c in range(6)], axis=1)


def _lowpass(x: np.ndarray, cutoff_hz: float, fs: float) -> np.ndarray:
    """Zero-phase Butterworth low-pass along time (analysis, not streaming)."""
    sos = signal.butter(2, min(cutoff_hz, 0.4 * fs), fs=fs, output="sos")
    return signal.sosfiltfilt(sos, x, axis=0, padlen=min(len(x) - 1, 3 * (2 * len(sos) + 1)))


def _free_decay_segments(
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


def _decay_spectrum(
    resultant: np.ndarray, segments: list[tuple[int, int]], fs: float, sigma: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray, int]:
    """Summed power spectra of the segments' six components in units of their noise σ.
    Returns frequencies, power and how many segments rang above the noise."""
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
    return freqs, total, used


def _peaks(freqs: np.ndarray, power: np.ndarray, fs: float) -> tuple[list[Mode], int]:
    """The spectrum's clear peaks above MIN_MODE_HZ, lowest frequency first, and how many
    peaks were left out as harmonics."""
    band = (freqs >= MIN_MODE_HZ) & (freqs <= 0.95 * fs / 2)
    idx = np.flatnonzero(band)
    if len(idx) < 3:
        return [], 0
    p = power[idx]
    floor = float(np.median(p))
    if not floor > 0:
        return [], 0
    bin_hz = float(freqs[1] - freqs[0])
    found, props = signal.find_peaks(
        p,
        height=PEAK_FLOOR_RATIO * floor,
        prominence=0.5 * PEAK_FLOOR_RATIO * floor,
        distance=max(1, round(0.5 / bin_hz)),
    )
    if len(found) == 0:
        return [], 0
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
    return sorted(modes, key=lambda m: m.frequency_hz), harmonics


def _is_harmonic(f: float, base: float, bin_hz: float) -> bool:
    n = round(f / base)
    return n >= 2 and abs(f - n * base) <= max(2 * bin_hz, 0.01 * f)
