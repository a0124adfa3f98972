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


#: the narrowest footprint a touch is located on, as a share of its length (see
#: :func:`thin_footprint`)
MIN_FOOTPRINT_SHARE = 0.05


@dataclass(frozen=True)
class Footprint:
    """Where the sensors pushing into a surface stand, seen along its normal: the width of
    their convex hull's narrowest strip, its length along the strip, and the sensor farthest
    off the strip's edge (the one whose place sets the width)."""

    width_m: float
    length_m: float
    widest: int  # index into the desk's sensors

    @property
    def share(self) -> float:
        return self.width_m / self.length_m if self.length_m > 0 else 0.0


def thin_footprint(profile: DeskProfile, surface: Surface) -> Footprint | None:
    """The footprint of the sensors under ``surface`` when a touch on it is located through
    it and it is too thin for that (narrower than :data:`MIN_FOOTPRINT_SHARE` of its length);
    None otherwise.

    Why the footprint and this share: where the sensors measure no moment themselves (load
    cells, three-axis cells), the moments about the surface's axes come only from the forces
    times the legs' places (paper eqs. 1–4). Legs a width w off one line, touched a distance d
    beside it, must push and pull by about F·d/w to hold the moment; a mounting error δ in a
    leg's place then moves the located point by about d·δ/w. With d up to half the length L,
    a millimetre of δ costs centimetres unless w is some percent of L: at 5 % and L = 0.7 m,
    1 mm moves a touch at the edge by 1 cm (and the legs carry 10 times the touch). The same
    ratio sets the conditioning of the map from the legs' forces to (F, M_u, M_v), moments
    over L: its smallest singular value against its largest is of the order of w/L (0.47 w/L
    for three legs), but the footprint says which leg to move and how far, in millimetres.
    Sensors that measure the moments themselves (six-axis, a force plate's calibrated
    channels) need no footprint. Every shipped desk's is over 50 %.
    """
    own = _own_map(profile)
    zero = np.zeros(3)
    if sees(own, np.concatenate((zero, surface.u_axis))) and sees(
        own, np.concatenate((zero, surface.v_axis))
    ):
        return None
    pushing = [
        i
        for i, s in enumerate(profile.sensors)
        if np.abs(surface.normal @ (s.rotation @ s.own_wrench_matrix()[:3])).max() > 1e-9
    ]
    if len(pushing) < 3:  # (the moments come from elsewhere, or are not seen: refused before)
        return None
    places = np.array([profile.sensors[i].position - surface.origin for i in pushing])
    flat = np.column_stack((places @ surface.u_axis, places @ surface.v_axis))
    width, length, widest = _narrowest_strip(flat)
    found = Footprint(width, length, pushing[widest])

    return found if found.share < MIN_FOOTPRINT_SHARE else None


def _own_map(profile: DeskProfile) -> np.ndarray:
    """(6, C): the channels to what the sensors measure themselves, each in the desk's axes,
    without the moments their forces make about P_o (no lever arms)."""
    blocks = []
    for s in profile.sensors:
        block = np.zeros((6, 6))
        block[:3, :3] = block[3:, 3:] = s.rotation
        blocks.append(block @ s.own_wrench_matrix())
    return np.hstack(blocks)


def _narrowest_strip(points: np.ndarray) -> tuple[float, float, int]:
    """(width, length, index) of the narrowest strip holding the (N, 2) ``points``: a convex
    hull's narrowest strip lies along one of its edges (rotating calipers), so each edge's
    direction is tried; ``index`` is the point farthest from that edge."""
    hull = _convex_hull(points)
    if len(hull) < 2:
        return 0.0, 0.0, 0
    best = (np.inf, 0.0, 0)
    for a, b in zip(hull, np.roll(hull, -1), strict=True):
        along = points[b] - points[a]
        norm = float(np.hypot(*along))
        if norm == 0.0:
            continue
        along /= norm
        across = np.array([-along[1], along[0]])
        offsets, spread = (points - points[a]) @ across, (points - points[a]) @ along
        width = float(np.ptp(offsets))
        if width < best[0]:
            best = (width, float(np.ptp(spread)), int(np.argmax(np.abs(offsets))))
    return best


def _convex_hull(points: np.ndarray) -> np.ndarray:
    """Indices of the (N, 2) ``points``' convex hull, counter-clockwise (Andrew's monotone
    chain: bounded by N log N, whatever the number of sensors); all of a line's two ends."""
    order = np.lexsort((points[:, 1], points[:, 0]))

    def half(indices: np.ndarray) -> list[int]:
        chain: list[int] = []
        for i in indices.tolist():
            while len(chain) >= 2:
                o, a = points[chain[-2]], points[chain[-1]]
                cross = (a[0] - o[0]) * (points[i][1] - o[1]) - (a[1] - o[1]) * (
                    points[i][0] - o[0]
                )
                if cross > 0:
                    break
                chain.pop()
            chain.append(i)
        return chain

    lower, upper = half(order), half(order[::-1])
    return np.array(lower[:-1] + upper[:-1], dtype=int)
