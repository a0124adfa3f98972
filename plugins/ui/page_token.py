"""Where the page's token comes from: ``--token-file PATH``, ``--token`` or
``$HAPTICDESK_UI_TOKEN``, for ``ui`` and ``run --ui`` alike.

A token on the command line is in every other user's ``ps``; the environment and a file are
not. The file's first line, stripped, is the token (a trailing newline from ``echo`` or an
editor is no part of it). Errors name the file, never the token: the token is in no error,
log line or address. Imports nothing heavy (``run --ui`` reads it while the run is built).
"""

from __future__ import annotations

import os
import stat
import sys
from pathlib import Path

from hapticdesk.errors import ConfigError

#: where the token comes from when no option gives it
TOKEN_ENV = "HAPTICDESK_UI_TOKEN"
#: the most of a token file read: a token is a line, not a file's worth
MAX_TOKEN_FILE_BYTES = 4096
#: what the warning about a token file others can read starts with
SAID_BY = "hapticdesk ui"


def page_token(token: str | None, token_file: str | None) -> tuple[str | None, str]:
    """The page's token and where it came from (the name an error about it gives: the
    file's path, ``--token`` or the environment variable): ``token_file`` (``--token-file``),
    else ``token`` (``--token``), else ``$HAPTICDESK_UI_TOKEN``; None without any. Both
    options at once are refused: which one would be used is no guess to leave a reader."""
    if token and token_file:
        raise ConfigError(
            "--token-file", "give the token one way: --token-file or --token, not both"
        )
    if token_file:
        return read_token_file(token_file), token_file
    if token:
        return token, "--token"
    return os.environ.get(TOKEN_ENV) or None, TOKEN_ENV


def read_token_file(path: str) -> str:
    """The token in the file at ``path``: its first line, stripped. A ConfigError naming the
    file when it is missing, unreadable, not text or has no token on its first line; a
    warning on stderr when other users may read it (as ssh says of a key)."""
    file = Path(path).expanduser()
    try:
        with file.open("rb") as f:
            mode = os.fstat(f.fileno()).st_mode
            if not stat.S_ISREG(mode):  # (a FIFO or a device would be read for ever)
                raise ConfigError(path, "the page's token file (--token-file) is no plain file")
            head = f.read(MAX_TOKEN_FILE_BYTES)
    except OSError as err:
        raise ConfigError(
            path, f"cannot read the page's token file (--token-file): {err.strerror or err}"
        ) from None
    if len(head) == MAX_TOKEN_FILE_BYTES and b"\n" not in head:
        raise ConfigError(
            path,
            f"the page's token file (--token-file) has a first line over "
            f"{MAX_TOKEN_FILE_BYTES} bytes: expected a token on a line of its own",
        )
    try:
        first = head.decode("utf-8").splitlines()[0] if head else ""
    except UnicodeDecodeError:
        raise ConfigError(path, "the page's token file (--token-file) is not text") from None
    token = first.strip()
    if not token:
        where = "is empty" if not head.strip() else "has no token on its first line"
        raise ConfigError(path, f"the page's token file (--token-file) {where}")
    if os.name == "posix" and mode & 0o077:
        print(
            f"{SAID_BY}: warning: {path}: the page's token file is open to other users "
            f"(mode {stat.S_IMODE(mode):04o}); `chmod 600 {path}` keeps the token yours",
            file=sys.stderr,
        )
    return token
