"""The commands, one module each (``hapticdesk COMMAND``), and the argument types they share."""

from __future__ import annotations

import argparse

#: the fastest CAN bit rate there is (CAN FD's data phase); classic CAN stops at 1 Mbit/s
MAX_BITRATE = 8_000_000


def _whole_number(text: str, low: int, high: int | None, wanted: str) -> int:
    """``text`` as a whole number from ``low`` to ``high`` (None: no end); else argparse's
    error, ``wanted`` saying what was expected."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{wanted}, found {text!r}") from None
    if value < low or (high is not None and value > high):
        raise argparse.ArgumentTypeError(f"{wanted}, found {value}")
    return value


def seed_number(text: str) -> int:
    """``--seed``: a whole number ≥ 0 (numpy's generators refuse a negative one, which had
    reached the user of ``record`` and ``emulate`` as an unexpected error)."""
    return _whole_number(text, 0, None, "must be a whole number >= 0")


def bit_rate(text: str) -> int:
    """``--bitrate``: a CAN bit rate, 1 to :data:`MAX_BITRATE` bit/s (0 or −1 were passed to
    the interface, or taken for "the profile's" without a word)."""
    return _whole_number(text, 1, MAX_BITRATE, f"expected 1 to {MAX_BITRATE} bits per second")
