"""The paper's error model for small forces (§3.1–3.2, Fig. 2), computed through our geometry.

A contact at x on the top board, height h, with a vertical force F_z: the computed point is
x = (h·F_x − M_y)/F_z (paper eq. 5 / 7). Noise of amplitude a on F_z (with M_y exact) moves
the computed x between x·F/(F + a) and x·F/(F − a): an error range that grows as 1/F. The
same with the differentiated force (paper eq. 12 / 16), where Ḟ_z ≈ −45 N/s at touch and the
differentiated noise is small, gives a far narrower range. Every number here is computed by
:func:`hapticdesk.estimator.intersection.intersect`, the code the estimator runs, on a wrench
built for the case — not by a formula copied beside the paper's figures.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import brentq

from hapticdesk.estimator.geometry import SurfaceFrame
from hapticdesk.estimator.intersection import intersect
from hapticdesk.files.profile import Surface

PAPER_X_M = 0.2  # the contact's distance from the centre in §3.1
PAPER_HEIGHT_M = 0.733  # Table 1: sensor to top board
PAPER_RAW_NOISE_N = 0.4  # §3.1: raw noise amplitude on F_z
PAPER_FILTERED_NOISE_N = 0.024  # §3.1: after the conventional second-order low-pass
PAPER_RATE_N_S = 45.0  # §3.2: mean |dF_z/dt| at touch, five subjects
PAPER_RATE_NOISE_N_S = 0.29  # §3.2: differentiated-noise amplitude


def _board(height_m: float) -> SurfaceFrame:
    big = 1e9  # an unbounded board: the model is about the formula, not the outline
    return SurfaceFrame.of(
        Surface(
            name="top",
            origin=np.array([0.0, 0.0, height_m]),
            normal=np.array([0.0, 0.0, 1.0]),
            u_axis=np.array([1.0, 0.0, 0.0]),
            v_axis=np.array([0.0, 1.0, 0.0]),
            polygon=np.array([[-big, -big], [big, -big], [big, big], [-big, big]]),
        )
    )


def computed_x(
    x_m: float, fz: np.ndarray, fz_measured: np.ndarray, height_m: float = PAPER_HEIGHT_M
) -> np.ndarray:
    """x computed from a measured F_z when the true F_z (which sets M_y) was ``fz``.

    The wrench of the supports for a vertical push at (x, 0, h): F_o = (0, 0, F_z),
    M_o = r × F_o = (0, −x·F_z, 0). Only F_z carries noise here, as in the paper.
    """
    fz = np.atleast_1d(np.asarray(fz, dtype=float))
    fz_measured = np.atleast_1d(np.asarray(fz_measured, dtype=float))
    n = len(fz_measured)
    wrench = np.zeros((6, n))
    wrench[2] = fz_measured
    wrench[4] = -x_m * np.broadcast_to(fz, (n,))
    hit = intersect([_board(height_m)], wrench, 1.0, None, 0.0)
    return np.where(hit.valid, hit.uv[0], np.nan)


def error_range(x_m: float, value: float, noise: float, height_m: float = PAPER_HEIGHT_M) -> float:
    """Width of the interval of computed x when ``value`` (F_z, or Ḟ_z) carries ±``noise``."""
    xs = computed_x(
        x_m, np.array([value, value]), np.array([value + noise, value - noise]), height_m
    )
    return float(np.ptp(xs))


def crossover_force(
    x_m: float = PAPER_X_M,
    filtered_noise_n: float = PAPER_FILTERED_NOISE_N,
    rate_n_s: float = PAPER_RATE_N_S,
    rate_noise_n_s: float = PAPER_RATE_NOISE_N_S,
) -> float:
    """The force below which the differentiated force gives the narrower range (Fig. 2)."""
    diff_range = error_range(x_m, rate_n_s, rate_noise_n_s)
    return float(
        brentq(
            lambda f: error_range(x_m, f, filtered_noise_n) - diff_range,
            filtered_noise_n * 1.01,
            1e3,
        )
    )


def figure2_curves(forces_n: np.ndarray, x_m: float = PAPER_X_M) -> dict[str, np.ndarray]:
    """Fig. 2: error range against force for the filtered force and for the differentiated one."""
    force = np.array([error_range(x_m, f, PAPER_FILTERED_NOISE_N) for f in forces_n])
    diff = np.full(len(forces_n), error_range(x_m, PAPER_RATE_N_S, PAPER_RATE_NOISE_N_S))
    return {
        "force_n": np.asarray(forces_n, dtype=float),
        "force_range_m": force,
        "diff_range_m": diff,
    }
