"""Where the lines of action of many wrenches meet a desk's surfaces, by the estimator's own
compiled code (``kernel_geometry.intersect``, sample by sample): for the paper's error model and the
tests, which ask it for whole arrays. (Apart from :mod:`.geometry` because it needs the
kernel's parameters, :mod:`.params`, which need the geometry's frames.)"""

from __future__ import annotations

import numpy as np

from hapticdesk.estimator.geometry import Intersection, SurfaceFrame, pack_cov
from hapticdesk.estimator.kernel import intersect_block
from hapticdesk.estimator.params import geometry_params


def intersect(
    frames: list[SurfaceFrame],
    wrench: np.ndarray,
    direction_sign: np.ndarray | float,
    covs: list[np.ndarray] | None,
    min_normal_cos: float,
    extra_var: np.ndarray | float = 0.0,
    drift_covs: list[np.ndarray] | None = None,
    drift_scale: np.ndarray | float = 0.0,
    force_norm: np.ndarray | None = None,
) -> Intersection:
    """Intersect the lines of action of ``wrench`` (6, n) = [F; M] with every surface, by the
    estimator's own code (``kernel_geometry.intersect``, sample by sample).

    ``direction_sign`` (n,) or scalar: +1 where F points like the supports' force F_o (the
    finger pushes along −F_o), −1 where it points the other way (a releasing differentiated
    force). ``covs``: per surface, :meth:`SurfaceFrame.project_cov` of the wrench's noise
    covariance (None: no uncertainty). ``extra_var`` (n,) is added to both in-plane variances
    (a model error). ``force_norm`` (n,): |F| when the caller has it. ``drift_covs`` (like
    ``covs``) times ``drift_scale`` (n,) is added to the wrench covariance: the zero's
    uncertainty, growing with its age. Where surfaces overlap, the one the finger reaches
    first along its push wins.
    """
    rows = np.ascontiguousarray(np.asarray(wrench, dtype=float).T)
    n = len(rows)
    pf, pi = geometry_params(frames, min_normal_cos)
    packed = np.zeros(max(1, len(frames)) * 24)
    for index in range(len(frames)):
        if covs is not None:
            packed[24 * index : 24 * index + 6] = pack_cov(covs[index])
        if drift_covs is not None:
            packed[24 * index + 18 : 24 * index + 24] = pack_cov(drift_covs[index])
    norm = (
        np.sqrt(np.einsum("ki,ki->k", rows[:, :3], rows[:, :3]))
        if force_norm is None
        else force_norm
    )
    out = np.empty((n, 6))

    def each(value: np.ndarray | float) -> np.ndarray:
        return np.ascontiguousarray(np.broadcast_to(np.asarray(value, dtype=float), (n,)))

    intersect_block(
        pf,
        pi,
        rows,
        each(direction_sign),
        packed,
        0 if covs is not None else -1,
        18 if covs is not None and drift_covs is not None else -1,
        each(drift_scale),
        each(extra_var),
        each(norm),
        out,
    )
    surface = out[:, 0].astype(np.int16)
    return Intersection(
        surface >= 0, surface, np.ascontiguousarray(out[:, 1:3].T), out[:, 3], out[:, 4], out[:, 5]
    )
