"""The set-up check of a new desk: presses at known points → what is wrong in its profile.

The procedure: a quiet desk for the tare, then firm presses (or a known weight) at a few
marked points, one after another, in order. For each press the held wrench of every sensor
(tared, averaged over the hold) is turned into the desk frame with the profile's rotation and
sign, and the balance of the paper's eqs. (1)-(4) is written per sensor:

    Σ_i F_i = -F_e,    Σ_i (r_i × F_i + M_i) = -(P × F_e)

A sensor whose vertical force opposes the others' is read with the wrong sign (``reports``
or upside down). With vertical presses the moment balance is linear in the sensors' (x, y)
positions; the imbalance the presses leave is the lever-arm error. On a rigid desk the legs'
forces depend on the point pressed through three numbers only, so not every position can be
solved for: the check finds the one sensor whose move explains the imbalance (> 90 %) and
proposes its position, or says no single sensor does. A
sensor whose vertical load appears in the desk's horizontal plane is tilted or turned wrong
in ``rotation_rpy_deg``. Rotation about the vertical (yaw) does not show under vertical
presses and is not checked.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, NamedTuple

import numpy as np

from hapticdesk.errors import ConfigError
from hapticdesk.files.profile import DeskProfile

#: a sensor placed further than this from where the presses put it is reported
POSITION_TOLERANCE_M = 0.01
#: a vertical load showing this much (as an angle) in the horizontal plane is reported
TILT_TOLERANCE_DEG = 3.0
#: a press is the part of a force bump above this share of its peak
HOLD_SHARE = 0.7


@dataclass
class SetupFinding:
    """One thing wrong with a sensor, and the fix proposed."""

    sensor: str
    kind: str  # sign, position, tilt
    message: str


@dataclass
class SetupReport:
    """What the presses showed: where the estimator put them, findings, the corrected profile."""

    points: np.ndarray  # (K, 2) the known points
    measured: np.ndarray  # (K, 2) where the estimator placed them (NaN-free: 0 when unplaced)
    placed: np.ndarray  # (K,) bool: the estimator located the press
    residual_m: np.ndarray  # (K,) distance measured - known (inf when not placed)
    fitted_positions: np.ndarray | None  # (S, 2) sensor (x, y) from the presses
    findings: list[SetupFinding] = field(default_factory=list)
    corrected: DeskProfile | None = None

    def profile_snippet(self) -> str:
        """The corrected sensors as YAML lines to paste into the profile."""
        if self.corrected is None:
            return ""
        lines = ["sensors:"]
        for s in self.corrected.sensors:
            x, y, z = (round(float(v), 4) for v in s.position)
            lines.append(f"  - {{name: {s.name}, position: [{x}, {y}, {z}], reports: {s.reports}}}")
        return "\n".join(lines)


def press_windows(force: np.ndarray, t: np.ndarray, count: int, min_n: float) -> list[slice]:
    """The ``count`` holds: runs where the force is above HOLD_SHARE of their bump's peak.

    The force is smoothed over 50 ms and bumps closer than 0.2 s are one press (the desk's
    sway and the noise make a press cross the threshold more than once)."""
    rate = 1.0 / float(np.median(np.diff(t)))
    width = max(1, int(0.05 * rate))
    smooth = np.convolve(force, np.ones(width) / width, mode="same")
    above = np.concatenate([[False], smooth > min_n, [False]])
    edges = np.flatnonzero(np.diff(above.astype(np.int8)))
    runs = [[int(a), int(b)] for a, b in zip(edges[::2], edges[1::2], strict=True)]
    bumps: list[list[int]] = []
    for a, b in runs:
        if bumps and a - bumps[-1][1] < 0.2 * rate:
            bumps[-1][1] = b
        else:
            bumps.append([a, b])
    bumps = [ab for ab in bumps if ab[1] - ab[0] > 0.05 * rate]
    if len(bumps) != count:
        raise ConfigError(
            None,
            f"expected {count} presses (one per marked point), found {len(bumps)} times the "
            f"force went over {min_n:g} N",
        )
    out = []
    for a, b in bumps:
        peak = smooth[a:b].max()
        inside = np.flatnonzero(smooth[a:b] >= HOLD_SHARE * peak) + a
        out.append(slice(int(inside[0]), int(inside[-1]) + 1))
    return out


@dataclass(frozen=True)
class HeldPresses:
    """Each press's held load per sensor in the desk frame, tared and averaged over its hold
    (``windows``): ``fz`` (K, S) the vertical force, ``fxy`` (K, S, 2) the horizontal one,
    ``moments`` (K, S, 3)."""

    windows: list[slice]
    fz: np.ndarray
    fxy: np.ndarray
    moments: np.ndarray

    def sign_corrected(self, flips: np.ndarray) -> HeldPresses:
        """The loads with each sensor's sign multiplied by ``flips`` (S,) (±1)."""
        per_axis = flips[None, :, None]
        return replace(
            self, fz=self.fz * flips, fxy=self.fxy * per_axis, moments=self.moments * per_axis
        )


