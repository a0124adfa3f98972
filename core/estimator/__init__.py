"""The contact estimator: raw sensor channels in, contact samples out (paper §2–3, Fig. 3).

One compiled pass per sample (:mod:`.kernel`, numba), the same for a single sample or a
million, so streaming and batch give the same output for any split of the input:

- **settings → parameters**: the profile's :class:`EstimationSettings` become
  :class:`~.settings.EstimatorSettings` (filters designed, windows in samples, surfaces
  prepared), flattened once into the kernel's parameter arrays (:mod:`.params`);
- **state**: one set of arrays per run (filter memories, delay rings, the zero, the window
  being filled, the detector's and the second finger's state); a snapshot is a copy, a
  re-tare resets slices;
- **one kernel, one loop**: a per-sample function over those arrays, looped over a push into
  preallocated output columns, or over a single sample into a reused one-sample record (the
  same machine code); ``push`` returns a view of them (it holds until the next push);
- **event codes**: what happens rarely (a zero window's end, a notice, the covariances made
  anew, a second finger's fit) leaves the loop with a code and the sample's index; Python
  (:class:`~.contact_estimator.ContactEstimator`) handles it and resumes.

The stages, in the order a sample meets them, each with its settings and its Python side in
a module of its name:

1. :mod:`.samples` — bad samples (NaN/inf, a saturated channel, time not increasing, a
   stuck input that repeats its last sample) are flagged and replaced by the last good
   sample, so no filter state is poisoned; a gap in time restarts the filters. The raw
   channels become the resultant wrench [F_o; M_o] about P_o by one general channels→wrench
   matrix (6, C) (paper eqs. 1–4; :meth:`DeskProfile.wrench_map`), each channel's resolution
   step learned (:mod:`.resolution`). With an accelerometer on the desk (:mod:`.inertia`),
   the desk's own inertial force and moment are removed from it.
2. :mod:`.filters` — filters on that wrench: the conventional second-order low-pass; the
   pseudo-differentiated wrench (paper eq. 8: an n-sample difference, then the low-pass); and
   a fast (30 Hz) low-pass for touch-down/release detection that does not wait for the
   position filters; the desk's sway compensated from the legs (:mod:`.sway`).
3. :mod:`.zero` — an automatic tare over the first ``tare_s`` of a quiet desk (refused with
   a warning and retried while the desk is not quiet); the zero then follows sensor drift
   whenever the idle desk rests for ``drift_settle_s``, and a load held perfectly still for
   ``settle_s`` (an object put down) becomes part of it, with a notice.
4. :mod:`.detector` — contact from the tared fast force with hysteresis, and its phase.
5. :mod:`.candidates` — P_er from the force and P_ed from the differentiated force (and,
   for ``fused``, one from the fast wrench), each the intersection of its line of action
   with the surfaces (paper eqs. 5, 12; :mod:`.geometry`), each with a covariance propagated
   from the noise measured at the tare, plus the rounding of channels quieter than their
   resolution step, the zero's drift since it was set and, for P_ed, the term eq. (11) drops.
6. :mod:`.methods` — ``force`` (the conventional), ``diff``, ``switched`` (paper Fig. 3
   with F_tth, F_rth) or ``fused`` (inverse-covariance combination of the candidates, no
   threshold; a point is reported when its 1-σ is below ``max_sigma_m``).
7. :mod:`.multitouch` — optional (``second_finger``, or a layout binding ``two_finger_tap``):
   a second finger that lands while the first holds, flagged ``FLAG_MULTI`` and placed.

Importing this package (or :mod:`.contacts`) imports neither numba nor scipy: they load
with :class:`ContactEstimator`, where estimation happens.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from hapticdesk.estimator.candidate_trace import CandidateTrace
    from hapticdesk.estimator.contact_estimator import ContactEstimator, estimate
    from hapticdesk.estimator.contacts import BAD_SAMPLE
    from hapticdesk.estimator.notices import Notice

__all__ = ["BAD_SAMPLE", "CandidateTrace", "ContactEstimator", "Notice", "estimate"]

# name -> the module that defines it, imported when the name is first used
_LAZY = {
    "BAD_SAMPLE": "hapticdesk.estimator.contacts",
    "CandidateTrace": "hapticdesk.estimator.candidate_trace",
    "ContactEstimator": "hapticdesk.estimator.contact_estimator",
    "Notice": "hapticdesk.estimator.notices",
    "estimate": "hapticdesk.estimator.contact_estimator",
}


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'hapticdesk.estimator' has no attribute {name!r}")
    import importlib

    return getattr(importlib.import_module(module), name)
