"""Characterising a desk (or one sensor on the bench) from a recording: what a new desk needs.

From a recording of a quiet desk knocked now and then (no ground truth needed):

- **Quiet windows** (:mod:`hapticdesk.analysis.quiet_windows`): windows whose detrended
  resultant wrench spreads no more than the noise floor: nobody touches, nothing rings.
- **Noise** per channel: the standard deviation of the detrended quiet windows, pooled; its
  3σ is the "amplitude" the paper quotes (0.4 N on the total F_z, §3.1). Per sensor channel
  and for the resultant (the desk's total force and moment).
- **Drift** per channel: the least-squares slope of the quiet windows' means over time, in
  units per minute, with its standard error (needs quiet windows spanning ``MIN_DRIFT_SPAN_S``).
  An object put down or taken away during the recording shows as drift.
- **Natural frequencies** (:mod:`hapticdesk.analysis.free_decay`): the peaks of the spectrum
  of the stretches where the desk rings freely after a knock or a quick release.
- **Cut-off**: ``CUTOFF_RATIO`` × the lowest mode, the paper's ratio (4.77 Hz for 5.9 Hz,
  §3.2), so the conventional and differentiating low-passes do not excite the resonance.
- **Moments of inertia**, with several accelerometers (:mod:`hapticdesk.analysis.inertia_fit`).

A profile with one sensor and no surfaces (a sensor on the bench) works the same way.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from hapticdesk.analysis.free_decay import (
    GUARD_S,
    MIN_SEGMENT_S,
    Mode,
    decay_spectrum,
    free_decay_segments,
    spectral_modes,
)
from hapticdesk.analysis.inertia_fit import InertiaFit, fit_inertia
from hapticdesk.analysis.quiet_windows import (
    MIN_DRIFT_SPAN_S,
    QUIET_WINDOW_S,
    ChannelDrift,
    ChannelNoise,
    QuietWindows,
    channel_drift,
    channel_noise,
    find_quiet_windows,
    quiet_baseline,
    resultant_sigma,
)
from hapticdesk.errors import ConfigError
from hapticdesk.files.profile import LOWPASS_PER_NATURAL_FREQUENCY, DeskProfile
from hapticdesk.files.recording import Recording
from hapticdesk.files.rigid_body import is_body_inertia

CUTOFF_RATIO = LOWPASS_PER_NATURAL_FREQUENCY  # paper §3.2: 4.77 Hz below the 5.9 Hz mode

#: the sample rates characterize works at (10 Hz: a mode above 1 Hz still has samples to show
#: in; 100 kHz: the zero-padded spectrum of a segment stays under a million bins)
MIN_RATE_HZ = 10.0
MAX_RATE_HZ = 100_000.0
#: a reading beyond this (N or N·m) is no sensor's: left out like NaN, so that the
#: statistics cannot overflow
MAX_READING = 1e12

RESULTANT = ("total_fx", "total_fy", "total_fz", "total_mx", "total_my", "total_mz")
RESULTANT_UNITS = ("N", "N", "N", "N·m", "N·m", "N·m")


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
    data = _usable_samples(profile, recording, where)
    windows = find_quiet_windows(
        data.t, data.resultant, data.channels, data.good, data.window_length, data.rate_hz
    )
    k = len(data.t)
    result = Characterization(
        samples=k,
        duration_s=float(data.t[-1] - data.t[0]) if k else 0.0,
        sample_rate_hz=data.rate_hz,
        window_s=windows.length / data.rate_hz,
        quiet_windows=windows.count,
        quiet_s=windows.count * windows.length / data.rate_hz,
        notes=data.notes,
    )
    _measure_noise_and_drift(result, profile, windows)
    baseline = quiet_baseline(data.t, windows, data.resultant)
    _measure_modes(result, data, windows, baseline)
    if len(profile.accelerometers) > 1:
        _measure_inertia(result, profile, recording, baseline, data.rate_hz)
    return result


@dataclass(frozen=True)
class _Samples:
    """The recording made usable: times, the sensor channels (k, C) with bad rows held at
    the last good one, ``good`` (k,) the rows that were usable, the resultant (k, 6), the
    sample rate, the quiet windows' length in samples, and notes for the report."""

    t: np.ndarray
    channels: np.ndarray
    good: np.ndarray
    resultant: np.ndarray
    rate_hz: float
    window_length: int
    notes: list[str]


