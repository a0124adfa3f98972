"""A C3D file's ``FORCE_PLATFORM`` parameters for one plate, read and checked, in metres:
its TYPE and channels, its corners, the transducer's ORIGIN (after the sign rule),
TYPE 4's CAL_MATRIX and TYPE 3's FPCOPPOLY. Each fault names the parameter and what was
expected. :mod:`.forceplate` turns a plate into a desk (its docstring gives the rules)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hapticdesk.errors import ConfigError
from hapticdesk.files.c3d import C3DFile
from hapticdesk.files.profile import AXES

#: the channels each TYPE delivers, in FORCE_PLATFORM:CHANNEL order (recording columns
#: ``plate<N>_<channel>``)
TYPE_CHANNELS: dict[int, tuple[str, ...]] = {
    1: AXES,  # (made from Fx Fy Fz X Y Tz by the reader)
    2: AXES,
    3: ("fx12", "fx34", "fy14", "fy23", "fz1", "fz2", "fz3", "fz4"),
    4: ("ch1", "ch2", "ch3", "ch4", "ch5", "ch6"),
}


@dataclass(frozen=True)
class ForcePlate:
    """One plate's parameters, checked, in metres (``number`` from 1, as C3D counts)."""

    number: int
    type: int
    corners: np.ndarray  # (4, 3) lab frame, m
    origin: np.ndarray  # (3,) plate frame, m, after the sign rule (see the module docstring)
    channels: np.ndarray  # (n,) 0-based analog channel indices, TYPE_CHANNELS order
    calibration: np.ndarray | None  # TYPE 4: (6, 6) channel units -> N, N·m
    cop_poly: np.ndarray | None  # TYPE 3: (12,) FPCOPPOLY, or None when absent or all zero

    @property
    def sensor_name(self) -> str:
        return f"plate{self.number}"

    def plate_rotation(self) -> np.ndarray:
        """(3, 3) the plate's axes as columns, in the lab frame (plate -> lab)."""
        c = self.corners
        x = c[0] - c[1]
        y = c[0] - c[3]
        z = np.cross(x, y)
        y = np.cross(z, x)
        return np.column_stack([v / np.linalg.norm(v) for v in (x, y, z)])

    def centre(self) -> np.ndarray:
        """The top's centre in the lab, m: the corners' mean."""
        return np.asarray(self.corners.mean(axis=0), dtype=float)


def plate_count(file: C3DFile) -> int:
    """FORCE_PLATFORM:USED (0 when the file has no FORCE_PLATFORM group)."""
    used = file.numbers("FORCE_PLATFORM", "USED")
    return 0 if used is None else int(used.reshape(-1)[0])


def read_plate(file: C3DFile, number: int) -> ForcePlate:
    """Plate ``number`` (from 1) of ``file``, its parameters checked (ConfigError naming
    the parameter and what was expected)."""
    count = plate_count(file)
    if count == 0:
        raise ConfigError(file.where, "the C3D file has no force plates (FORCE_PLATFORM:USED)")
    if not 1 <= number <= count:
        raise ConfigError(
            "--plate",
            f"{file.path.name} has {count} force plate{'s' if count > 1 else ''}: expected "
            f"--plate 1{f' to {count}' if count > 1 else ''} (C3D counts from 1), found {number}",
        )
    p = number - 1
    what = f"force plate {number} of {file.where}"
    types = _required(file, "TYPE", what)
    if types.size < number:
        raise ConfigError(file.where, f"FORCE_PLATFORM:TYPE lists no type for {what}")
    plate_type = int(types.reshape(-1, order="F")[p])
    if plate_type not in TYPE_CHANNELS:
        raise ConfigError(
            file.where,
            f"{what} is of FORCE_PLATFORM:TYPE {plate_type}; hapticdesk reads types "
            f"{', '.join(map(str, TYPE_CHANNELS))} (six channels Fx … Mz, a Kistler plate's "
            "eight, six with a calibration matrix, or Fx Fy Fz X Y Tz)",
        )
    names = TYPE_CHANNELS[plate_type]
    corners = _per_plate(file, "CORNERS", (3, 4), p, what).T * file.point_metres
    origin = _per_plate(file, "ORIGIN", (3,), p, what) * file.point_metres
    channels = _channels(file, p, len(names), what)
    _check_corners(corners, file, what)
    if plate_type == 3:
        origin = np.array([origin[0], origin[1], -abs(origin[2])])
    elif plate_type == 1:
        origin = np.zeros(3)  # (the centre of pressure comes on the top itself)
    elif origin[2] > 0:  # the vector written from the top to the transducer
        origin = -origin
    calibration = _calibration(file, p, what) if plate_type == 4 else None
    return ForcePlate(
        number=number,
        type=plate_type,
        corners=corners,
        origin=origin,
        channels=channels,
        calibration=calibration,
        cop_poly=_cop_poly(file, p) if plate_type == 3 else None,
    )