@dataclass(frozen=True)
class _PositionFix:
    """What the moment balance says of the sensors' positions: a finding (None: they
    balance), and the one sensor moved (its index and new (x, y); -1 and None: none)."""

    finding: SetupFinding | None
    sensor: int = -1
    position: np.ndarray | None = None


def check_setup(
    profile: DeskProfile,
    t: np.ndarray,
    wrench: np.ndarray,
    points: np.ndarray,
    *,
    tare_s: float = 1.0,
    min_force_n: float = 3.0,
) -> SetupReport:
    """Check ``profile`` against presses at ``points`` (K, 2) in order, recorded as ``t``
    (n,), ``wrench`` (n, S, 6) sensor frames, the first ``tare_s`` a quiet desk."""
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    sensors = profile.sensors
    held = _held_presses(profile, t, wrench, len(points), tare_s, min_force_n)
    share = held.fz / np.abs(held.fz).sum(axis=1, keepdims=True)
    flips = np.where(np.median(share, axis=0) < -0.02, -1.0, 1.0)
    findings = _sign_findings(profile, flips)
    held = held.sign_corrected(flips)
    findings += _tilt_findings(profile, held)
    corrected_sensors = [
        replace(s, reports=("load" if s.reports == "reaction" else "reaction")) if f < 0 else s
        for s, f in zip(sensors, flips, strict=True)
    ]
    fitted = np.array([s.position[:2] for s in sensors])
    fix = _position_fix(profile, held, _moment_imbalance(profile, held, points))
    if fix.finding is not None:
        findings.append(fix.finding)
    if fix.position is not None:
        fitted[fix.sensor] = fix.position
        position = np.array([*fix.position, sensors[fix.sensor].position[2]])
        corrected_sensors[fix.sensor] = replace(corrected_sensors[fix.sensor], position=position)
    measured, placed = _placed(profile, t, wrench, held.windows)
    residual = np.where(placed, np.hypot(*(measured - points).T), np.inf)
    corrected = replace(profile, sensors=tuple(corrected_sensors)) if findings else None
    return SetupReport(points, measured, placed, residual, fitted, findings, corrected)


def _held_presses(
    profile: DeskProfile,
    t: np.ndarray,
    wrench: np.ndarray,
    count: int,
    tare_s: float,
    min_force_n: float,
) -> HeldPresses:
    """The ``count`` presses' held loads, tared over the first ``tare_s`` (a quiet desk)."""
    sensors = profile.sensors
    quiet = t < t[0] + tare_s
    if quiet.sum() < 10:
        raise ConfigError(None, f"the recording needs {tare_s:g} s of a quiet desk first")
    tared = wrench - wrench[quiet].mean(axis=0)
    # desk frame: R_i · (sign_i · reading), forces and moments alike (docs/reference/contracts.md)
    rot = np.stack([s.rotation for s in sensors])  # (S, 3, 3)
    sign = np.array([s.sign for s in sensors])[None, :, None]
    f_desk = np.einsum("sij,nsj->nsi", rot, tared[:, :, :3]) * sign
    m_desk = np.einsum("sij,nsj->nsi", rot, tared[:, :, 3:]) * sign
    magnitude = np.abs(f_desk[:, :, 2]).sum(axis=1)  # sign-blind: a flipped sensor still counts
    windows = press_windows(magnitude, t, count, min_force_n)
    return HeldPresses(
        windows,
        np.array([f_desk[w, :, 2].mean(axis=0) for w in windows]),
        np.array([f_desk[w, :, :2].mean(axis=0) for w in windows]),
        np.array([m_desk[w].mean(axis=0) for w in windows]),
    )


def _sign_findings(profile: DeskProfile, flips: np.ndarray) -> list[SetupFinding]:
    """A finding per sensor whose vertical force opposes the others' (``flips`` -1)."""
    findings = []
    for s, flip in zip(profile.sensors, flips, strict=True):
        if flip < 0:
            other = "load" if s.reports == "reaction" else "reaction"
            findings.append(
                SetupFinding(
                    s.name,
                    "sign",
                    f"{s.name} reads pressing down as pulling up: `reports: {other}` (or it is "
                    "mounted upside down: roll 180 in rotation_rpy_deg)",
                )
            )
    return findings


def _tilt_findings(profile: DeskProfile, held: HeldPresses) -> list[SetupFinding]:
    """A finding per sensor whose vertical load shows partly in the horizontal plane."""
    findings = []
    for i, s in enumerate(profile.sensors):
        vertical = np.abs(held.fz[:, i]).sum()
        if vertical <= 0:
            continue
        horizontal = np.linalg.norm(held.fxy[:, i, :].sum(axis=0) * np.sign(held.fz[:, i]).mean())
        angle = float(np.degrees(np.arctan2(horizontal, vertical)))
        if angle > TILT_TOLERANCE_DEG:
            findings.append(
                SetupFinding(
                    s.name,
                    "tilt",
                    f"{s.name} sees {angle:.1f}° of its vertical load as horizontal: check "
                    "roll and pitch in its rotation_rpy_deg",
                )
            )
    return findings


