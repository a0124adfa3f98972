"""Rigid-body maths a desk needs: the cross-product matrix, a rotation from roll, pitch and
yaw, a body's spatial inertia about the desk origin, and whether three principal moments of
inertia can belong to a body."""

from __future__ import annotations

import math

import numpy as np


def skew(v: np.ndarray) -> np.ndarray:
    """[v]×, the matrix with [v]× w = v × w."""
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def is_body_inertia(moments: list[float] | tuple[float, ...]) -> bool:
    """Three principal moments of inertia a body can have: finite, positive, each at most the
    sum of the other two."""
    return all(math.isfinite(v) and v > 0 for v in moments) and max(moments) <= (
        sum(moments) - max(moments)
    ) * (1 + 1e-9)


def spatial_inertia(mass_kg: float, center_of_mass: np.ndarray, inertia: np.ndarray) -> np.ndarray:
    """The (6, 6) spatial inertia M about the desk origin for small motions q = [d; θ]: the
    inertial wrench about the origin is M q̈ = [m (d̈ + θ̈ × c); m c × d̈ + I_o θ̈], with
    ``inertia`` (3, 3) about the centre of mass c and I_o = I_c − m [c]×² (parallel axes)."""
    cx = skew(np.asarray(center_of_mass, dtype=float))
    mass = np.zeros((6, 6))
    mass[:3, :3] = mass_kg * np.eye(3)
    mass[:3, 3:] = -mass_kg * cx
    mass[3:, :3] = mass_kg * cx
    mass[3:, 3:] = inertia - mass_kg * cx @ cx
    return mass


def rotation_matrix(roll_deg: float, pitch_deg: float, yaw_deg: float) -> np.ndarray:
    """R = Rz(yaw) · Ry(pitch) · Rx(roll): the sensor frame expressed in the desk frame."""
    r, p, y = (math.radians(v) for v in (roll_deg, pitch_deg, yaw_deg))
    cr, sr, cp, sp, cy, sy = (
        math.cos(r),
        math.sin(r),
        math.cos(p),
        math.sin(p),
        math.cos(y),
        math.sin(y),
    )
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx
