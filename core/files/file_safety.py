"""Opening a file a user named without harm: a regular file only (a named pipe would block,
/dev/zero never end), inside the folders reads are confined to while the browser UI checks
a layout (:func:`reads_confined_to`), and text strictly UTF-8, every fault at its place."""

from __future__ import annotations

import contextlib
import os
import stat
from collections.abc import Iterator
from contextvars import ContextVar
from pathlib import Path

from hapticdesk.errors import ConfigError, Position

_FILE_KINDS = (
    (stat.S_ISREG, "a regular file"),
    (stat.S_ISDIR, "a directory"),
    (stat.S_ISFIFO, "a named pipe (FIFO)"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
)


def file_kind(mode: int) -> str:
    """What a file of ``os.stat`` mode ``mode`` is, for a message (``a directory`` …)."""
    return next((name for test, name in _FILE_KINDS if test(mode)), "not a regular file")


#: while set (:func:`reads_confined_to`), the only folders files are read from
_READ_ROOTS: ContextVar[tuple[Path, ...] | None] = ContextVar("read_roots", default=None)


@contextlib.contextmanager
def reads_confined_to(*roots: str | Path) -> Iterator[None]:
    """Within it, a file outside ``roots`` (after symlinks and ``..``) is not read: the
    browser UI checks a layout a page sent, and its `desk: /etc/passwd` had been read and
    quoted back in the error."""
    token = _READ_ROOTS.set(tuple(Path(r).resolve() for r in roots))
    try:
        yield
    finally:
        _READ_ROOTS.reset(token)


def check_confined(path: str | Path, what: str, where: Position | str | None = None) -> None:
    """ConfigError (at ``where``, else at the path) when reads are confined
    (:func:`reads_confined_to`) and ``path`` lies outside every root.

    Called *before* anything looks at the path (exists, is a file or a folder, its listing):
    the answer for a path outside is then the same whether it exists or not (``layouts: {x:
    /etc/shadow}`` had been accepted where a missing file was "no such file", and
    ``templates: /root`` had named a folder in it)."""
    roots = _READ_ROOTS.get()
    if roots is None:
        return
    real = Path(path).resolve()
    if not any(real.is_relative_to(root) for root in roots):
        raise ConfigError(
            str(path) if where is None else where,
            f"{what} lies outside the layout's folder: a layout edited in the browser reads "
            "files there only (and the shipped profiles and examples)",
        )


def regular_file_size(path: str | Path, what: str) -> int:
    """The size in bytes of ``path``, which must be a regular file (after symlinks).

    Checked before opening: opening a named pipe with no writer blocks forever, a device
    such as /dev/zero never ends, a directory cannot be read. ``what`` names the file in the
    message (``the file``, ``the stroke file`` …).
    """
    check_confined(path, what)
    try:
        info = os.stat(path)
    except OSError as err:
        raise ConfigError(str(path), f"cannot read {what}: {err.strerror or err}") from None
    if not stat.S_ISREG(info.st_mode):
        raise ConfigError(
            str(path), f"cannot read {what}: it is {file_kind(info.st_mode)}, not a regular file"
        )
    return info.st_size


def decode_utf8(data: bytes, file: str, kind: str) -> str:
    """Strict UTF-8 (a UTF-8 byte-order mark is allowed); otherwise say where and why.

    ``kind`` names what the text should be (``YAML``, ``a CSV stroke`` …) in the messages.
    """
    for bom, name in (
        (b"\xff\xfe", "UTF-16"),
        (b"\xfe\xff", "UTF-16"),
        (b"\x00\x00\xfe\xff", "UTF-32"),
    ):
        if data.startswith(bom):
            raise ConfigError(Position(file, 1, 1), f"the file is {name} text; save it as UTF-8")
    nul = data.find(b"\x00")
    if nul >= 0:
        raise ConfigError(
            byte_position(data, nul, file),
            f"a NUL byte: this is a binary file (or UTF-16 text), not {kind} saved as UTF-8",
        )
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        raise ConfigError(
            byte_position(data, err.start, file),
            f"not UTF-8 text: byte 0x{data[err.start]:02x} ({err.reason}); save the file as UTF-8",
        ) from None


def byte_position(data: bytes, offset: int | None, file: str) -> Position:
    """Line and column (in characters) of byte ``offset`` of ``data`` (its end when None)."""
    offset = len(data) if offset is None else offset
    line_start = data.rfind(b"\n", 0, offset) + 1
    column = len(data[line_start:offset].decode("utf-8", "replace")) + 1
    return Position(file, data.count(b"\n", 0, offset) + 1, column)
