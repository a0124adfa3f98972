"""Read any recording a user hands us: CSV, NPZ, or a CAN log decoded through the profile."""

from __future__ import annotations

from pathlib import Path

from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.recording import RECORDING_SUFFIXES, Recording, read_recording
from hapticdesk.files.yamlfile import ConfigError, regular_file_size


def read_any_recording(path: str | Path, profile: DeskProfile) -> Recording:
    """A recording (.csv, .npz) or a CAN log (.asc, .blf, .log, .trc, candump text).

    CAN logs are decoded through the profile's ``can:`` section; python-can and cantools are
    imported only for them.
    """
    if Path(path).suffix.lower() in RECORDING_SUFFIXES:
        return read_recording(path, profile.sensor_names)  # (it checks the file itself)
    # before the CAN log's own checks: a missing file is said so, not taken for a CAN log
    # the profile cannot decode
    regular_file_size(path, "the recording")
    from hapticdesk.canbus.logs import is_can_log, read_can_log  # (python-can: lazily)

    if profile.can is None and not is_can_log(path):
        raise ConfigError(
            str(path),
            f"not a recording hapticdesk reads: expected {' or '.join(RECORDING_SUFFIXES)}, or "
            "a CAN log (.asc, .blf, .log, .trc, candump text) with a desk profile that has a "
            "`can:` section",
        )
    return read_can_log(path, profile)
