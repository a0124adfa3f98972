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