def _usable_samples(profile: DeskProfile, recording: Recording, where: str) -> _Samples:
    """Check the recording's times and values (:class:`ConfigError` at ``where`` when they
    cannot be characterized) and leave out the bad samples."""
    t = np.asarray(recording.t, dtype=float)
    k = len(t)
    needs = f"characterize needs at least {2 * QUIET_WINDOW_S:g} s"
    if k < 2:
        raise ConfigError(where, f"{k} sample(s): too short, {needs}")
    flat = recording.wrench.reshape(k, -1)
    fs = _sample_rate(profile, t, where)
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
    return _Samples(t, flat, good, resultant, fs, n_w, notes)


def _sample_rate(profile: DeskProfile, t: np.ndarray, where: str) -> float:
    """The recording's sample rate from its median step, within MIN/MAX_RATE_HZ."""
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
    return fs


def _measure_noise_and_drift(
    result: Characterization, profile: DeskProfile, windows: QuietWindows
) -> None:
    """Each channel's and the resultant's noise and drift over the quiet windows, or the
    reason they could not be measured (into ``result``)."""
    if windows.count == 0:
        result.noise_reason = "no quiet window found: record the desk untouched for a while"
        result.drift_reason = result.noise_reason
        return
    channels = profile.channel_names()  # (a load cell's one, a six-axis sensor's six)
    sensor_units = ["N·m" if moment else "N" for moment in profile.moment_channels()]
    quiet = windows.quiet
    result.noise = channel_noise(channels, sensor_units, windows.channel_var[quiet])
    result.total_noise = channel_noise(
        list(RESULTANT), list(RESULTANT_UNITS), windows.resultant_var[quiet]
    )
    constant = [n.channel for n in result.noise if n.sigma == 0.0]
    if constant:
        result.notes.append(
            f"{', '.join(constant)} did not change in the quiet windows: their noise is "
            "below their resolution (σ reads 0)"
        )
    quiet_t = windows.t[quiet]
    span = float(quiet_t[-1] - quiet_t[0])
    if windows.count < 3 or span < MIN_DRIFT_SPAN_S:
        result.drift_reason = (
            f"quiet windows span {span:.1f} s; drift needs at least {MIN_DRIFT_SPAN_S:g} s"
        )
        return
    result.drift = channel_drift(channels, sensor_units, quiet_t, windows.channel_mean[quiet])
    result.total_drift = channel_drift(
        list(RESULTANT), list(RESULTANT_UNITS), quiet_t, windows.resultant_mean[quiet]
    )


def _measure_modes(
    result: Characterization, data: _Samples, windows: QuietWindows, baseline: np.ndarray
) -> None:
    """The natural frequencies from the free decay and the cut-off they suggest, or the
    reason there are none (into ``result``)."""
    sigma = resultant_sigma(data.resultant, windows)
    segments = free_decay_segments(data.resultant - baseline, data.good, data.rate_hz, sigma)
    spectrum = decay_spectrum(data.resultant, segments, data.rate_hz, sigma)
    result.segments = spectrum.segments_used
    result.spectrum_hz, result.spectrum = spectrum.frequencies_hz, spectrum.power
    if spectrum.segments_used == 0:
        result.modes_reason = (
            "no free decay found: knock the desk sideways (or tap it) a few times, "
            f"leaving at least {MIN_SEGMENT_S + GUARD_S:g} s of quiet after each"
        )
    else:
        found = spectral_modes(spectrum, data.rate_hz)
        result.modes = found.modes
        if found.harmonics:
            result.notes.append(
                f"{found.harmonics} spectral peak(s) at multiples of a mode left out"
            )
        if not result.modes:
            result.modes_reason = "the free decay shows no clear spectral peak"
    if result.modes:
        lowest = result.modes[0].frequency_hz
        result.lowest_mode_hz = lowest
        result.suggested_cutoff_hz = round(CUTOFF_RATIO * lowest, 2)


def _measure_inertia(
    result: Characterization,
    profile: DeskProfile,
    recording: Recording,
    baseline: np.ndarray,
    rate_hz: float,
) -> None:
    """The desk's moments of inertia from its accelerometers (into ``result``)."""
    fit = fit_inertia(profile, recording, baseline, rate_hz)
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
