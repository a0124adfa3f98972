"""The messages this host sends: a deep copy (what python-can's virtual bus hands every other
bus) is the same frame as python-can's own copy, a plain Message with its own data."""

from __future__ import annotations

import copy

import can
import pytest

from hapticdesk.canbus.outgoing import OutgoingMessage

FIELDS = (
    "timestamp",
    "arbitration_id",
    "is_extended_id",
    "is_remote_frame",
    "is_error_frame",
    "channel",
    "dlc",
    "data",
    "is_fd",
    "is_rx",
    "bitrate_switch",
    "error_state_indicator",
)


@pytest.mark.parametrize(
    "fields",
    [
        {"arbitration_id": 0x200, "data": b"", "is_extended_id": False},  # an ATI poll
        {"arbitration_id": 0x201, "data": bytes(range(6)), "is_extended_id": False},
        {"arbitration_id": 0x1ABCDEF, "data": b"\xff" * 8, "channel": "can0", "is_rx": False},
        {"arbitration_id": 0x7FF, "is_remote_frame": True, "dlc": 3, "channel": 1},
        {"arbitration_id": 0x5, "data": bytes(64), "is_fd": True, "bitrate_switch": True},
        {"arbitration_id": 0x20000080, "is_error_frame": True, "channel": ["vcan", 0]},
    ],
)
def test_a_deep_copy_is_the_frame_python_can_would_copy(fields):
    theirs = copy.deepcopy(can.Message(timestamp=12.5, **fields))
    ours = OutgoingMessage(timestamp=12.5, **fields)
    copied = copy.deepcopy(ours)
    assert type(copied) is can.Message
    assert {f: getattr(copied, f) for f in FIELDS} == {f: getattr(theirs, f) for f in FIELDS}
    assert copied.equals(theirs, timestamp_delta=0)
    ours.data[:] = b"\x55" * len(ours.data)  # the copy's data is its own
    assert copied.data == theirs.data
    if isinstance(fields.get("channel"), list):
        assert copied.channel is not ours.channel  # a mutable channel is copied too


def test_the_virtual_bus_delivers_it_unchanged():
    sender = can.Bus(interface="virtual", channel="outgoing-test", preserve_timestamps=True)
    receiver = can.Bus(interface="virtual", channel="outgoing-test")
    try:
        sent = OutgoingMessage(
            timestamp=3.25, arbitration_id=0x200, data=b"\x00\x01" * 4, is_extended_id=False
        )
        sender.send(sent)
        got = receiver.recv(timeout=1.0)
        assert got is not None and type(got) is can.Message
        assert {f: getattr(got, f) for f in FIELDS if f not in ("channel", "is_rx")} == {
            f: getattr(sent, f) for f in FIELDS if f not in ("channel", "is_rx")
        }
        assert got.channel == "outgoing-test" and got.is_rx and got.data is not sent.data
    finally:
        sender.shutdown()
        receiver.shutdown()
