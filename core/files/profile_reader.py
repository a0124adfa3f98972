"""Loading a desk profile: find it (a shipped name or a path), read its YAML and check every
key, each error with its place (file:line:column) and what was expected.

The model it fills is :mod:`.profile`, which never imports this module. The top level and
the ``desk:`` section are read here; ``sensors:`` and ``accelerometer(s):`` by
:mod:`.profile_sensors`, ``surfaces:`` by :mod:`.profile_surfaces`, ``estimation:`` by
:mod:`.profile_estimation`.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from hapticdesk.errors import ConfigError
from hapticdesk.files.c3d import is_c3d
from hapticdesk.files.file_safety import check_confined, file_kind
from hapticdesk.files.marked_values import MarkedDict
from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.profile_estimation import fit_to_desk, read_estimation
from hapticdesk.files.profile_sensors import read_accelerometers, read_sensors
from hapticdesk.files.profile_surfaces import read_surfaces
from hapticdesk.files.rigid_body import is_body_inertia
from hapticdesk.files.validators import check_keys, number, place, require_mapping, vector
from hapticdesk.files.yamlfile import load_marked_yaml

#: a desk's sample rate, Hz: fast enough for the paper's 4.77 Hz low-pass (below half of
#: it), and no faster than a force sensor samples (ATI's boards: 7 kHz); the estimator and
#: the simulator size buffers by it
MIN_SAMPLE_RATE_HZ = 10.0
MAX_SAMPLE_RATE_HZ = 100_000.0
#: a desk's mass (kg): a heavier one is a typing mistake (the simulator's modes overflow)
MAX_DESK_MASS_KG = 1e4
#: a desk's lowest natural frequency (Hz) at least this (1e-300 divided by zero in the sway
#: model)
MIN_NATURAL_HZ = 0.5
#: a desk's principal moments of inertia (kg·m²): outside, a typing mistake (inverted, they
#: overflow)
MIN_INERTIA, MAX_INERTIA = 1e-6, 1e6

PROFILE_KEYS = {
    "name",
    "sample_rate_hz",
    "sensors",
    "surfaces",
    "estimation",
    "can",
    "serial",
    "desk",
    "accelerometer",
    "accelerometers",
}
DESK_KEYS = {"mass_kg", "natural_frequency_hz", "center_of_mass_m", "inertia_kg_m2", "note"}


def builtin_profile_path(name: str) -> Path | None:
    """The shipped profile called ``name``, if there is one."""
    candidate = resources.files("hapticdesk.profiles").joinpath(f"{name}.yaml")
    return Path(str(candidate)) if candidate.is_file() else None


def resolve_profile_path(name_or_path: str | Path, relative_to: Path | None = None) -> Path:
    """A profile name from profiles/ or a path (relative to ``relative_to`` when given)."""
    text = str(name_or_path)
    if not text.endswith((".yaml", ".yml")) and "/" not in text:
        builtin = builtin_profile_path(text)
        if builtin is not None:
            return builtin
    path = Path(text)
    if not path.is_absolute() and relative_to is not None:
        path = relative_to / path
    if is_c3d(path):  # (read as YAML it says "larger than 1 MB" or "a NUL byte")
        raise ConfigError(
            str(name_or_path),
            "a C3D file is not a desk profile: without --desk, `contacts`, `plot` and "
            "`run --source replay:FILE.c3d` make the desk from its force plate (--plate N), "
            "as `check LAYOUT --desk FILE.c3d` does",
        )
    check_confined(path, "the desk profile", str(name_or_path))  # (before it is looked at)
    if not path.is_file():
        try:
            mode: int | None = os.stat(path).st_mode
        except OSError:
            mode = None
        if mode is not None:  # it is there, but not a file (a directory, a FIFO, /dev/zero)
            raise ConfigError(
                str(name_or_path),
                f"the desk profile is {file_kind(mode)}, not a regular file "
                "(a profile is a YAML file, or the name of a shipped one)",
            )
        shipped = ", ".join(sorted(p.stem for p in _shipped_profiles()))
        raise ConfigError(str(name_or_path), f"no such desk profile; shipped profiles: {shipped}")
    return path


def _shipped_profiles() -> list[Path]:
    root = resources.files("hapticdesk.profiles")
    return [Path(str(p)) for p in root.iterdir() if str(p).endswith(".yaml")]


def load_profile(name_or_path: str | Path, relative_to: Path | None = None) -> DeskProfile:
    """Load and validate a desk profile; raises :class:`ConfigError` on any problem."""
    path = resolve_profile_path(name_or_path, relative_to)
    doc = require_mapping(load_marked_yaml(path), str(path), "a desk profile")
    return profile_from_mapping(doc, path)


@dataclass(frozen=True)
class DeskBody:
    """What the profile's optional ``desk:`` section says of the desk itself (None: not
    given)."""

    mass_kg: float | None = None
    natural_frequency_hz: float | None = None
    center_of_mass_m: np.ndarray | None = None
    inertia_kg_m2: tuple[float, float, float] | None = None


def profile_from_mapping(doc: MarkedDict, path: Path) -> DeskProfile:
    """The profile in ``doc`` (a marked YAML mapping read from ``path``), every key checked."""
    check_keys(
        doc, PROFILE_KEYS, "the desk profile", required={"name", "sample_rate_hz", "sensors"}
    )
    name = doc["name"]
    if not isinstance(name, str) or not name:
        raise ConfigError(doc.where("name"), "`name` must be a non-empty text")
    rate = number(
        doc,
        "sample_rate_hz",
        "the desk profile",
        minimum=MIN_SAMPLE_RATE_HZ,
        maximum=MAX_SAMPLE_RATE_HZ,
    )
    sensors = read_sensors(doc)
    surfaces = read_surfaces(doc, sensors)
    estimation = read_estimation(doc)
    can = _section(doc, "can")
    serial = _section(doc, "serial")  # read by hapticdesk.boards.settings, when a run uses it
    body = _desk_body(doc, rate)
    accelerometers = read_accelerometers(doc)
    if accelerometers and body.mass_kg is None:
        key = "accelerometer" if "accelerometer" in doc else "accelerometers"
        raise ConfigError(
            doc.where(key, of_key=True),
            f"`{key}` needs the desk's mass: give `desk: {{mass_kg: ...}}` "
            "(the inertial force it removes is mass × acceleration)",
        )
    profile = DeskProfile(
        name=name,
        sample_rate_hz=rate,
        sensors=sensors,
        surfaces=surfaces,
        estimation=fit_to_desk(estimation, doc, rate, body.natural_frequency_hz),
        can=can,
        serial=serial,
        path=path,
        mass_kg=body.mass_kg,
        natural_frequency_hz=body.natural_frequency_hz,
        center_of_mass_m=body.center_of_mass_m,
        inertia_kg_m2=body.inertia_kg_m2,
        accelerometers=accelerometers,
    )
    _check_sway_compensation(doc, profile)
    return profile


def _check_sway_compensation(doc: MarkedDict, profile: DeskProfile) -> None:
    """``sway_compensation: true`` needs a horizontal force to differentiate: refused on a
    desk whose sensors measure none (upright load cells), where it would silently do
    nothing."""
    if profile.estimation.sway_compensation and not profile.measures_horizontal_force:
        estimation = doc["estimation"]
        raise ConfigError(
            estimation.where("sway_compensation"),
            "`sway_compensation: true` needs sensors that measure a horizontal force (the "
            "legs' shear, as six-axis sensors do); this desk's sensors measure none (load "
            "cells): set it to false or leave it out",
        )


def _section(doc: MarkedDict, key: str) -> MarkedDict | None:
    """An optional section kept as its marked mapping, for the part that reads it when a run
    uses it (``can:``, ``serial:``)."""
    value = doc.get(key)
    return None if value is None else require_mapping(value, doc.where(key), f"`{key}`")


def _desk_body(doc: MarkedDict, rate: float) -> DeskBody:
    """The optional ``desk:`` section: mass, lowest natural frequency, centre of mass and
    principal moments of inertia."""
    if "desk" not in doc:
        return DeskBody()
    desk = require_mapping(doc["desk"], doc.where("desk"), "`desk`")
    check_keys(desk, DESK_KEYS, "`desk`")
    mass = (
        number(desk, "mass_kg", "`desk`", default=0.0, minimum=0.0, maximum=MAX_DESK_MASS_KG)
        or None
    )
    natural = _natural_frequency(desk, rate)
    com = None
    if "center_of_mass_m" in desk:
        com = np.array(
            place(
                desk["center_of_mass_m"],
                desk.where("center_of_mass_m"),
                "`center_of_mass_m` of `desk`",
                3,
            )
        )
    inertia = _inertia(desk) if "inertia_kg_m2" in desk else None
    return DeskBody(mass, natural, com, inertia)


def _natural_frequency(desk: MarkedDict, rate: float) -> float | None:
    """``natural_frequency_hz`` (0 or none: not known), a sway the sensors can see."""
    natural = number(desk, "natural_frequency_hz", "`desk`", default=0.0, minimum=0.0) or None
    # (too high for the rate: the low-passes it sets are refused by fit_to_desk)
    if natural is not None and natural < MIN_NATURAL_HZ:
        raise ConfigError(
            desk.where("natural_frequency_hz"),
            f"`natural_frequency_hz` of `desk` must be at least {MIN_NATURAL_HZ:g} Hz (no "
            f"desk sways slower), or 0 (not known), found {natural:g}",
        )
    if natural is not None and natural >= rate / 2:  # (1e300 overflowed the sway model)
        raise ConfigError(
            desk.where("natural_frequency_hz"),
            f"`natural_frequency_hz` of `desk` is {natural:g} Hz; a sway the sensors can "
            f"see must be below half the sample rate ({rate / 2:g} Hz at `sample_rate_hz` "
            f"{rate:g}); with sensors this slow give 0 (not known)",
        )
    return natural


def _inertia(desk: MarkedDict) -> tuple[float, float, float]:
    """``inertia_kg_m2``: three principal moments a body can have, within bounds."""
    moments = vector(
        desk["inertia_kg_m2"], desk.where("inertia_kg_m2"), "`inertia_kg_m2` of `desk`", 3
    )
    if not is_body_inertia(moments) or not all(MIN_INERTIA <= v <= MAX_INERTIA for v in moments):
        raise ConfigError(
            desk.where("inertia_kg_m2"),
            "`inertia_kg_m2` of `desk` must be three positive principal moments of "
            "inertia (kg·m², about the centre of mass along the desk's x, y, z), each "
            f"at most the sum of the other two (a body's are) and {MIN_INERTIA:g} to "
            f"{MAX_INERTIA:g}, found {moments}",
        )
    return (moments[0], moments[1], moments[2])
