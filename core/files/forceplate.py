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

from hapticdesk.errors import ConfigError
from hapticdesk.files.c3d import C3DFile, open_c3d
from hapticdesk.files.plate_parameters import TYPE_CHANNELS, ForcePlate, read_plate
from hapticdesk.files.plate_readings import channel_noise, plate_readings
from hapticdesk.files.profile import DeskProfile, EstimationSettings, SensorSpec, Surface
from hapticdesk.files.recording import Recording

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
# the desk frame from the plate's: half a turn about x (z up, out of the top)
_DESK_FROM_PLATE = np.diag([1.0, -1.0, -1.0])


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


def plate_desk(file: C3DFile, number: int = 1) -> PlateDesk:
    """Plate ``number`` of ``file`` as a desk (see the module docstring)."""
    plate = read_plate(file, number)
    lab_rotation = plate.plate_rotation() @ _DESK_FROM_PLATE
    centre = plate.centre()
    top = _top(plate, lab_rotation, centre)
    readings = plate_readings(file, plate)
    sensor = _signed(_plate_sensor(plate), top, readings, file.analog_rate_hz)
    profile = DeskProfile(
        name=f"{file.path.stem}-plate{number}",
        sample_rate_hz=file.analog_rate_hz,
        sensors=(sensor,),
        surfaces=(top,),
        estimation=_plate_estimation(file, readings, sensor, top),
        path=file.path,
    )
    return PlateDesk(profile, plate, lab_rotation, centre, file.point_metres)


def _plate_sensor(plate: ForcePlate) -> SensorSpec:
    """The plate's transducer as the desk's one sensor: at the transducer's origin (TYPE 3:
    the centre of the sensors' plane) below the top's centre, its channels by TYPE, a
    Kistler plate's through the 6×8 map of its formulae (module docstring)."""
    to_top = np.array([0.0, 0.0, plate.origin[2]]) if plate.type == 3 else plate.origin
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
    return SensorSpec(
        name=plate.sensor_name,
        position=_DESK_FROM_PLATE @ -to_top,
        rotation=_DESK_FROM_PLATE,  # the transducer's frame is the plate's
        channels=TYPE_CHANNELS[plate.type],
        calibration=calibration,
    )


def _top(plate: ForcePlate, lab_rotation: np.ndarray, centre: np.ndarray) -> Surface:
    """The top: the surface z = 0 of the desk frame, the corners its outline."""
    outline = (plate.corners - centre) @ lab_rotation  # desk frame; its z is the top's tilt
    return Surface(
        name="top",
        origin=np.zeros(3),
        normal=np.array([0.0, 0.0, 1.0]),
        u_axis=np.array([1.0, 0.0, 0.0]),
        v_axis=np.array([0.0, 1.0, 0.0]),
        polygon=outline[:, :2],
    )


def _signed(sensor: SensorSpec, top: Surface, readings: np.ndarray, rate: float) -> SensorSpec:
    """``sensor`` read as the plate's reaction, or as the load when its largest vertical
    force points into the top.

    C3D writers store the plate's reaction (the ground reaction force: up, out of the top);
    a plate that gives the force on it instead (its largest vertical force points into the
    top: a person can only push) is read as a "load" sensor. The point is the same either
    way; the detector's "presses into the surface" needs the sign."""
    probe = DeskProfile(name="", sample_rate_hz=rate, sensors=(sensor,), surfaces=(top,))
    vertical = readings @ probe.wrench_map()[2]
    if vertical.size and vertical[np.argmax(np.abs(vertical))] < 0:
        return replace(sensor, reports="load")
    return sensor


def _plate_estimation(
    file: C3DFile, readings: np.ndarray, sensor: SensorSpec, top: Surface
) -> EstimationSettings:
    """The plate's estimation: the force's own line, low-passed at PLATE_LOWPASS_SHARE of
    the rate, zeroed readings with the channels' noise measured from the file."""
    probe = DeskProfile(
        name="", sample_rate_hz=file.analog_rate_hz, sensors=(sensor,), surfaces=(top,)
    )
    sigma = channel_noise(file, readings)
    moments = probe.moment_channels()
    return EstimationSettings(
        method=PLATE_METHOD,
        force_lowpass_hz=PLATE_LOWPASS_SHARE * file.analog_rate_hz,
        diff_lowpass_hz=PLATE_LOWPASS_SHARE * file.analog_rate_hz,
        zeroed=True,
        hold_jumps=False,  # (a lab amplifier's readings: every jump is a foot's, none corrupt)
        noise_force_n=_rms(sigma[~moments]),
        noise_moment_nm=_rms(sigma[moments]),
    )


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
