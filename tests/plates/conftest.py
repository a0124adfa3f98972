"""Force-plate C3D files made here with ezc3d: a known press on a plate of each TYPE, written
the way the C3D User Guide defines the parameters (independently of hapticdesk's reader), and
the real recordings of ../shared/data/forceplates/ where this machine has them."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

ezc3d = pytest.importorskip("ezc3d", reason="the c3d extra (pip install 'hapticdesk[c3d]')")
from ezc3d import ezc3d as _swig  # noqa: E402  (the parameter type codes)

SHARED = Path(__file__).resolve().parents[3] / "shared" / "data" / "forceplates"
if not SHARED.is_dir():  # (CI lays shared/ beside the clone)
    SHARED = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "forceplates"


def shared_file(name: str) -> Path:
    """A real recording, or a skip saying where it was looked for (never copied here)."""
    path = SHARED / name
    if not path.is_file():
        pytest.skip(f"the real recording {name} is not on this machine (looked in {SHARED})")
    return path


@dataclass
class Press:
    """A person's force on the top: the ground reaction ``force_n`` (lab frame, N; the
    plate pushes back) at ``point_m`` (lab, on the top), held for ``seconds`` after
    ``quiet_s`` of an unloaded plate."""

    point_m: tuple[float, float, float]
    force_n: tuple[float, float, float]
    seconds: float = 1.0
    quiet_s: float = 0.2


@dataclass
class PlateSpec:
    """One plate as a C3D file describes it. ``corners_m`` lab frame, in the C3D order
    (quadrants +x+y, −x+y, −x−y, +x−y of the plate's frame, whose z points down)."""

    type: int
    corners_m: np.ndarray
    origin: tuple[float, float, float]  # as written to FORCE_PLATFORM:ORIGIN, POINT:UNITS
    point_units: str = "mm"
    moment_units: str = "Nmm"
    calibration: np.ndarray | None = None  # TYPE 4: channel -> [N; N·POINT:UNITS]
    offsets: np.ndarray | None = None  # added to every channel (the baseline ZERO removes)
    zero: tuple[int, int] = (0, 0)
    rate_hz: float = 1000.0
    frame_rate_hz: float = 100.0
    extra: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def metres(self) -> float:
        return {"mm": 1e-3, "m": 1.0}[self.point_units]

    def rotation(self) -> np.ndarray:
        """Plate -> lab, the C3D definition."""
        c = self.corners_m
        x, y = c[0] - c[1], c[0] - c[3]
        z = np.cross(x, y)
        y = np.cross(z, x)
        return np.column_stack([v / np.linalg.norm(v) for v in (x, y, z)])


def z_up_corners(centre=(0.5, 0.4, 0.0), half=(0.3, 0.2)) -> np.ndarray:
    """A plate in a lab whose vertical is z: its x along the lab's x, its z down."""
    cx, cy, cz = centre
    hx, hy = half
    # plate x = lab x, plate y = lab −y, so plate z = lab −z
    return np.array(
        [
            [cx + hx, cy - hy, cz],
            [cx - hx, cy - hy, cz],
            [cx - hx, cy + hy, cz],
            [cx + hx, cy + hy, cz],
        ]
    )


def y_up_corners(centre=(1.0, 0.0, 0.5), half=(0.2, 0.3)) -> np.ndarray:
    """A plate in a lab whose vertical is y (BTS writes so): plate x = lab z, plate y = lab
    −x, plate z = lab −y (down)."""
    cx, cy, cz = centre
    hx, hy = half
    return np.array(
        [
            [cx - hy, cy, cz + hx],
            [cx - hy, cy, cz - hx],
            [cx + hy, cy, cz - hx],
            [cx + hy, cy, cz + hx],
        ]
    )


def plate_channels(spec: PlateSpec, press: Press) -> np.ndarray:
    """The plate's channels (n, k) for ``press``, from the C3D definitions of each TYPE."""
    rate = spec.rate_hz
    k_quiet, k_load = round(press.quiet_s * rate), round(press.seconds * rate)
    r = spec.rotation()
    centre = spec.corners_m.mean(axis=0)
    f_lab = np.array(press.force_n, float)
    p_lab = np.array(press.point_m, float)
    f = r.T @ f_lab  # plate frame
    unit = spec.metres
    origin = np.array(spec.origin, float) * unit
    if spec.type in (2, 4):
        o = origin if origin[2] <= 0 else -origin  # (centre − transducer, plate frame)
        transducer = centre - r @ o
        m = r.T @ np.cross(p_lab - transducer, f_lab)  # N·m about the transducer
        m_file = m / {"Nmm": 1e-3, "Nm": 1.0}[spec.moment_units]
        wrench = np.concatenate([f, m_file])
        if spec.type == 4:
            cal = spec.calibration
            assert cal is not None
            wrench = np.linalg.solve(cal, np.concatenate([f, m / unit]))
        loaded = wrench
    elif spec.type == 3:
        a, b, az0 = origin[0], origin[1], -abs(origin[2])
        sensors = centre - r @ np.array([0.0, 0.0, az0])  # the sensors' plane's centre
        m = r.T @ np.cross(p_lab - sensors, f_lab)
        # fx12, fx34, fy14, fy23: Fx = fx12 + fx34, Mz = b (fx34 − fx12) + a (fy14 − fy23)
        fy14 = fy23 = f[1] / 2
        fx34 = (f[0] + m[2] / b) / 2
        fx12 = f[0] - fx34
        # fz1..fz4 from Fz, Mx, My and a fourth condition (no twist of the four)
        rows = np.array([[1, 1, 1, 1], [b, b, -b, -b], [-a, a, a, -a], [1, -1, 1, -1]], float)
        fz = np.linalg.solve(rows, [f[2], m[0], m[1], 0.0])
        loaded = np.array([fx12, fx34, fy14, fy23, *fz])
    else:  # TYPE 1: Fx Fy Fz, the centre of pressure X Y (plate frame, from the centre), Tz
        cop = r.T @ (p_lab - centre)
        loaded = np.array([*f, cop[0] / unit, cop[1] / unit, 0.0])
    n = len(loaded)
    channels = np.zeros((n, k_quiet + k_load))
    channels[:, k_quiet:] = loaded[:, None]
    if spec.offsets is not None:
        channels += np.asarray(spec.offsets, float)[:, None]
    return channels


def write_plate_file(path: Path, specs: list[PlateSpec], presses: list[Press]) -> Path:
    """One C3D file with these plates, each loaded by its press (the plates share one
    length of recording: the longest press's)."""
    rate = specs[0].rate_hz
    per_frame = round(rate / specs[0].frame_rate_hz)
    blocks = [plate_channels(s, p) for s, p in zip(specs, presses, strict=True)]
    k = max(b.shape[1] for b in blocks)
    k = -(-k // per_frame) * per_frame
    data = np.zeros((sum(len(b) for b in blocks), k))
    row = 0
    for b in blocks:
        data[row : row + len(b), : b.shape[1]] = b
        data[row : row + len(b), b.shape[1] :] = b[:, -1:]
        row += len(b)
    units = []
    for s in specs:
        if s.type == 2:
            units += ["N"] * 3 + [s.moment_units] * 3
        elif s.type == 3:
            units += ["N"] * 8
        elif s.type == 4:
            units += ["V"] * 6
        else:
            units += ["N"] * 3 + [s.point_units] * 2 + [s.moment_units]
    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [specs[0].frame_rate_hz]
    c["parameters"]["ANALOG"]["RATE"]["value"] = [rate]
    c["parameters"]["ANALOG"]["LABELS"]["value"] = [f"ch{i + 1}" for i in range(len(data))]
    c["parameters"]["ANALOG"]["UNITS"]["value"] = units
    c["data"]["points"] = np.zeros((4, 0, k // per_frame))
    c["data"]["analogs"] = data[None]
    c.add_parameter("POINT", "UNITS", [specs[0].point_units])
    _int(c, "USED", [len(specs)])
    _int(c, "TYPE", [s.type for s in specs])
    _int(c, "ZERO", list(specs[0].zero))
    corners = np.stack([s.corners_m.T / s.metres for s in specs], axis=2)
    c.add_parameter("FORCE_PLATFORM", "CORNERS", corners)
    c.add_parameter("FORCE_PLATFORM", "ORIGIN", np.array([s.origin for s in specs], float).T)
    per_plate = max(len(b) for b in blocks)
    channel = np.zeros((per_plate, len(specs)))
    row = 0
    for j, b in enumerate(blocks):
        channel[: len(b), j] = np.arange(row, row + len(b)) + 1
        row += len(b)
    _int(c, "CHANNEL", channel)
    cal = np.zeros((6, 6, len(specs)))
    for j, s in enumerate(specs):
        if s.calibration is not None:
            cal[:, :, j] = s.calibration
    c.add_parameter("FORCE_PLATFORM", "CAL_MATRIX", cal)
    c.write(str(path))
    return path


def _int(c: object, name: str, value: object) -> None:
    c.add_parameter("FORCE_PLATFORM", name, np.asarray(value, float))  # type: ignore[attr-defined]
    c["parameters"]["FORCE_PLATFORM"][name]["type"] = _swig.INT  # type: ignore[index]


def reference_cop_mm(path: Path, plate: int) -> np.ndarray:
    """ezc3d's centre of pressure (k, 3), lab, in POINT:UNITS (mm in the real files): the
    yardstick."""
    platforms = ezc3d.c3d(str(path), extract_forceplat_data=True)["data"]["platform"]
    return np.asarray(platforms[plate - 1]["center_of_pressure"]).T
