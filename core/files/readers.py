"""Read any recording a user hands us: CSV, NPZ, or a CAN log decoded through the profile."""

from __future__ import annotations

from pathlib import Path

from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.recording import RECORDING_SUFFIXES, Recording, read_recording
from hapticdesk.files.yamlfile import regular_file_size


def read_any_recording(path: str | Path, profile: DeskProfile) -> Recording:
    """A recording (.csv, .npz) or a CAN log (.asc, .blf, .log, .trc, candump text).

    CAN logs are decoded through the profile's ``can:`` section; python-can and cantools are
    imported only for them.
    """
    # first: a missing file is said so, not taken for a CAN log the profile cannot decode
    regular_file_size(path, "the recording")
    if Path(path).suffix.lower() in RECORDING_SUFFIXES:
        return read_recording(path, profile.sensor_names)
    from hapticdesk.canbus.logs import read_can_log  # a CAN log: imports python-can lazily

    return read_can_log(path, profile)