def _moment_imbalance(profile: DeskProfile, held: HeldPresses, points: np.ndarray) -> np.ndarray:
    """(K, 2) the moment imbalance (N·m) each press leaves with the profile's positions.

    Σ_i x_i fz_ik = x_k W_k + Σ_i My_ik and Σ_i y_i fz_ik = y_k W_k - Σ_i Mx_ik; the
    finger's force is not quite vertical: its horizontal part acts at the board's height."""
    sensors = profile.sensors
    f3 = np.concatenate([held.fxy, held.fz[:, :, None]], axis=2)  # (K, S, 3), sign-corrected
    height = float(profile.surfaces[0].origin[2])
    p3 = np.column_stack([points, np.full(len(points), height)])
    rhs = np.cross(p3, f3.sum(axis=1)) - held.moments.sum(axis=1)  # Σ r_i × F_i must equal this
    z = np.array([s.position[2] for s in sensors])
    target = np.stack(
        [
            -rhs[:, 1] + (z * f3[:, :, 0]).sum(axis=1),  # Σ x_i fz_i
            rhs[:, 0] + (z * f3[:, :, 1]).sum(axis=1),  # Σ y_i fz_i
        ],
        axis=1,
    )  # (K, 2)
    positions = np.array([s.position[:2] for s in sensors])
    return target - held.fz @ positions


def _position_fix(profile: DeskProfile, held: HeldPresses, residual: np.ndarray) -> _PositionFix:
    """The one sensor whose move explains the moment imbalance ``residual`` (> 90 %).

    On a rigid desk the legs' vertical forces are an affine function of the point pressed,
    so with four legs the columns of fz are dependent and positions cannot all be solved
    for. What can: which one sensor, moved, explains the imbalance the presses leave."""
    sensors = profile.sensors
    load = held.fz.sum(axis=1)  # W_k, the press's force (vertical)
    lever = np.sqrt(np.mean(np.sum((residual / load[:, None]) ** 2, axis=1)))  # metres
    if lever <= POSITION_TOLERANCE_M / 2:
        return _PositionFix(None)
    best, best_left, best_shift = -1, np.inf, np.zeros(2)
    for i in range(len(sensors)):
        column = held.fz[:, i]
        shift = column @ residual / max(float(column @ column), 1e-12)  # (2,)
        left = float(np.sum((residual - np.outer(column, shift)) ** 2))
        if left < best_left:
            best, best_left, best_shift = i, left, shift
    explained = 1.0 - best_left / float(np.sum(residual**2))
    s = sensors[best]
    off = float(np.hypot(*best_shift))
    if explained > 0.9 and off > POSITION_TOLERANCE_M:
        moved = np.asarray(s.position[:2], dtype=float) + best_shift
        message = (
            f"{s.name} is at ({moved[0]:.3f}, {moved[1]:.3f}) m by the presses, "
            f"{off * 100:.1f} cm from the profile's ({s.position[0]:.3f}, {s.position[1]:.3f})"
        )
        return _PositionFix(SetupFinding(s.name, "position", message), best, moved)
    message = (
        f"the presses leave a {lever * 100:.1f} cm lever-arm imbalance no single "
        "sensor's position explains: measure the sensors' positions again"
    )
    return _PositionFix(SetupFinding("", "position", message))


class _Placed(NamedTuple):
    """Where the estimator put each press ((K, 2); 0 where it did not) and whether it did."""

    measured: np.ndarray
    placed: np.ndarray


def _placed(
    profile: DeskProfile, t: np.ndarray, wrench: np.ndarray, windows: list[slice]
) -> _Placed:
    """Where the estimator puts each press (median over its hold of the located samples)."""
    from hapticdesk.estimator import ContactEstimator

    contacts = ContactEstimator(profile).push(t, wrench)
    measured = np.zeros((len(windows), 2))
    placed = np.zeros(len(windows), dtype=bool)
    for k, w in enumerate(windows):
        ok = contacts.located[w]
        if ok.any():
            measured[k] = np.median(contacts.x[w][ok]), np.median(contacts.y[w][ok])
            placed[k] = True
    return _Placed(measured, placed)


def report_dict(report: SetupReport) -> dict[str, Any]:
    """The report as JSON-ready data (the page's set-up panel)."""
    return {
        "points": report.points.tolist(),
        "measured": report.measured.tolist(),
        "placed": report.placed.tolist(),
        "residual_m": [
            None if not np.isfinite(r) else round(float(r), 5) for r in report.residual_m
        ],
        "findings": [
            {"sensor": f.sensor, "kind": f.kind, "message": f.message} for f in report.findings
        ],
        "profile_snippet": report.profile_snippet(),
    }
