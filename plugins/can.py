"""The ``can`` source: a live desk on a CAN bus (python-can), ``can:INTERFACE:CHANNEL``.

    hapticdesk run --layout L --source can:socketcan:can0

Only registered here; :mod:`hapticdesk.canbus.source` (and python-can with it) is imported
when a run uses it, never for a simulated or replayed desk.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from hapticdesk.hookspecs import hookimpl

if TYPE_CHECKING:  # the hooks are loaded for every command, even `--help`: no numpy here
    from hapticdesk.files.profile import DeskProfile
    from hapticdesk.runtime.source import Source


def open_can(argument: str, profile: DeskProfile, **options: Any) -> Source:
    """``can:INTERFACE:CHANNEL`` (e.g. socketcan:can0, virtual:desk) on ``profile``; a bare
    ``can:`` uses the interface and channel of the profile's ``can:`` section."""
    from hapticdesk.canbus.source import open_can_source

    options.pop("speed", None)  # a live bus runs at its own pace
    return open_can_source(argument or "can", profile, **options)


@hookimpl
def register_sources(register: Any) -> None:
    register("can", open_can, "a live desk on a CAN bus: can:INTERFACE:CHANNEL (python-can)")
