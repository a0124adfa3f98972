"""The commands, one module each (``hapticdesk COMMAND``), and the argument types they share."""

from __future__ import annotations

import argparse


def seed_number(text: str) -> int:
    """``--seed``: a whole number ≥ 0 (numpy's generators refuse a negative one, which had
    reached the user of ``record`` and ``emulate`` as an unexpected error)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a whole number >= 0, found {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be a whole number >= 0, found {value}")
    return value


#: the fastest CAN bit rate there is (CAN FD's data phase); classic CAN stops at 1 Mbit/s
MAX_BITRATE = 8_000_000


def bit_rate(text: str) -> int:
    """``--bitrate``: a CAN bit rate, 1 to :data:`MAX_BITRATE` bit/s (0 or −1 were passed to
    the interface, or taken for "the profile's" without a word)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected bits per second, found {text!r}") from None
    if not 1 <= value <= MAX_BITRATE:
        raise argparse.ArgumentTypeError(
            f"expected 1 to {MAX_BITRATE} bits per second, found {value}"
        )
    return value
