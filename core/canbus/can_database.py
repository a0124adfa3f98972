"""The profile's CAN database (DBC, KCD, SYM, ARXML through cantools), loaded within bounds
(its size, a DBC's message lengths and signal count checked before cantools builds it), and
``Message.Signal`` references resolved against it: each a classic, unmultiplexed signal; a
counter unsigned; a reading's scale finite and non-zero. Part of :mod:`.config_reader`."""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

from hapticdesk.canbus.config import AtiSensor, SignalRef, SignalSensor
from hapticdesk.errors import ConfigError, Position
from hapticdesk.files.marked_values import MarkedDict
from hapticdesk.files.profile import DeskProfile

#: the largest CAN database read: a desk's is a few kB and a whole vehicle's DBC a few MB;
#: cantools holds some 70 times the file's size while parsing it
MAX_DATABASE_BYTES = 8 * 1024 * 1024


def load_database(section: MarkedDict, profile: DeskProfile) -> tuple[Path, Any]:
    raw = section["database"]
    where = section.where("database")
    if not isinstance(raw, str) or not raw:
        raise ConfigError(where, f"`database` must be a file name, found {raw!r}")
    path = Path(raw)
    if not path.is_absolute() and profile.path is not None:
        path = profile.path.parent / path
    if not path.is_file():
        raise ConfigError(where, f"CAN database {raw!r} not found (looked for {path})")
    size = path.stat().st_size
    if size > MAX_DATABASE_BYTES:
        raise ConfigError(
            where,
            f"CAN database {path} is {size / 2**20:.1f} MiB; at most "
            f"{MAX_DATABASE_BYTES / 2**20:g} MiB is read (a desk's database is a few kB: keep "
            "its messages in a file of their own)",
        )
    if path.suffix.lower() == ".dbc":
        _check_dbc_sizes(path)
    import cantools  # lazily: only a desk on CAN needs it

    try:
        database = cantools.database.load_file(str(path), strict=True)
    except Exception as err:  # cantools raises many kinds (ParseError, UnsupportedDatabaseFormat…)
        raise ConfigError(where, f"cannot load CAN database {path}: {_load_failure(err)}") from None
    if not hasattr(database, "get_message_by_name"):
        raise ConfigError(where, f"{path} is a diagnostics database, expected a CAN database")
    return path, database


#: a DBC message's length in bytes at most this (a CAN FD frame's); cantools builds tables
#: as long as the length it is told (BO_ … : 99999999 ran past a minute and 2.8 GB)
MAX_FRAME_BYTES = 64
#: signals in a DBC at most this many (2000 messages of 64 signals took cantools 25 s, 475 MB)
MAX_DBC_SIGNALS = 10_000
_DBC_MESSAGE = re.compile(r"^\s*BO_\s+\d+\s+\w+\s*:\s*(\d+)")
_DBC_SIGNAL = re.compile(r"^\s*SG_\s")


def _check_dbc_sizes(path: Path) -> None:
    """Refuse, at its line, a DBC message longer than a CAN frame, and a DBC with more
    signals than any desk has, before cantools builds them (file:line:column)."""
    signals = 0
    with path.open(encoding="utf-8", errors="replace") as lines:  # (size checked above)
        for number, line in enumerate(lines, 1):
            found = _DBC_MESSAGE.match(line)
            if found and (len(found[1]) > 3 or int(found[1]) > MAX_FRAME_BYTES):
                raise ConfigError(
                    Position(str(path), number, found.start(1) + 1),
                    f"message length {found[1]} bytes; a CAN frame carries at most "
                    f"{MAX_FRAME_BYTES} (CAN FD)",
                )
            signals += bool(_DBC_SIGNAL.match(line))
            if signals > MAX_DBC_SIGNALS:
                raise ConfigError(
                    Position(str(path), number, 1),
                    f"more than {MAX_DBC_SIGNALS:,} signals: a desk's database has a few dozen "
                    "(keep its messages in a file of their own)",
                )


def _load_failure(err: BaseException) -> str:
    """Why cantools could not load a database, never empty: cantools reports each format it
    tried (``DBC: "…"``), and an exception without a message (a MemoryError) reads as ``""``."""
    tried = [
        (name.upper(), getattr(err, f"e_{name}", None))
        for name in ("arxml", "dbc", "kcd", "sym", "cdd")
    ]
    parts = [f'{name}: "{_exception_text(e)}"' for name, e in tried if e is not None]
    return ", ".join(parts) if parts else _exception_text(err)


def _exception_text(err: BaseException) -> str:
    text = str(err).strip()
    if text:
        return text
    if isinstance(err, MemoryError):
        return "it needs more memory than there is"
    return f"an unexplained {type(err).__name__}"


def check_scales(
    groups: list[SignalSensor | AtiSensor], database: Any, database_path: Path | None
) -> None:
    """A signal read as a force, moment or acceleration needs a finite non-zero scale: with
    scale 0 every frame decodes as the offset (and encoding one divides by zero)."""
    for group in groups:
        if not isinstance(group, SignalSensor):
            continue
        for ref in group.axes.values():
            message = database.get_message_by_name(ref.message)
            scale = float(message.get_signal_by_name(ref.signal).scale)
            if scale == 0.0 or not math.isfinite(scale):
                raise ConfigError(
                    ref.where,
                    f"signal `{ref}` of CAN database {database_path} has scale {scale:g}; "
                    "expected a finite non-zero scale (with 0 every frame reads the same)",
                )


def signal_ref(value: Any, where: Position | str, what: str, database: Any) -> SignalRef:
    if not isinstance(value, str) or "." not in value:
        raise ConfigError(where, f"{what} must be `Message.Signal`, found {value!r}")
    message_name, _, signal_name = value.rpartition(".")
    ref = SignalRef(message_name, signal_name, where)
    if database is None:
        raise ConfigError(where, f"{what} names signal {value} but `can` gives no `database`")
    try:
        message = database.get_message_by_name(message_name)
    except KeyError:
        names = sorted(m.name for m in database.messages)
        raise ConfigError(
            where,
            f"{what}: the database has no message `{message_name}`; it has "
            f"{', '.join(names[:12])}{' …' if len(names) > 12 else ''}",
        ) from None
    if message.is_container:
        raise ConfigError(where, f"{what}: `{message_name}` is a container message (unsupported)")
    if message.length > 8:
        raise ConfigError(
            where,
            f"{what}: `{message_name}` is {message.length} bytes long; only classic CAN "
            "frames of up to 8 bytes are supported",
        )
    try:
        signal = message.get_signal_by_name(signal_name)
    except KeyError:
        raise ConfigError(
            where,
            f"{what}: message `{message_name}` has no signal `{signal_name}`; it has "
            + ", ".join(s.name for s in message.signals),
        ) from None
    if signal.multiplexer_ids or signal.is_multiplexer:
        raise ConfigError(where, f"{what}: `{value}` is multiplexed (unsupported)")
    return ref


def counter_modulus(database: Any, ref: SignalRef) -> int:
    signal = database.get_message_by_name(ref.message).get_signal_by_name(ref.signal)
    if signal.is_float or signal.is_signed:
        raise ConfigError(ref.where, f"counter {ref} must be an unsigned integer signal")
    return 1 << int(signal.length)
