"""C3D files, read through ezc3d (the optional ``c3d`` extra): parameters, analog channels in
SI units, their times and the baseline named by ``FORCE_PLATFORM:ZERO``.

This module knows the file, not the plates: :mod:`.forceplate` turns a plate's parameters
into a desk. ezc3d applies ``ANALOG:OFFSET``, ``SCALE`` (and ``SCALE2``) and ``GEN_SCALE``
as it reads (``(stored − |offset|) · scale · gen_scale``, the C3D rule), so the values taken
here are already in each channel's ``ANALOG:UNITS``; what is left is the units themselves
(``Nmm`` or ``Nm``, ``POINT:UNITS`` mm or m) and the zero. ezc3d is imported only when a
C3D file is read; without it the user is told how to install it.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hapticdesk.errors import ConfigError
from hapticdesk.files.file_safety import regular_file_size

C3D_SUFFIX = ".c3d"
INSTALL_HINT = "pip install 'hapticdesk[c3d]'"

#: metres per unit of ``POINT:UNITS`` (the C3D default, when the parameter is empty, is mm)
LENGTH_UNITS = {"mm": 1e-3, "cm": 1e-2, "dm": 0.1, "m": 1.0, "in": 0.0254, "inch": 0.0254}
#: newtons per unit of a force channel (``ANALOG:UNITS``)
FORCE_UNITS = {"n": 1.0, "kn": 1e3, "lbf": 4.4482216152605, "lb": 4.4482216152605}
# a moment's unit: a force unit, an optional separator, a length unit ("Nmm", "N.m", "N·m")
_MOMENT_UNIT = re.compile(r"^(n|kn|lbf|lb)\s*[.*·\-]?\s*(mm|cm|dm|m|in)$")


def is_c3d(path: str | Path) -> bool:
    """True for a file whose name says C3D."""
    return Path(path).suffix.lower() == C3D_SUFFIX


def import_ezc3d() -> Any:
    """The ezc3d module, or a ConfigError naming the extra to install."""
    try:
        import ezc3d
    except ImportError:
        raise ConfigError(
            "ezc3d",
            f"reading C3D files needs ezc3d, which is not installed: {INSTALL_HINT}",
        ) from None
    return ezc3d


def force_factor(unit: str) -> float | None:
    """Newtons per unit of a force channel's ``unit``, or None when it is not a force unit
    (a type-2 plate written with ``V``: its channels are taken in newtons, as ezc3d does)."""
    return FORCE_UNITS.get(unit.strip().lower())


def moment_factor(unit: str) -> float | None:
    """N·m per unit of a moment channel's ``unit`` (``Nmm``, ``N.m``, ``N·m`` …), or None
    when it is not a moment unit."""
    found = _MOMENT_UNIT.match(unit.strip().lower().replace("·", "."))
    if found is None:
        return None
    return FORCE_UNITS[found.group(1)] * LENGTH_UNITS[found.group(2)]


@dataclass(frozen=True)
class C3DFile:
    """One C3D file's parameters and analog channels (a whole file: ezc3d reads it whole).

    ``analogs`` (n_channels, k) in each channel's ``ANALOG:UNITS`` (scaled by ezc3d), ``t``
    (k,) seconds from the capture's start (the file's first frame as its header counts it,
    so two files cut from one capture keep their times), ``point_metres`` metres per unit of
    ``POINT:UNITS`` (which CORNERS, ORIGIN and a type-4 CAL_MATRIX's moments are in).
    """

    path: Path
    parameters: dict[str, Any]
    analogs: np.ndarray
    t: np.ndarray
    analog_rate_hz: float
    analogs_per_frame: int
    point_metres: float
    units: tuple[str, ...]  # each analog channel's ANALOG:UNITS (+ UNITS2 …), '' if none
    labels: tuple[str, ...]

    @property
    def where(self) -> str:
        return str(self.path)

    def parameter(self, group: str, name: str) -> Any | None:
        """A parameter's value, or None when the group or the parameter is missing."""
        found = self.parameters.get(group, {}).get(name)
        return None if found is None else found.get("value")

    def numbers(self, group: str, name: str) -> np.ndarray | None:
        """A numeric parameter as a float array in its C3D shape (first index fastest, as
        ezc3d gives it), or None when missing or empty."""
        value = self.parameter(group, name)
        if value is None:
            return None
        try:
            array = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise ConfigError(
                self.where, f"{group}:{name} must hold numbers, found {value!r}"
            ) from None
        return None if array.size == 0 else array

    def zero_range(self) -> tuple[int, int] | None:
        """The analog samples ``[a, b)`` of the ``FORCE_PLATFORM:ZERO`` frames (1-based 3D
        frames of this file; 0 reads as 1, the C3D rule), or None for ``[0, 0]`` or no
        parameter (the channels come zeroed). A range past the file's end is an error."""
        zero = self.numbers("FORCE_PLATFORM", "ZERO")
        if zero is None:
            return None
        values = zero.reshape(-1)[:2] if zero.ndim == 1 else zero[:2, 0]
        if len(values) < 2 or not np.isfinite(values).all():
            raise ConfigError(
                self.where,
                f"FORCE_PLATFORM:ZERO must be two frame numbers, found {zero.tolist()}",
            )
        first, last = int(values[0]), int(values[1])
        if first == 0 and last == 0:
            return None
        first = max(first, 1)
        frames = self.analogs.shape[1] // max(self.analogs_per_frame, 1)
        if last < first or first > frames:
            raise ConfigError(
                self.where,
                f"FORCE_PLATFORM:ZERO names frames {int(values[0])}–{last} for the baseline, "
                f"but the file holds frames 1–{frames}: expected a range within them, or "
                "[0, 0] for channels that come zeroed",
            )
        last = min(last, frames)
        return (first - 1) * self.analogs_per_frame, last * self.analogs_per_frame


def open_c3d(path: str | Path) -> C3DFile:
    """Read a C3D file (ConfigError, never a traceback, for a missing, unreadable or broken
    file, or a missing ezc3d)."""
    path = Path(path)
    regular_file_size(path, "the C3D file")  # (a FIFO would block, a folder is no file)
    ezc3d = import_ezc3d()
    try:
        c3d = ezc3d.c3d(str(path))
    except Exception as err:  # ezc3d raises RuntimeError, IOError, … for a broken file
        raise ConfigError(
            str(path), f"not a C3D file ezc3d can read ({type(err).__name__}: {err})"
        ) from None
    parameters = c3d["parameters"]
    analogs = np.asarray(c3d["data"]["analogs"], dtype=float)
    analogs = analogs.reshape(analogs.shape[-2], analogs.shape[-1]) if analogs.size else analogs
    header = c3d["header"]
    rate = float(header["analogs"]["frame_rate"] or 0.0)
    if analogs.size == 0 or rate <= 0 or not math.isfinite(rate):
        raise ConfigError(str(path), "the C3D file holds no analog channels (no force plate data)")
    point_rate = float(header["points"]["frame_rate"] or 0.0)
    per_frame = max(1, round(rate / point_rate)) if point_rate > 0 else 1
    first = float(header["analogs"]["first_frame"] or 0)
    t = (first + np.arange(analogs.shape[1])) / rate
    unit_text = _first_text(parameters, "POINT", "UNITS") or "mm"
    metres = LENGTH_UNITS.get(unit_text.strip().lower())
    if metres is None:
        raise ConfigError(
            str(path),
            f"POINT:UNITS is {unit_text!r}; expected one of {', '.join(LENGTH_UNITS)} (the "
            "unit of the plates' CORNERS and ORIGIN)",
        )
    n = analogs.shape[0]
    return C3DFile(
        path=path,
        parameters=parameters,
        analogs=analogs,
        t=t,
        analog_rate_hz=rate,
        analogs_per_frame=per_frame,
        point_metres=metres,
        units=_channel_texts(parameters, "UNITS", n),
        labels=_channel_texts(parameters, "LABELS", n),
    )


def _first_text(parameters: dict[str, Any], group: str, name: str) -> str | None:
    value = parameters.get(group, {}).get(name, {}).get("value")
    if isinstance(value, list | tuple) and value and isinstance(value[0], str):
        return value[0]
    return value if isinstance(value, str) else None


def _channel_texts(parameters: dict[str, Any], name: str, n: int) -> tuple[str, ...]:
    """``ANALOG:<name>`` then ``<name>2``, ``<name>3`` … (the C3D way past 255 channels),
    one text per channel ('' where none is given)."""
    group = parameters.get("ANALOG", {})
    texts: list[str] = []
    for suffix in ["", *map(str, range(2, 10))]:
        value = group.get(f"{name}{suffix}", {}).get("value")
        if value is None:
            break
        texts += [str(v).strip() for v in (value if isinstance(value, list | tuple) else [])]
    return tuple((texts + [""] * n)[:n])