def _required(file: C3DFile, name: str, what: str) -> np.ndarray:
    value = file.numbers("FORCE_PLATFORM", name)
    if value is None:
        raise ConfigError(file.where, f"FORCE_PLATFORM:{name} is missing; {what} needs it")
    if not np.isfinite(value).all():
        raise ConfigError(file.where, f"FORCE_PLATFORM:{name} holds a value that is not finite")
    return value


def _per_plate(file: C3DFile, name: str, shape: tuple[int, ...], p: int, what: str) -> np.ndarray:
    """Plate ``p``'s block of a parameter dimensioned (*shape, USED), first index fastest."""
    flat = _required(file, name, what).reshape(-1, order="F")
    size = int(np.prod(shape))
    if flat.size < size * (p + 1):
        raise ConfigError(
            file.where,
            f"FORCE_PLATFORM:{name} holds {flat.size} numbers, too few for {what} "
            f"({size} per plate: {' × '.join(map(str, shape))})",
        )
    return flat[size * p : size * (p + 1)].reshape(shape, order="F")


def _channels(file: C3DFile, p: int, n: int, what: str) -> np.ndarray:
    raw = _required(file, "CHANNEL", what)
    per_plate = raw.shape[0] if raw.ndim > 1 else raw.size
    if per_plate < n:
        raise ConfigError(
            file.where,
            f"FORCE_PLATFORM:CHANNEL lists {per_plate} channels per plate; {what} needs {n}",
        )
    block = _per_plate(file, "CHANNEL", (per_plate,), p, what)[:n]
    channels = block.astype(int) - 1  # (C3D counts analog channels from 1)
    count = file.analogs.shape[0]
    if (channels < 0).any() or (channels >= count).any():
        raise ConfigError(
            file.where,
            f"FORCE_PLATFORM:CHANNEL for {what} names analog channels "
            f"{(channels + 1).tolist()}; the file has channels 1 to {count}",
        )
    return channels


def _check_corners(corners: np.ndarray, file: C3DFile, what: str) -> None:
    x, y = corners[0] - corners[1], corners[0] - corners[3]
    area = float(np.linalg.norm(np.cross(x, y)))
    if not area > 1e-6:  # (1 cm² : the corners do not span a top)
        raise ConfigError(
            file.where,
            f"FORCE_PLATFORM:CORNERS of {what} do not span a top (corners 1, 2 and 4 on one "
            f"line): {np.round(corners / file.point_metres, 3).tolist()}",
        )


def _calibration(file: C3DFile, p: int, what: str) -> np.ndarray:
    """TYPE 4's CAL_MATRIX in N and N·m per channel unit (identity when the file gives
    none, as ezc3d takes a file without one)."""
    value = file.numbers("FORCE_PLATFORM", "CAL_MATRIX")
    if value is None:
        matrix = np.eye(6)
    else:
        flat = value.reshape(-1, order="F")
        if flat.size < 36 * (p + 1):
            raise ConfigError(
                file.where,
                f"FORCE_PLATFORM:CAL_MATRIX holds {flat.size} numbers; {what} (TYPE 4) needs "
                "a 6 × 6 matrix per plate",
            )
        matrix = flat[36 * p : 36 * (p + 1)].reshape(6, 6, order="F")
        store = file.parameter("FORCE_PLATFORM", "MATRIX_STORE")
        if isinstance(store, list | tuple) and store and str(store[0]).upper() == "BYROW":
            matrix = matrix.T
        if not np.isfinite(matrix).all() or not matrix.any():
            raise ConfigError(
                file.where,
                f"FORCE_PLATFORM:CAL_MATRIX of {what} (TYPE 4) must be finite and not all zero",
            )
    matrix = np.array(matrix, dtype=float)
    matrix[3:] *= file.point_metres  # N·POINT:UNITS -> N·m
    return matrix


def _cop_poly(file: C3DFile, p: int) -> np.ndarray | None:
    value = file.numbers("FORCE_PLATFORM", "FPCOPPOLY")
    if value is None:
        return None
    flat = value.reshape(-1, order="F")
    if flat.size < 12 * (p + 1):
        return None
    poly = flat[12 * p : 12 * (p + 1)]
    return poly if np.isfinite(poly).all() and poly.any() else None
