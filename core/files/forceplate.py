"""A force plate of a C3D file as a desk: its ``FORCE_PLATFORM`` parameters made a
:class:`DeskProfile` of one sensor under one surface, and its analog channels a recording.

A force plate is the paper's desk with one sensor: a rigid top on a six-axis transducer (C3D
TYPE 2, 4) or on four three-axis piezo sensors at its corners (TYPE 3, Kistler), whose centre
of pressure is the line of action cut with the top (paper eqs. 1–5). Built from the
parameters alone (the C3D User Guide, c3d.org; ezc3d's ``ForcePlatforms.cpp`` for how they
are read in practice):

* **The plate's frame** from ``CORNERS`` (four corners in the lab, in the plate's quadrants
  +x+y, −x+y, −x−y, +x−y): x = c1 − c2, y = c1 − c4, z = x × y (pointing into the plate:
  down, the C3D convention), y made square to x. The plate's centre is the corners' mean.
* **The desk's frame** is the plate's turned half a turn about x (y and z flipped), so that
  its z points up out of the top, as every hapticdesk desk's does; its origin P_o is the
  top's centre, and the top is the surface z = 0 with the corners as its outline. Points go
  back to the lab with :meth:`PlateDesk.to_lab`.
* **ORIGIN** (TYPE 2, 4) is the vector from the transducer's origin to the top's centre, in
  the plate's frame; the transducer lies below the top, so its z is negative. A file with a
  positive z wrote the vector the other way: it is negated whole (as Visual3D and ezc3d do).
  TYPE 3: ORIGIN is (a, b, az0), the sensors' offsets from the plate's axes and the depth of
  their plane below the top (az0 negative; a positive one is taken as its negative, a and b
  as given).
* **TYPE 2**: the channels are Fx Fy Fz Mx My Mz about the transducer's origin (a six-axis
  sensor). **TYPE 4**: six raw channels and ``CAL_MATRIX`` (6×6, stored by column unless
  ``MATRIX_STORE`` says ``BYROW``; forces in N and moments in N·``POINT:UNITS`` per channel
  unit) — a calibrated sensor. **TYPE 3**: eight channels fx12 fx34 fy14 fy23 fz1 … fz4 and
  the 6×8 map of the Kistler formulae (sensor 1 at (a, b), 2 at (−a, b), 3 at (−a, −b), 4 at
  (a, −b)): Fx = fx12 + fx34, Fy = fy14 + fy23, Fz = Σ fz, Mx = b (fz1 + fz2 − fz3 − fz4),
  My = a (−fz1 + fz2 + fz3 − fz4), Mz = b (fx34 − fx12) + a (fy14 − fy23), about the centre
  of the sensors' plane. **TYPE 1**: Fx Fy Fz, the centre of pressure X Y and the free
  moment Tz; the reader turns them into the wrench about the top's centre.
* **Units**: ezc3d has applied ANALOG:OFFSET, SCALE and GEN_SCALE; a force channel's
  ANALOG:UNITS (N, kN, lbf) and a moment channel's (Nmm, N.m, …) are converted to N and N·m;
  a channel whose unit says neither (a TYPE-2 plate written with ``V``) is taken in N and
  N·``POINT:UNITS``, as ezc3d takes it.
* **The zero**: the mean of each channel over the ``ZERO`` frames is taken off (none for
  ``[0, 0]``: the channels come zeroed); the estimator is told the readings come zeroed, so
  it never tares over a loaded plate, and a person standing still never becomes part of the
  zero. The channels' noise is measured over the ZERO frames, or, without them, from the
  sample-to-sample differences over the whole file (robustly: a person's force hardly
  changes between two samples at 1 kHz).
* The channels are taken as the plate's reaction (the ground reaction force, up, as C3D
  writers store it), unless the plate's largest vertical force points into the top (a plate
  that gives the force on it, or corners listed the other way round): then as the load. The
  located point does not depend on the sign; the detector's "presses into the top" does.
* ``FPCOPPOLY`` (a Kistler plate's centre-of-pressure correction polynomial, 12 numbers per
  plate, as ezc3d applies it) is applied by :meth:`PlateDesk.to_lab`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from hapticdesk.files.c3d import (
    C3DFile,
    force_factor,
    moment_factor,
    open_c3d,
)
from hapticdesk.files.profile import AXES, DeskProfile, EstimationSettings, SensorSpec, Surface
from hapticdesk.files.recording import Recording
from hapticdesk.files.yamlfile import ConfigError

#: the channels each TYPE delivers, in FORCE_PLATFORM:CHANNEL order (recording columns
#: ``plate<N>_<channel>``)
TYPE_CHANNELS: dict[int, tuple[str, ...]] = {
    1: AXES,  # (made from Fx Fy Fz X Y Tz by the reader)
    2: AXES,
    3: ("fx12", "fx34", "fy14", "fy23", "fz1", "fz2", "fz3", "fz4"),
    4: ("ch1", "ch2", "ch3", "ch4", "ch5", "ch6"),
}
SENSOR_NAME = re.compile(r"plate([1-9][0-9]*)")
#: the plate's estimation (docs/forceplates.md, "Which method"): the force's own line of
#: action (`force`), low-passed as little as the estimator's filters allow (0.45 × the rate,
#: its fast path's ceiling). The paper's 4.77 Hz low-pass is there for its desk's 5.9 Hz mode
#: and for a finger's 2–3 N; a plate's first mode is hundreds of Hz and a person puts
#: hundreds of N on it, while a walking person's centre of pressure rolls at 0.1–1 m/s, which
#: a low-pass turns into lag (a 2nd-order Butterworth runs 0.225 / f_c behind: 47 ms at
#: 4.77 Hz, 4.5 mm at 0.1 m/s). The differentiated force (`diff`, `switched` below F_tth)
#: assumes a still point, which a rolling foot is not, and matters for a millisecond of a step.
PLATE_METHOD = "force"
PLATE_LOWPASS_SHARE = 0.45
#: a channel's noise is never taken below this share of its largest reading (an exactly
#: repeating, quantised channel measures 0; the covariances need a positive one)
NOISE_FLOOR_SHARE = 1e-7
NOISE_FLOOR = 1e-6
#: the fewest changing samples the noise is measured on without ZERO frames (else the floor)
MIN_NOISE_SAMPLES = 100
# the desk frame from the plate's: half a turn about x (z up, out of the top)
_DESK_FROM_PLATE = np.diag([1.0, -1.0, -1.0])
_MAD_TO_SIGMA = 1.4826  # a normal distribution's σ per median absolute deviation


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


@dataclass(frozen=True)
class PlateDesk:
    """A plate as a desk: the profile, the plate, and the desk frame in the lab."""

    profile: DeskProfile
    plate: ForcePlate
    lab_rotation: np.ndarray  # (3, 3) desk frame -> lab frame
    lab_origin: np.ndarray  # (3,) the desk's origin (the top's centre) in the lab, m
    point_metres: float  # metres per POINT:UNITS (FPCOPPOLY is in them)

    def to_lab(self, points: np.ndarray) -> np.ndarray:
        """Desk-frame points (..., 3), m, on the top -> the lab frame, m, with a TYPE-3
        plate's FPCOPPOLY correction applied (in the plate's frame and the file's units,
        as ezc3d applies it)."""
        points = np.array(points, dtype=float)
        poly = self.plate.cop_poly
        if poly is not None:
            unit = self.point_metres
            x, y = points[..., 0] / unit, -points[..., 1] / unit  # the plate's x, y
            x2, y2 = x * x, y * y
            dx = (poly[0] * y2 * y2 + poly[1] * y2 + poly[2]) * x2 * x + (
                poly[3] * y2 * y2 + poly[4] * y2 + poly[5]
            ) * x
            dy = (poly[6] * x2 * x2 + poly[7] * x2 + poly[8]) * y2 * y + (
                poly[9] * x2 * x2 + poly[10] * x2 + poly[11]
            ) * y
            points[..., 0] -= dx * unit
            points[..., 1] += dy * unit  # (the desk's y is the plate's −y)
        return np.asarray(points @ self.lab_rotation.T + self.lab_origin)


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


def plate_readings(file: C3DFile, plate: ForcePlate) -> np.ndarray:
    """The plate's channels (k, n), TYPE_CHANNELS order, in N, N·m (TYPE 4: the channel's
    own unit), zeroed over the ZERO frames; TYPE 1's six made into Fx … Mz about the top's
    centre."""
    raw = file.analogs[plate.channels].T.astype(float)  # (k, n), a copy
    zero = file.zero_range()
    if zero is not None:
        a, b = zero
        keep = slice(None) if plate.type != 1 else [0, 1, 2, 5]  # (not a centre of pressure)
        raw[:, keep] -= raw[a:b, keep].mean(axis=0)
    units = [file.units[c] for c in plate.channels]
    if plate.type in (2, 3):
        kinds = ["force"] * 8 if plate.type == 3 else ["force"] * 3 + ["moment"] * 3
        return raw * _factors(units, kinds, file.point_metres)
    if plate.type == 4:
        return raw
    factors = _factors(units, ["force"] * 3 + ["length"] * 2 + ["moment"], file.point_metres)
    f, x, y = raw[:, :3] * factors[:3], raw[:, 3] * factors[3], raw[:, 4] * factors[4]
    tz = raw[:, 5] * factors[5]
    # the force at (x, y, 0) about the top's centre, with the free moment about z
    moment = np.stack([y * f[:, 2], -x * f[:, 2], x * f[:, 1] - y * f[:, 0] + tz], axis=1)
    return np.concatenate([f, moment], axis=1)


def _factors(units: list[str], kinds: list[str], point_metres: float) -> np.ndarray:
    """SI factors per channel: by its unit where it names one, else N, N·POINT:UNITS, or
    POINT:UNITS (ezc3d's reading)."""
    out = []
    for unit, kind in zip(units, kinds, strict=True):
        if kind == "force":
            factor = force_factor(unit)
            out.append(1.0 if factor is None else factor)
        elif kind == "moment":
            factor = moment_factor(unit)
            out.append(point_metres if factor is None else factor)
        else:
            from hapticdesk.files.c3d import LENGTH_UNITS

            out.append(LENGTH_UNITS.get(unit.strip().lower(), point_metres))
    return np.array(out)


def channel_noise(file: C3DFile, readings: np.ndarray) -> np.ndarray:
    """Each channel's noise σ (n,) in its reading's unit: the spread over the ZERO frames,
    or, without them, robustly from the second differences over the whole file where the
    channel changes (their median absolute deviation: a person's force is smooth over three
    samples at 1 kHz, its slope cancels); never below a floor (NOISE_FLOOR, and
    NOISE_FLOOR_SHARE of the channel's largest reading)."""
    zero = file.zero_range()
    if zero is not None and zero[1] - zero[0] >= 2:
        sigma = readings[zero[0] : zero[1]].std(axis=0, ddof=1)
    else:
        sigma = np.zeros(readings.shape[1])
        for j in range(readings.shape[1]):
            # (samples that exactly repeat the one before say nothing of the noise: a plate
            # written 0 while unloaded, a noise-free file)
            x = readings[:, j]
            second = (x[2:] - 2.0 * x[1:-1] + x[:-2])[x[2:] != x[1:-1]]
            if second.size >= MIN_NOISE_SAMPLES:
                mad = np.median(np.abs(second - np.median(second)))
                sigma[j] = _MAD_TO_SIGMA * mad / np.sqrt(6.0)  # (var of x₊ − 2x + x₋: 6σ²)
    largest = np.abs(readings).max(axis=0) if len(readings) else np.zeros(readings.shape[1])
    return np.maximum(sigma, np.maximum(NOISE_FLOOR_SHARE * largest, NOISE_FLOOR))


def plate_desk(file: C3DFile, number: int = 1) -> PlateDesk:
    """Plate ``number`` of ``file`` as a desk (see the module docstring)."""
    plate = read_plate(file, number)
    names = TYPE_CHANNELS[plate.type]
    # the transducer's origin (TYPE 3: the centre of the sensors' plane) from the top's centre
    to_top = np.array([0.0, 0.0, plate.origin[2]]) if plate.type == 3 else plate.origin
    position = _DESK_FROM_PLATE @ -to_top
    calibration: np.ndarray | None = None
    if plate.type == 3:
        a, b = plate.origin[0], plate.origin[1]
        calibration = np.array(
            [
                [1, 1, 0, 0, 0, 0, 0, 0],
                [0, 0, 1, 1, 0, 0, 0, 0],
                [0, 0, 0, 0, 1, 1, 1, 1],
                [0, 0, 0, 0, b, b, -b, -b],
                [0, 0, 0, 0, -a, a, a, -a],
                [-b, b, a, -a, 0, 0, 0, 0],
            ],
            dtype=float,
        )
    elif plate.type == 4:
        calibration = plate.calibration
    sensor = SensorSpec(
        name=plate.sensor_name,
        position=position,
        rotation=_DESK_FROM_PLATE,  # the transducer's frame is the plate's
        channels=names,
        calibration=calibration,
    )
    lab_rotation = plate.plate_rotation() @ _DESK_FROM_PLATE
    centre = plate.centre()
    outline = (plate.corners - centre) @ lab_rotation  # desk frame; its z is the top's tilt
    top = Surface(
        name="top",
        origin=np.zeros(3),
        normal=np.array([0.0, 0.0, 1.0]),
        u_axis=np.array([1.0, 0.0, 0.0]),
        v_axis=np.array([0.0, 1.0, 0.0]),
        polygon=outline[:, :2],
    )
    probe = DeskProfile(
        name="", sample_rate_hz=file.analog_rate_hz, sensors=(sensor,), surfaces=(top,)
    )
    readings = plate_readings(file, plate)
    # C3D writers store the plate's reaction (the ground reaction force: up, out of the top);
    # a plate that gives the force on it instead (its largest vertical force points into the
    # top: a person can only push) is read as a "load" sensor. The point is the same either
    # way; the detector's "presses into the surface" needs the sign.
    vertical = readings @ probe.wrench_map()[2]
    if vertical.size and vertical[np.argmax(np.abs(vertical))] < 0:
        sensor = replace(sensor, reports="load")
        probe = replace(probe, sensors=(sensor,))
    sigma = channel_noise(file, readings)
    moments = probe.moment_channels()
    estimation = EstimationSettings(
        method=PLATE_METHOD,
        force_lowpass_hz=PLATE_LOWPASS_SHARE * file.analog_rate_hz,
        diff_lowpass_hz=PLATE_LOWPASS_SHARE * file.analog_rate_hz,
        zeroed=True,
        noise_force_n=_rms(sigma[~moments]),
        noise_moment_nm=_rms(sigma[moments]),
    )
    profile = DeskProfile(
        name=f"{file.path.stem}-plate{number}",
        sample_rate_hz=file.analog_rate_hz,
        sensors=(sensor,),
        surfaces=(top,),
        estimation=estimation,
        path=file.path,
    )
    return PlateDesk(profile, plate, lab_rotation, centre, file.point_metres)


def _rms(values: np.ndarray) -> float:
    return float(np.sqrt(np.mean(values**2))) if values.size else 0.0


def read_plate_recording(
    path: str | Path, profile: DeskProfile, file: C3DFile | None = None
) -> Recording:
    """A C3D file's plates as a recording for ``profile``: each sensor named ``plate<N>``
    gets plate N's channels (its ``channels`` named as :data:`TYPE_CHANNELS` names them for
    the plate's TYPE), zeroed and in SI units (see :func:`plate_readings`)."""
    file = file if file is not None else open_c3d(path)
    columns = []
    for sensor in profile.sensors:
        found = SENSOR_NAME.fullmatch(sensor.name)
        if found is None:
            raise ConfigError(
                str(path),
                f"desk {profile.name!r} has a sensor {sensor.name!r}; reading a C3D file, a "
                "desk's sensors are its force plates, named plate1, plate2, … (leave out "
                "--desk to build the desk from the file's own plate)",
            )
        plate = read_plate(file, int(found.group(1)))
        names = TYPE_CHANNELS[plate.type]
        if sorted(sensor.channels) != sorted(names):
            raise ConfigError(
                str(path),
                f"sensor {sensor.name!r} of desk {profile.name!r} delivers "
                f"{', '.join(sensor.channels)}, but plate {plate.number} is of TYPE "
                f"{plate.type}, whose channels are {', '.join(names)}",
            )
        readings = plate_readings(file, plate)
        columns.append(readings[:, [names.index(c) for c in sensor.channels]])
    return Recording(
        file.t.copy(),
        np.concatenate(columns, axis=1),
        profile.sensor_names,
        channel_names=profile.channel_names(),
    )
