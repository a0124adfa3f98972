"""Read any recording a user hands us: CSV, NPZ, a CAN log decoded through the profile, or a
C3D file's force plates (:mod:`hapticdesk.files.forceplate`).

It stands above :mod:`hapticdesk.files` and :mod:`hapticdesk.canbus` because it picks between
them by the file's kind; the files layer itself reads no CAN log."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from hapticdesk.errors import ConfigError
from hapticdesk.files.c3d import is_c3d
from hapticdesk.files.file_safety import regular_file_size
from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.recording import Recording
from hapticdesk.files.recording_io import RECORDING_SUFFIXES, RecordingBlocks, read_recording

# a recording's sample interval may differ from its profile's by this share (a sensor's clock,
# the jitter of CAN timestamps); beyond it the filters and windows, made for the profile's
# rate, are wrong (a 600 Hz recording on a 1200 Hz profile halves every time constant)
RATE_TOLERANCE = 0.1
RATE_CHECK_SAMPLES = 20_000  # the first samples the interval is measured on
RATE_CHECK_MIN = 20  # fewer intervals than this say nothing about the rate
# the time column in another unit than seconds, by the factor it is off
TIME_UNITS = {1e3: "milliseconds", 1e6: "microseconds", 1e9: "nanoseconds"}


def check_sample_rate(t: np.ndarray, profile: DeskProfile, where: str) -> None:
    """Refuse a recording whose samples ``t`` do not come at the profile's rate (its median
    interval, within :data:`RATE_TOLERANCE`): the estimator's filters are made for that rate,
    and a time column in milliseconds would turn every sample into a gap."""
    steps = np.diff(np.asarray(t[:RATE_CHECK_SAMPLES], float))
    steps = steps[np.isfinite(steps) & (steps > 0)]
    if len(steps) < RATE_CHECK_MIN:
        return
    interval = float(np.median(steps))
    off = interval * profile.sample_rate_hz  # the interval in the profile's intervals

    def near(factor: float) -> bool:
        return abs(math.log(off / factor)) <= math.log1p(RATE_TOLERANCE)

    if near(1.0):
        return
    unit = next((u for f, u in TIME_UNITS.items() if near(f)), None)
    said = (
        f"the time column t looks like {unit}; it must be seconds"
        if unit is not None
        else f"record at {profile.sample_rate_hz:g} Hz, or give the desk a profile with "
        f"sample_rate_hz: {1 / interval:.4g}"
    )
    raise ConfigError(
        where,
        f"samples come every {interval:.4g} s ({1 / interval:.4g} Hz, the median interval of "
        f"the first {len(steps) + 1:,}), but desk {profile.name!r} samples at "
        f"{profile.sample_rate_hz:g} Hz (its sample_rate_hz), which its filters are made for: "
        + said,
    )


def open_recording_blocks(path: str | Path, profile: DeskProfile) -> RecordingBlocks:
    """A CSV or NPZ recording to stream in blocks (``replay:``, ``record``), its first block
    read and checked to come at the profile's rate (:func:`check_sample_rate`); the file is
    closed when it is refused."""
    recording = RecordingBlocks(path, profile.sensor_names, channel_names=profile.channel_names())
    try:
        check_sample_rate(recording.first_times(), profile, str(path))
    except ConfigError:
        recording.close()
        raise
    return recording


def read_any_recording(
    path: str | Path, profile: DeskProfile, *, at_profile_rate: bool = True
) -> Recording:
    """A recording (.csv, .npz), a CAN log (.asc, .blf, .log, .trc, candump text) or a C3D
    file (its plates the desk's sensors ``plate<N>``: :mod:`.forceplate`), whose
    samples come at the profile's rate (:func:`check_sample_rate`) unless
    ``at_profile_rate`` is False (``characterize`` measures a desk's rate itself).

    CAN logs are decoded through the profile's ``can:`` section; python-can and cantools are
    imported only for them.
    """
    recording = _read(path, profile)
    if at_profile_rate:
        check_sample_rate(recording.t, profile, str(path))
    return recording


def _read(path: str | Path, profile: DeskProfile) -> Recording:
    if is_c3d(path):  # a force plate's C3D file: its plates are the desk's sensors
        from hapticdesk.files.forceplate import read_plate_recording  # (ezc3d: lazily)

        return read_plate_recording(path, profile)
    if Path(path).suffix.lower() in RECORDING_SUFFIXES:
        # (it checks the file itself)
        return read_recording(path, profile.sensor_names, channel_names=profile.channel_names())
    # before the CAN log's own checks: a missing file is said so, not taken for a CAN log
    # the profile cannot decode
    regular_file_size(path, "the recording")
    from hapticdesk.canbus.logs.desk_samples import read_can_log
    from hapticdesk.canbus.logs.formats import is_can_log  # (python-can: lazily)

    if profile.can is None and not is_can_log(path):
        raise ConfigError(
            str(path),
            f"not a recording hapticdesk reads: expected {' or '.join(RECORDING_SUFFIXES)}, or "
            "a CAN log (.asc, .blf, .log, .trc, candump text) with a desk profile that has a "
            "`can:` section",
        )
    return read_can_log(path, profile)
