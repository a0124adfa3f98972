"""How a desk's board is read: the profile's ``serial:`` section and the ``--source`` spec.

    serial:                        # in the desk profile (all optional)
      port: /dev/ttyUSB0           # or any pyserial URL (socket://host:port, rfc2217://…)
      baud: 921600
      scale: [2.1e-5, 2.0e-5, 2.2e-5, 2.1e-5]   # N per count, per channel (or one number)
      zero: [8120, -310, 455, 12]  # counts taken off before scaling (or one number)
      offsets_us: [0, 229, 458, 687]  # when the board cannot say them in its hello
      simultaneous: false          # true: the channels are sampled together (no offsets)

    --source serial:/dev/ttyUSB0?baud=921600&scale=2.1e-5&hello_timeout_s=10

A value in the spec wins over the profile's. A channel's value is ``(reading - zero) * scale``
in the unit the profile's sensors use (N, N·m). Every error names where: the profile's
``file:line:column``, or ``--source:1:COLUMN`` in the spec.
"""

from __future__ import annotations

import urllib.parse
from dataclasses import dataclass

import numpy as np

from hapticdesk.boards.hello import MAX_OFFSET_US
from hapticdesk.errors import ConfigError, Position
from hapticdesk.files.marked_values import MarkedDict, MarkedList
from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.validators import check_keys, flag, number, require_mapping, vector

SECTION_KEYS = {
    "port",
    "baud",
    "scale",
    "zero",
    "offsets_us",
    "simultaneous",
    "hello_timeout_s",
    "silent_timeout_s",
    "reconnect_timeout_s",
}
MAX_BAUD = 12_000_000
MAX_WAIT_S = 3600.0


@dataclass(frozen=True)
class SerialSettings:
    """Where and how the board is read (module docstring). ``scale``/``zero`` (C,) per
    board channel; ``offsets_us`` (C,) or None."""

    port: str
    baud: int
    scale: np.ndarray
    zero: np.ndarray
    offsets_us: tuple[float, ...] | None = None
    simultaneous: bool = False
    hello_timeout_s: float = 5.0
    silent_timeout_s: float = 1.0
    reconnect_timeout_s: float = 10.0
    scale_given: bool = True  # False: no `scale` anywhere, the board's values taken as newtons


def board_channels(profile: DeskProfile) -> list[str]:
    """The channels a board of ``profile`` sends, in order: every sensor's raw channels
    (``<sensor>_<channel>``), then the accelerometers' (``acc_x`` …) when the desk has some."""
    return profile.channel_names() + profile.accelerometer_columns()


def spec_mapping(spec: str) -> tuple[str, MarkedDict]:
    """``PORT?key=value&…`` -> (PORT, the options as a mapping whose positions are columns of
    ``--source``); a list is comma-separated numbers."""
    port, _, query = spec.partition("?")
    options = MarkedDict()
    options.position = Position("--source", 1, 1)
    options.key_positions, options.value_positions = {}, {}
    column = len("serial:") + len(port) + 2
    for part in query.split("&") if query else []:
        key, sep, value = part.partition("=")
        key_at = Position("--source", 1, column)
        value_at = Position("--source", 1, column + len(key) + 1)
        column += len(part) + 1
        if not sep:
            raise ConfigError(key_at, f"expected KEY=VALUE after `?` in the source, found `{part}`")
        key = urllib.parse.unquote(key)
        if key in options:
            raise ConfigError(key_at, f"`{key}` is given twice in the source")
        options.key_positions[key] = key_at
        options.value_positions[key] = value_at
        options[key] = _query_value(urllib.parse.unquote(value), value_at)
    return port, options


def _query_value(text: str, where: Position) -> object:
    if text.lower() in ("true", "false"):
        return text.lower() == "true"
    items: list[object] = []
    for word in text.split(","):
        try:
            items.append(int(word) if word.lstrip("+-").isdigit() else float(word))
        except ValueError:
            items.append(word)
    if len(items) == 1:
        return items[0]
    out = MarkedList(items)
    out.position, out.item_positions = where, [where] * len(items)
    return out


def serial_settings(profile: DeskProfile, spec: str) -> SerialSettings:
    """The settings for reading ``profile``'s board from ``spec`` (the text after
    ``serial:``), the spec's options over the profile's ``serial:`` section."""
    port, given = spec_mapping(spec)
    merged = _merged_options(profile, given)
    port = port or str(merged.get("port") or "")
    if not port:
        raise ConfigError(
            "--source",
            "no serial port: write --source serial:PORT (e.g. serial:/dev/ttyUSB0, "
            "serial:COM3) or give `port` in the profile's `serial:`",
        )
    what = "`serial`"
    baud = number(merged, "baud", what, default=115200.0, minimum=50.0, maximum=MAX_BAUD)
    if baud != int(baud):
        raise ConfigError(merged.where("baud"), f"`baud` must be a whole number, found {baud:g}")
    n = len(board_channels(profile))
    scale = _per_channel(merged, "scale", n, 1.0)
    if not (np.isfinite(scale).all() and (scale != 0).all()):
        raise ConfigError(merged.where("scale"), "`scale` must be finite and not 0")
    zero = _per_channel(merged, "zero", n, 0.0)
    offsets = None
    if "offsets_us" in merged:
        offsets = tuple(vector(merged["offsets_us"], merged.where("offsets_us"), "`offsets_us`", n))
        if not all(0 <= v < MAX_OFFSET_US for v in offsets):
            raise ConfigError(
                merged.where("offsets_us"),
                f"`offsets_us` must be 0 or more and under {MAX_OFFSET_US:g} µs, found {offsets}",
            )
    simultaneous = flag(merged, "simultaneous", what, default=False)
    if simultaneous and offsets is not None:
        raise ConfigError(
            merged.where("simultaneous"), "give `offsets_us` or `simultaneous: true`, not both"
        )
    waits = {
        key: number(merged, key, what, default=default, minimum=0.01, maximum=MAX_WAIT_S)
        for key, default in (
            ("hello_timeout_s", 5.0),
            ("silent_timeout_s", 1.0),
            ("reconnect_timeout_s", 10.0),
        )
    }
    return SerialSettings(
        port=port,
        baud=int(baud),
        scale=scale,
        zero=zero,
        offsets_us=offsets,
        simultaneous=simultaneous,
        scale_given="scale" in merged,
        **waits,
    )


def _merged_options(profile: DeskProfile, given: MarkedDict) -> MarkedDict:
    """The profile's ``serial:`` section with the spec's options (``given``) over it, each
    key checked and keeping where it was written."""
    section = profile.serial
    merged = MarkedDict()
    if section is not None:
        section = require_mapping(section, str(profile.path or profile.name), "`serial`")
        check_keys(section, SECTION_KEYS, "the profile's `serial`")
        merged.update(section)
        merged.position = section.position
        merged.key_positions = dict(section.key_positions)
        merged.value_positions = dict(section.value_positions)
    else:
        merged.position, merged.key_positions, merged.value_positions = given.position, {}, {}
    check_keys(given, SECTION_KEYS - {"port"}, "the `serial:` source's options")
    merged.update(given)
    merged.key_positions.update(given.key_positions)
    merged.value_positions.update(given.value_positions)
    return merged


def _per_channel(mapping: MarkedDict, key: str, n: int, default: float) -> np.ndarray:
    """One number for every channel, or a list of ``n``."""
    if key not in mapping:
        return np.full(n, default)
    value = mapping[key]
    if isinstance(value, list):
        return np.array(vector(value, mapping.where(key), f"`{key}`", n))
    return np.full(n, number(mapping, key, "`serial`"))
