"""Stage 6, the methods: which candidate is reported, or how they are fused.

``force`` (the conventional), ``diff``, ``switched`` (paper Fig. 3 with F_tth, F_rth) or
``fused`` (inverse-covariance combination of the candidates, no threshold; a point is
reported when its 1-σ is below ``max_sigma_m``). For ``fused`` the fast and the low-passed
candidates are not fused with each other (they share their noise: one is filtered from the
other's input): the fast one stands in where it is the surer; the candidates on the surface
of the surest one are combined, p = (Σ Σ_i⁻¹)⁻¹ Σ Σ_i⁻¹ p_i, in closed form (2×2).

The per-sample work is ``_locate`` and ``_fuse`` in
:mod:`hapticdesk.estimator.kernel_methods`; these are its constants.
"""

from __future__ import annotations

DET_FLOOR = 1e-12  # a 2×2 covariance is inverted as if its determinant were at least this share
# of the product of its variances (never singular, whatever the scale)
# `fused` leaves out a differentiated candidate this much less sure than the force's: it adds
# under 4 % of the information
DIFF_INFO_RATIO = 25.0
