"""The ``serial`` source: a board on a serial line (pyserial), ``serial:PORT[?key=value&…]``.

    hapticdesk run --layout L --source serial:/dev/ttyUSB0?baud=921600

The board prints one sample a line (docs/serial.md). Only registered here;
:mod:`hapticdesk.boards.source` (and pyserial with it) is imported when a run uses it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from hapticdesk.hookspecs import hookimpl

if TYPE_CHECKING:  # the hooks are loaded for every command, even `--help`: no numpy here
    from hapticdesk.files.profile import DeskProfile
    from hapticdesk.runtime.source import Source


def open_serial(argument: str, profile: DeskProfile, **options: Any) -> Source:
    """``serial:PORT?baud=…`` on ``profile``; a bare ``serial:`` uses the port of the
    profile's ``serial:`` section. A live board runs at its own pace (``speed`` ignored)."""
    from hapticdesk.boards.source import open_serial_source

    return open_serial_source(argument, profile)


@hookimpl
def register_sources(register: Any) -> None:
    register(
        "serial",
        open_serial,
        "a board printing samples on a serial line: serial:PORT[?baud=...] (pyserial)",
    )
