"""The board's hello line and the line checksum (the format is docs/serial.md's contract).

A board says who it is before its samples, and again whenever the host sends ``?``::

    @hapticdesk/1 rate=1000 channels=fl_fz,fr_fz,bl_fz,br_fz stamp=seq offsets_us=0,229,458,687

``rate`` (Hz) and ``channels`` (the desk's raw channels, in the order the sample lines carry
them) are required; ``stamp`` is ``seq`` (a sequence number counting sample periods, the
default) or ``us`` (the board's microseconds); ``offsets_us`` gives each channel's sampling
time after the stamp, or ``offsets=line`` says every sample line ends with them;
``checksum=xor`` makes a checksum on every line compulsory; ``wrap`` is where the stamp wraps
(default 2³², an Arduino's ``uint32_t`` and ``micros()``); ``board`` is a free name.

Any line may end with ``*HH``: the XOR of every byte before the ``*``, as two hex digits
(NMEA's checksum, without the ``$``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

from hapticdesk.errors import ConfigError

MAGIC = "@hapticdesk/1"
STAMPS = ("seq", "us")
DEFAULT_WRAP = 2**32
#: a stamp has at most this many digits (2³² - 1 has 10)
MAX_STAMP_DIGITS = 12
#: each channel's offset (µs) after the stamp must be below this: one second
MAX_OFFSET_US = 1_000_000.0
MAX_CHANNELS = 256
HELLO_KEYS = ("rate", "channels", "stamp", "offsets_us", "offsets", "checksum", "wrap", "board")


@dataclass(frozen=True)
class BoardHello:
    """What a board said about itself in its hello line."""

    rate_hz: float
    channels: tuple[str, ...]
    stamp: str = "seq"  # "seq" or "us"
    #: each channel's sampling time after the line's stamp, µs (None: the board gives none)
    offsets_us: tuple[float, ...] | None = None
    offsets_per_line: bool = False  # each sample line ends with its channels' offsets
    checksum_required: bool = False
    wrap: int = DEFAULT_WRAP
    board: str = ""

    @property
    def stamp_units_per_s(self) -> float:
        """Stamp units in a second: the rate for a sequence number, 10⁶ for microseconds."""
        return self.rate_hz if self.stamp == "seq" else 1e6

    @property
    def fields(self) -> int:
        """Comma-separated fields of a sample line: the stamp, the values, the offsets."""
        n = len(self.channels)
        return 1 + n + (n if self.offsets_per_line else 0)

    def text(self) -> str:
        """The hello line (without checksum or newline) that says this."""
        words = [MAGIC, f"rate={self.rate_hz:g}", "channels=" + ",".join(self.channels)]
        if self.stamp != "seq":
            words.append(f"stamp={self.stamp}")
        if self.offsets_per_line:
            words.append("offsets=line")
        elif self.offsets_us is not None:
            words.append("offsets_us=" + ",".join(f"{v:g}" for v in self.offsets_us))
        if self.checksum_required:
            words.append("checksum=xor")
        if self.wrap != DEFAULT_WRAP:
            words.append(f"wrap={self.wrap}")
        if self.board:
            words.append(f"board={self.board}")
        return " ".join(words)


def checksum(content: bytes) -> int:
    """The XOR of ``content``'s bytes (what a line's ``*HH`` carries)."""
    value = 0
    for byte in content:
        value ^= byte
    return value


def with_checksum(content: str) -> str:
    """``content`` followed by its ``*HH``."""
    return f"{content}*{checksum(content.encode('ascii')):02X}"


def parse_hello(text: str, where: str) -> BoardHello:
    """The hello in ``text`` (one line, checksum removed); ConfigError naming ``where`` (the
    port and line) and what was expected."""
    given = _hello_words(text, where)
    rate = _number(given["rate"], "rate", where)
    if not 0 < rate <= 1e6:
        raise ConfigError(
            where, f"hello: `rate` must be above 0 and at most 1e6 Hz, found {rate:g}"
        )
    channels = tuple(given["channels"].split(","))
    if not all(c and c.isprintable() for c in channels) or len(channels) > MAX_CHANNELS:
        raise ConfigError(
            where,
            f"hello: `channels` must be 1 to {MAX_CHANNELS} names separated by commas, "
            f"found `{given['channels'][:80]}`",
        )
    stamp = given.get("stamp", "seq")
    if stamp not in STAMPS:
        raise ConfigError(
            where, f"hello: `stamp` must be one of {', '.join(STAMPS)}, found `{stamp}`"
        )
    offsets = _offsets(given, len(channels), where)
    check = given.get("checksum")
    if check not in (None, "xor"):
        raise ConfigError(where, f"hello: `checksum` can only be `xor`, found `{check}`")
    return BoardHello(
        rate_hz=rate,
        channels=channels,
        stamp=stamp,
        offsets_us=offsets.offsets_us,
        offsets_per_line=offsets.per_line,
        checksum_required=check == "xor",
        wrap=_wrap(given, where),
        board=given.get("board", ""),
    )


def _hello_words(text: str, where: str) -> dict[str, str]:
    """The hello's ``KEY=VALUE`` words by key, after its magic word; each key known and
    given once, ``rate`` and ``channels`` given."""
    words = text.split()
    if not words or words[0] != MAGIC:
        found = words[0] if words else "nothing"
        raise ConfigError(where, f"a hello starts with `{MAGIC}`, found `{found[:40]}`")
    given: dict[str, str] = {}
    for word in words[1:]:
        key, sep, value = word.partition("=")
        if not sep or not value:
            raise ConfigError(where, f"hello: expected KEY=VALUE, found `{word[:40]}`")
        if key not in HELLO_KEYS:
            raise ConfigError(
                where, f"hello: unknown key `{key[:40]}`; known: {', '.join(HELLO_KEYS)}"
            )
        if key in given:
            raise ConfigError(where, f"hello: `{key}` given twice")
        given[key] = value
    for key in ("rate", "channels"):
        if key not in given:
            raise ConfigError(where, f"hello: missing `{key}=` (the hello was: {text[:120]})")
    return given


class _Offsets(NamedTuple):
    """When each channel was sampled: fixed offsets after the stamp (µs, one a channel), or
    on every line (``per_line``), or neither (all at the stamp)."""

    offsets_us: tuple[float, ...] | None
    per_line: bool


def _offsets(given: dict[str, str], channels: int, where: str) -> _Offsets:
    """The hello's ``offsets=line`` or ``offsets_us=...`` (at most one of them)."""
    if "offsets" in given:
        if given["offsets"] != "line":
            raise ConfigError(
                where, f"hello: `offsets` can only be `line`, found `{given['offsets']}`"
            )
        if "offsets_us" in given:
            raise ConfigError(where, "hello: give `offsets=line` or `offsets_us=...`, not both")
        return _Offsets(None, True)
    if "offsets_us" not in given:
        return _Offsets(None, False)
    offsets = tuple(_number(v, "offsets_us", where) for v in given["offsets_us"].split(","))
    if len(offsets) != channels:
        raise ConfigError(
            where,
            f"hello: `offsets_us` must give one offset per channel ({channels}), "
            f"found {len(offsets)}",
        )
    if not all(0 <= v < MAX_OFFSET_US for v in offsets):
        raise ConfigError(
            where,
            "hello: each of `offsets_us` must be 0 or more (the stamp is the first "
            f"channel's time) and under {MAX_OFFSET_US:g} µs, found {given['offsets_us']}",
        )
    return _Offsets(offsets, False)


def _wrap(given: dict[str, str], where: str) -> int:
    """Where the board's stamp wraps around (``wrap=``, DEFAULT_WRAP without)."""
    if "wrap" not in given:
        return DEFAULT_WRAP
    w = _number(given["wrap"], "wrap", where)
    if w != int(w) or not 2**8 <= w <= 10**MAX_STAMP_DIGITS:
        raise ConfigError(
            where, f"hello: `wrap` must be a whole number from 256 to 1e12, found {w:g}"
        )
    return int(w)


def _number(text: str, key: str, where: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise ConfigError(where, f"hello: `{key}` must be a number, found `{text[:40]}`")
    return value
