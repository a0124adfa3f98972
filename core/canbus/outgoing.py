"""The python-can message this host sends (the live source's polls and requests, the
emulator's replies): a plain :class:`can.Message` whose deep copy is built directly.

python-can's ``virtual`` bus deep-copies every message it sends, once per other bus on the
channel. ``Message.__deepcopy__`` copies its ``data`` bytearray through ``copy.deepcopy``,
which goes through ``copyreg`` and ``__reduce_ex__`` (about 10 µs a message here, 70 % of a
send): four boards polled at 1.2 kHz send 12 frames a sample, so it was ~130 µs of the
host's CPU a sample. :meth:`OutgoingMessage.__deepcopy__` makes the same copy (a new
``Message``, its own ``bytearray`` of the data, every field equal) in about a third of the
time. Other interfaces (socketcan, pcan, …) read the message's fields to build their own
frame and never copy it: for them it is an ordinary ``Message``.

Imported only where python-can is in use (a CAN source or the emulator).
"""

from __future__ import annotations

from copy import deepcopy
from typing import Any

import can


class OutgoingMessage(can.Message):
    """A :class:`can.Message` cheap to deep-copy; its copy is a plain ``can.Message``."""

    __slots__ = ()

    def __deepcopy__(self, memo: dict[int, Any] | None) -> can.Message:
        channel = self.channel
        if not isinstance(channel, str | int | None):  # (str, int: immutable, shared)
            channel = deepcopy(channel, memo)
        return can.Message(
            timestamp=self.timestamp,
            arbitration_id=self.arbitration_id,
            is_extended_id=self.is_extended_id,
            is_remote_frame=self.is_remote_frame,
            is_error_frame=self.is_error_frame,
            channel=channel,
            dlc=self.dlc,
            data=bytearray(self.data),
            is_fd=self.is_fd,
            is_rx=self.is_rx,
            bitrate_switch=self.bitrate_switch,
            error_state_indicator=self.error_state_indicator,
        )
