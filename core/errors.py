"""What a user's file or option did wrong, and where: :class:`ConfigError` at a
:class:`Position`, and :class:`LayoutWarning` for what works but was likely not meant.

The bottom layer: every room raises these, so this module imports nothing of the project
and nothing heavy (``hapticdesk --help`` loads it).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass


@dataclass(frozen=True)
class Position:
    """A place in a file: 1-based line and column."""

    file: str
    line: int
    column: int

    def __str__(self) -> str:
        return f"{self.file}:{self.line}:{self.column}"


#: the longest message a :class:`ConfigError` keeps: what it quotes of the file (a value it
#: found, 500 kB of one line) is cut in the middle beyond it, so an error stays one line
MAX_MESSAGE_CHARS = 1000
_KEPT_HEAD, _KEPT_TAIL = 700, 200


def shortened(message: str) -> str:
    """``message`` at most about :data:`MAX_MESSAGE_CHARS` long: its middle left out, and
    said so, when it is longer (its start says what was expected, its end what follows)."""
    if len(message) <= MAX_MESSAGE_CHARS:
        return message
    left_out = len(message) - _KEPT_HEAD - _KEPT_TAIL
    return f"{message[:_KEPT_HEAD]} … ({left_out:,} characters left out) … {message[-_KEPT_TAIL:]}"


class ConfigError(ValueError):
    """A user-written file is wrong. ``str(err)`` is ``file:line:column: what was expected``
    (a message that quotes too much of the file is :func:`shortened`)."""

    def __init__(self, where: Position | str | None, message: str) -> None:
        message = shortened(message)
        self.where = where
        self.message = message
        super().__init__(f"{where}: {message}" if where is not None else message)


class LayoutWarning(UserWarning):
    """A layout that works, but likely not as its author meant. A plugin's check of its
    options says it with ``warnings.warn(LayoutWarning(...))``; the layout reader collects it
    into :attr:`Layout.warnings` (``check`` shows them, ``run`` logs them). Anywhere else,
    e.g. when a run builds the actions again, it is not shown a second time."""


warnings.filterwarnings("ignore", category=LayoutWarning)
