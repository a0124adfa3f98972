"""The desk profile's ``estimation:`` read and checked, and fitted to the desk: the filters'
cut-offs follow ``desk: natural_frequency_hz`` unless given, ``max_gap_s`` the sample rate
unless given, and every cut-off is checked against the sample rate at the key that set it.
Part of :mod:`.profile_reader`."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from hapticdesk.errors import ConfigError
from hapticdesk.files.marked_values import MarkedDict
from hapticdesk.files.profile import LOWPASS_PER_NATURAL_FREQUENCY, METHODS, EstimationSettings
from hapticdesk.files.validators import (
    MAX_REACH_M,
    MAX_SETTING_FORCE_N,
    check_keys,
    choice,
    flag,
    flag_or_auto,
    number,
    require_mapping,
)

#: the lowest low-pass cut-off as a share of the sample rate (0.0048 Hz at 1.2 kHz): the
#: estimator's noise gains sum impulse responses of 8 × rate / cut-off samples (2 million)
MIN_CUTOFF_PER_RATE = 4e-6
#: the shortest gap in sample times, in sample intervals, where ``max_gap_s`` is not given
#: (its default, 0.05 s, is under one interval below 20 Hz)
GAP_INTERVALS = 2.5
#: the steepest force slope a setting may name, N/s (10 kN within a millisecond)
MAX_FORCE_SLOPE_N_S = 1e7
#: physical bounds on `estimation` values that are not windows: beyond them a value is a
#: typing mistake, and its square (a covariance) or inverse would overflow downstream
MAX_ESTIMATION = {
    "noise_force_n": 1e3,
    "noise_moment_nm": 1e3,
    "drift_force_n_per_min": 1e3,
    "drift_moment_nm_per_min": 1e3,
    # forces a threshold names: no desk's beyond MAX_SETTING_FORCE_N (10 kN)
    "tare_quiet_n": MAX_SETTING_FORCE_N,
    "contact_force_n": MAX_SETTING_FORCE_N,
    "release_hysteresis_n": MAX_SETTING_FORCE_N,
    "touch_threshold_n": MAX_SETTING_FORCE_N,
    "release_threshold_n": MAX_SETTING_FORCE_N,
    "drift_max_n": MAX_SETTING_FORCE_N,
    "still_n": MAX_SETTING_FORCE_N,
    "release_slope_n_s": MAX_FORCE_SLOPE_N_S,
    "phase_rate_n_s": MAX_FORCE_SLOPE_N_S,
    # a point's 1-σ, metres: none beyond the room a desk stands in
    "max_sigma_m": MAX_REACH_M,
    # a finger's drift, m/s: a flick across a desk is a few
    "contact_speed_m_s": 10.0,
    "min_normal_cos": 1.0,  # (a cosine; 1 itself is refused below)
}
#: the longest estimation windows, seconds (the paper's: 0.166 s, a 1 s tare, 5 s settle)
MAX_WINDOW_S = {
    "diff_window_s": 5.0,
    "tare_s": 60.0,
    "max_gap_s": 60.0,
    "settle_s": 3600.0,
    "object_settle_s": 3600.0,
    "drift_settle_s": 3600.0,
}

#: `estimation` numbers that may be 0 (measured at the tare, or off); the others must be above
MAY_BE_ZERO = frozenset(
    {
        "noise_force_n",
        "noise_moment_nm",
        "min_normal_cos",
        "contact_speed_m_s",
        "release_hysteresis_n",
        "release_slope_n_s",
        "drift_settle_s",
        "object_settle_s",
        "drift_force_n_per_min",
        "drift_moment_nm_per_min",
    }
)
#: the low-passes' cut-offs, bounded by the sample rate (:func:`fit_to_desk`), not a number
CUTOFF_KEYS = ("force_lowpass_hz", "diff_lowpass_hz", "detect_lowpass_hz")


def read_estimation(doc: MarkedDict) -> EstimationSettings:
    """The profile's ``estimation:`` (the paper's defaults for what it leaves out)."""
    if "estimation" not in doc:
        return EstimationSettings()
    return _estimation(doc["estimation"], doc.where("estimation"))


def fit_to_desk(
    settings: EstimationSettings, doc: MarkedDict, rate: float, natural: float | None
) -> EstimationSettings:
    """``settings`` with the low-passes below the desk's lowest mode ``natural`` (Hz) unless
    ``estimation`` gives them, checked against the sample ``rate``."""
    given = doc["estimation"] if isinstance(doc.get("estimation"), MarkedDict) else {}
    if natural is not None:
        # the filters must stay below the desk's lowest mode, as the paper's 4.77 Hz stays
        # below its 5.9 Hz (ratio 0.81); a value given in `estimation` wins
        cutoff = round(LOWPASS_PER_NATURAL_FREQUENCY * natural, 2)
        for key in ("force_lowpass_hz", "diff_lowpass_hz"):
            if key not in given:
                settings = replace(settings, **{key: cutoff})
    if "max_gap_s" not in given:
        # a gap must be longer than a sample interval, or a slow desk (a 20 Hz converter)
        # restarts its filters at every sample: two and a half intervals at least
        settings = replace(settings, max_gap_s=max(settings.max_gap_s, GAP_INTERVALS / rate))
    _check_against_rate(settings, rate, doc, given)
    return settings


def _check_against_rate(
    settings: EstimationSettings, rate: float, doc: MarkedDict, given: Any
) -> None:
    """The filters' cut-offs against the sample rate, each at the place that set it: the
    key in `estimation`, else `desk: natural_frequency_hz` (which sets the low-passes), else
    `sample_rate_hz` (a default cut-off)."""
    estimation = given if isinstance(given, MarkedDict) else None
    lowest = MIN_CUTOFF_PER_RATE * rate
    for key in CUTOFF_KEYS:
        value = getattr(settings, key)
        given_here = estimation is not None and key in estimation
        if estimation is not None and given_here:
            where, source = estimation.where(key), f"`{key}` in `estimation`"
        elif (
            key != "detect_lowpass_hz"
            and isinstance(doc.get("desk"), MarkedDict)
            and ("natural_frequency_hz" in doc["desk"])
        ):
            where = doc["desk"].where("natural_frequency_hz")
            source = f"`{key}` (from `desk: natural_frequency_hz`)"
        else:
            where, source = doc.where("sample_rate_hz"), f"the default `{key}`"
        # the fast detection low-pass is held below 0.45 × the rate by the estimator itself
        # (its default, 30 Hz, is above a slow desk's Nyquist); given, it is a frequency no
        # sampled signal has (1e300 was taken)
        if (key != "detect_lowpass_hz" or given_here) and value >= rate / 2:
            raise ConfigError(
                where,
                f"{source} is {value:g} Hz; a low-pass cut-off must be below half the sample "
                f"rate (the Nyquist frequency, {rate / 2:g} Hz at `sample_rate_hz` {rate:g})",
            )
        if value < lowest:
            raise ConfigError(
                where,
                f"{source} is {value:g} Hz; a cut-off must be at least {lowest:g} Hz "
                f"({MIN_CUTOFF_PER_RATE:g} × `sample_rate_hz` {rate:g}): lower, the filter "
                "would take longer to settle than any touch lasts",
            )


def _estimation(item: Any, where: Any) -> EstimationSettings:
    m = require_mapping(item, where, "`estimation`")
    defaults = EstimationSettings()
    allowed = set(EstimationSettings.__dataclass_fields__)
    check_keys(m, allowed, "`estimation`")
    values: dict[str, Any] = {}
    for key in allowed:
        if key == "method":
            values[key] = choice(m, "method", METHODS, "`estimation`", default=defaults.method)
        elif key == "sway_compensation":
            values[key] = flag_or_auto(m, key, "`estimation`")
        elif key == "second_finger":
            values[key] = flag(m, key, "`estimation`", default=defaults.second_finger)
        elif key in ("zeroed", "hold_jumps"):
            values[key] = flag(m, key, "`estimation`", default=getattr(defaults, key))
        elif key in m:
            values[key] = number(
                m,
                key,
                "`estimation`",
                minimum=0.0,
                exclusive_minimum=key not in MAY_BE_ZERO,
                maximum=MAX_WINDOW_S.get(key, MAX_ESTIMATION.get(key)),
            )
    settings = EstimationSettings(**values)
    if settings.min_normal_cos >= 1.0:
        raise ConfigError(m.where("min_normal_cos"), "`min_normal_cos` must be below 1")
    if settings.zeroed and not (settings.noise_force_n > 0 or settings.noise_moment_nm > 0):
        raise ConfigError(
            m.where("zeroed"),
            "`zeroed: true` (the readings come zeroed: no tare) needs the channels' noise, "
            "which a tare would have measured: give `noise_force_n` and `noise_moment_nm`",
        )
    if settings.release_hysteresis_n >= settings.contact_force_n:
        raise ConfigError(
            m.where("release_hysteresis_n"),
            "`release_hysteresis_n` must be smaller than `contact_force_n`",
        )
    return settings
