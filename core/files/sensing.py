"""What a desk's sensors see of the wrench, and what follows for locating a touch.

Six-axis sensors see the whole resultant [F_o; M_o]. Load cells under the legs see only the
force along their axes: four upright cells give F_z, M_x and M_y (paper eqs. 1–4 with the
other rows zero), so a push along the board (F_x, F_y) and a twist (M_z) are invisible, and
the estimator takes them as zero: the line of action is then vertical, which on a horizontal
board gives the centre of pressure x = −M_y / F_z, y = M_x / F_z (paper eq. 5 with F_x = F_y
= 0). A force plate's calibration matrix sees all six.

A component, or any combination of them, is *seen* when it lies in the row space of the
desk's map from raw channels to the wrench (:meth:`DeskProfile.wrench_map`): some weighting
of the channels measures it whatever the rest of the wrench does.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hapticdesk.files.profile import DeskProfile, Surface

COMPONENTS = ("Fx", "Fy", "Fz", "Mx", "My", "Mz")
# a direction is in the row space when the map's rows explain all but this share of it
_IN_ROW_SPACE = 1e-9


def _row_space(wrench_map: np.ndarray) -> np.ndarray:
    """(6, r) an orthonormal basis of the row space of the (6, C) map."""
    u, singular, _ = np.linalg.svd(wrench_map, full_matrices=False)
    if singular.size == 0 or singular[0] <= 0:
        return np.zeros((6, 0))
    keep = singular > singular[0] * 1e-10
    return u[:, keep]


def sees(wrench_map: np.ndarray, direction: np.ndarray) -> bool:
    """True when the channels measure ``direction`` · [F_o; M_o] (a 6-vector)."""
    direction = np.asarray(direction, dtype=float)
    basis = _row_space(wrench_map)
    left = direction - basis @ (basis.T @ direction)
    return float(left @ left) <= _IN_ROW_SPACE * float(direction @ direction)


@dataclass(frozen=True)
class Sensing:
    """What one desk sees: the wrench components, and per surface whether a touch on it can
    be located and whether a finger's drag along it (shear) is seen."""

    seen: tuple[str, ...]  # of COMPONENTS
    unseen: tuple[str, ...]
    locatable: dict[str, bool]  # surface name -> a touch there can be located
    shear_seen: dict[str, bool]  # surface name -> a drag along it is seen

    def lines(self) -> list[str]:
        """What ``check`` and ``characterize`` print about it."""
        out = [f"the sensors see {', '.join(self.seen)} of the wrench"]
        if self.unseen:
            out[0] += f"; not {', '.join(self.unseen)}"
            if "Fx" in self.unseen and "Fy" in self.unseen and "Fz" in self.seen:
                out[0] += " (taken as zero: the line of action is taken as vertical)"
            else:
                out[0] += " (taken as zero)"
        for name, ok in self.locatable.items():
            if not ok:
                out.append(
                    f"surface {name!r}: a touch there cannot be located (the sensors do not "
                    "see the force into it and the moments about its axes)"
                )
            elif not self.shear_seen[name]:
                out.append(
                    f"surface {name!r}: a finger's drag along it is not seen (no shear): a "
                    "swipe is told by its located points alone (no check against the drag, "
                    "no quick flick the points cannot follow), a tap by its movement alone"
                )
        return out


def surface_locatable(wrench_map: np.ndarray, surface: Surface) -> bool:
    """True when a touch on ``surface`` can be located: the channels see the force into it
    and the moments about both of its in-plane axes (what the intersection of the line of
    action with the plane needs, given zero for what is not seen)."""
    zero = np.zeros(3)
    return all(
        sees(wrench_map, np.concatenate(parts))
        for parts in (
            (surface.normal, zero),
            (zero, surface.u_axis),
            (zero, surface.v_axis),
        )
    )


def shear_seen(wrench_map: np.ndarray, surface: Surface) -> bool:
    """True when a drag along ``surface`` (the force along both its in-plane axes) is seen."""
    zero = np.zeros(3)
    return sees(wrench_map, np.concatenate((surface.u_axis, zero))) and sees(
        wrench_map, np.concatenate((surface.v_axis, zero))
    )


def sensing_of(profile: DeskProfile) -> Sensing:
    """What ``profile``'s sensors see."""
    wrench_map = profile.wrench_map()
    seen = tuple(c for i, c in enumerate(COMPONENTS) if sees(wrench_map, np.eye(6)[i]))
    return Sensing(
        seen=seen,
        unseen=tuple(c for c in COMPONENTS if c not in seen),
        locatable={s.name: surface_locatable(wrench_map, s) for s in profile.surfaces},
        shear_seen={s.name: shear_seen(wrench_map, s) for s in profile.surfaces},
    )
