"""A force plate's analog channels as readings: zeroed over the file's ZERO frames, in N and
N·m by each channel's unit (TYPE 1's centre of pressure and free moment made the wrench about
the top's centre), and each channel's noise, measured over the ZERO frames or robustly from
the whole file. See :mod:`.forceplate` for the rules."""

from __future__ import annotations

import numpy as np

from hapticdesk.files.c3d import LENGTH_UNITS, C3DFile, force_factor, moment_factor
from hapticdesk.files.plate_parameters import ForcePlate

#: a channel's noise is never taken below this share of its largest reading (an exactly
#: repeating, quantised channel measures 0; the covariances need a positive one)
NOISE_FLOOR_SHARE = 1e-7
NOISE_FLOOR = 1e-6
#: the fewest changing samples the noise is measured on without ZERO frames (else the floor)
MIN_NOISE_SAMPLES = 100
_MAD_TO_SIGMA = 1.4826  # a normal distribution's σ per median absolute deviation


def plate_readings(file: C3DFile, plate: ForcePlate) -> np.ndarray:
    """The plate's channels (k, n), TYPE_CHANNELS order, in N, N·m (TYPE 4: the channel's
    own unit), zeroed over the ZERO frames; TYPE 1's six made into Fx … Mz about the top's
    centre."""
    raw = file.analogs[plate.channels].T.astype(float)  # (k, n), a copy
    zero = file.zero_range()
    if zero is not None:
        a, b = zero
        keep = slice(None) if plate.type != 1 else [0, 1, 2, 5]  # (not a centre of pressure)
        raw[:, keep] -= raw[a:b, keep].mean(axis=0)
    units = [file.units[c] for c in plate.channels]
    if plate.type in (2, 3):
        kinds = ["force"] * 8 if plate.type == 3 else ["force"] * 3 + ["moment"] * 3
        return raw * _factors(units, kinds, file.point_metres)
    if plate.type == 4:
        return raw
    factors = _factors(units, ["force"] * 3 + ["length"] * 2 + ["moment"], file.point_metres)
    f, x, y = raw[:, :3] * factors[:3], raw[:, 3] * factors[3], raw[:, 4] * factors[4]
    tz = raw[:, 5] * factors[5]
    # the force at (x, y, 0) about the top's centre, with the free moment about z
    moment = np.stack([y * f[:, 2], -x * f[:, 2], x * f[:, 1] - y * f[:, 0] + tz], axis=1)
    return np.concatenate([f, moment], axis=1)


def _factors(units: list[str], kinds: list[str], point_metres: float) -> np.ndarray:
    """SI factors per channel: by its unit where it names one, else N, N·POINT:UNITS, or
    POINT:UNITS (ezc3d's reading)."""
    out = []
    for unit, kind in zip(units, kinds, strict=True):
        if kind == "force":
            factor = force_factor(unit)
            out.append(1.0 if factor is None else factor)
        elif kind == "moment":
            factor = moment_factor(unit)
            out.append(point_metres if factor is None else factor)
        else:
            out.append(LENGTH_UNITS.get(unit.strip().lower(), point_metres))
    return np.array(out)


def channel_noise(file: C3DFile, readings: np.ndarray) -> np.ndarray:
    """Each channel's noise σ (n,) in its reading's unit: the spread over the ZERO frames,
    or, without them, robustly from the second differences over the whole file where the
    channel changes (their median absolute deviation: a person's force is smooth over three
    samples at 1 kHz, its slope cancels); never below a floor (NOISE_FLOOR, and
    NOISE_FLOOR_SHARE of the channel's largest reading)."""
    zero = file.zero_range()
    if zero is not None and zero[1] - zero[0] >= 2:
        sigma = readings[zero[0] : zero[1]].std(axis=0, ddof=1)
    else:
        sigma = np.zeros(readings.shape[1])
        for j in range(readings.shape[1]):
            # (samples that exactly repeat the one before say nothing of the noise: a plate
            # written 0 while unloaded, a noise-free file)
            x = readings[:, j]
            second = (x[2:] - 2.0 * x[1:-1] + x[:-2])[x[2:] != x[1:-1]]
            if second.size >= MIN_NOISE_SAMPLES:
                mad = np.median(np.abs(second - np.median(second)))
                sigma[j] = _MAD_TO_SIGMA * mad / np.sqrt(6.0)  # (var of x₊ − 2x + x₋: 6σ²)
    largest = np.abs(readings).max(axis=0) if len(readings) else np.zeros(readings.shape[1])
    return np.maximum(sigma, np.maximum(NOISE_FLOOR_SHARE * largest, NOISE_FLOOR))
