"""Which live CAN bus a source spec names, and why one could not be opened.

``can:INTERFACE:CHANNEL`` (or ``INTERFACE:CHANNEL``, or ``can`` for the profile's) names any
interface python-can offers; :class:`CanSourceError` is what a live CAN source raises when the
bus cannot be opened, or was lost and did not come back. ``emulate`` says a bus it cannot open
the same way (:func:`bus_cannot_open`).
"""

from __future__ import annotations

from typing import NamedTuple

from hapticdesk.canbus.config import CanConfig
from hapticdesk.errors import ConfigError


def bus_cannot_open(interface: str, channel: str | None, err: Exception) -> str:
    """Why python-can could not open ``interface`` ``channel``, for a message (a live source
    and ``emulate`` say it alike). An interface's own bug when its driver library is missing
    (python-can's kvaser raises NameError: canGetNumberOfChannels) is as much a bus that
    cannot be opened, said as such."""
    import can  # lazily: only a CAN source or the emulator needs python-can

    said = f"cannot open CAN interface {interface!r} channel {channel!r}: "
    if isinstance(err, (can.CanError, OSError, ValueError, ImportError, TypeError)):
        return said + str(err)
    return (
        said + f"python-can failed with {type(err).__name__}: {err} (is the interface's driver "
        "library installed?)"
    )


class CanSourceError(ConfigError):
    """The bus could not be opened, or was lost and did not come back."""


class BusName(NamedTuple):
    """A python-can interface and its channel (None: the interface's default)."""

    interface: str
    channel: str | None


def parse_spec(spec: str, config: CanConfig | None) -> BusName:
    """``can:INTERFACE:CHANNEL`` (or ``INTERFACE:CHANNEL``, or ``can`` for the profile's)."""
    text = spec[4:] if spec.startswith("can:") else ("" if spec == "can" else spec)
    interface, _, channel = text.partition(":")
    interface = interface or (config.interface if config else None) or ""
    if not interface:
        raise CanSourceError(
            spec,
            "no CAN interface: write --source can:INTERFACE:CHANNEL (e.g. can:socketcan:can0, "
            "can:virtual:desk) or give `interface` and `channel` in the profile's `can:`",
        )
    return BusName(interface, channel or (config.channel if config else None))
