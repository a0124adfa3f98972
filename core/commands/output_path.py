"""Files a command writes, checked before the work that fills them: a folder, a missing folder
or a format that cannot be written is a clear error at once, not a traceback after the work.
What the check cannot foresee (no permission, a full disk) is :func:`cannot_write`'s error,
which ``contacts``, ``simulate`` and ``record`` share; what a full disk cut short is removed
(:func:`remove_partial`)."""

from __future__ import annotations

import contextlib
from pathlib import Path

from hapticdesk.errors import ConfigError


def check_output_path(
    path: Path,
    where: str,
    suffixes: tuple[str, ...] | None = None,
    what: str = "the output",
    reads: dict[str, str | Path | None] | None = None,
) -> None:
    """Raise ConfigError at ``where`` (the file or the flag naming it) unless ``path`` can be
    a file to write: not a folder, in a folder that exists, with one of ``suffixes``, and
    none of the files the command reads (``reads``: what each is, as "the recording", and
    its path; ``contacts rec.csv -o rec.csv`` replaced the recording with its contacts)."""
    if suffixes is not None and path.suffix.lower() not in suffixes:
        raise ConfigError(
            where,
            f"{what} is written as {' or '.join(suffixes)}: expected a file name ending in "
            f"{' or '.join(suffixes)}, found {path.name!r}",
        )
    target = "" if where == str(path) else f" {path}"  # (a flag names it: say which file)
    if path.is_dir():
        raise ConfigError(where, f"cannot write{target}: it is a folder; expected a file name")
    if not path.parent.is_dir():
        raise ConfigError(where, f"cannot write{target}: the folder {path.parent} does not exist")
    for read, other in (reads or {}).items():
        if other is not None and _same_file(path, Path(other)):
            raise ConfigError(
                where,
                f"cannot write{target}: it is {read}, which this command reads; give another "
                "file name",
            )


def _same_file(path: Path, other: Path) -> bool:
    try:
        return path.samefile(other)
    except OSError:  # (either does not exist, or cannot be looked at: not the same file)
        return False


def cannot_write(path: Path | str, err: OSError) -> ConfigError:
    """The error for an output that could not be written after all."""
    return ConfigError(str(path), f"cannot write: {err.strerror or err}")


def remove_partial(output: Path) -> None:
    """A recording cut short by a full disk is removed: a reader would take the part for
    the whole (b5a43bd left truncated recordings behind)."""
    with contextlib.suppress(OSError):
        output.unlink(missing_ok=True)


def partial_removed(output: Path, err: OSError) -> ConfigError:
    """The error for an output that could not be written and was removed."""
    return ConfigError(
        str(output), f"cannot write: {err.strerror or err} (the partial file was removed)"
    )
