"""Both candidates of every sample in contact, kept for research (``trace=True``).

:class:`CandidateTrace` is what :class:`~hapticdesk.estimator.ContactEstimator` keeps in
``traces`` when asked: the paper's D_er and D_ed (and the fast candidate of ``fused``), for
threshold derivation and plots; :meth:`CandidateTrace.of` reads them from the kernel's trace
rows of the output columns.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from hapticdesk.estimator import kernel_slots as slots


@dataclass(frozen=True)
class CandidateTrace:
    """Both candidates for the samples in contact of one push (``trace=True``).

    ``force_n``: |F_o| after the conventional low-pass; ``rate_n_s``: the differentiated force
    magnitude (paper Fig. 3, its sign is the motion); points (3, n) in the desk frame with
    their validity and 1-σ uncertainty: P_er from the force, P_ed from its derivative.
    """

    t: np.ndarray
    force_n: np.ndarray
    rate_n_s: np.ndarray
    force_point: np.ndarray
    force_valid: np.ndarray
    force_sigma_m: np.ndarray
    diff_point: np.ndarray
    diff_valid: np.ndarray
    diff_sigma_m: np.ndarray
    fast_point: np.ndarray  # from the fast (detection) low-pass: the third `fused` candidate
    fast_valid: np.ndarray
    fast_sigma_m: np.ndarray

    @classmethod
    def concat(cls, traces: list[CandidateTrace]) -> CandidateTrace:
        """Join the traces of several pushes."""
        if not traces:
            z = np.zeros(0)
            none = np.zeros((3, 0))
            return cls(
                z, z, z, none, z.astype(bool), z, none, z.astype(bool), z, none, z.astype(bool), z
            )
        return cls(
            **{
                f.name: np.concatenate([getattr(tr, f.name) for tr in traces], axis=-1)
                for f in fields(cls)
            }
        )

    @classmethod
    def of(cls, rows: np.ndarray, at: np.ndarray) -> CandidateTrace:
        """The trace of the samples ``at`` from the output columns' trace rows."""
        trace = rows[slots.N_OUT_F :, at]
        per = [slots.TRACE_CANDIDATES + slots.TRACE_PER_CANDIDATE * j for j in range(3)]
        parts = []
        for p in per:
            parts += [trace[p : p + 3], trace[p + 3] > 0.5, trace[p + 4]]
        return cls(rows[slots.OUT_T, at], trace[slots.TRACE_FORCE], trace[slots.TRACE_RATE], *parts)
