"""Paper §3.1–3.2 (Fig. 2), reproduced through the estimator's own geometry."""

import numpy as np
import pytest

from hapticdesk.estimator import error_model as em


def test_force_error_range_at_2n_is_the_papers_83_mm():
    # §3.1: F_z = 2 N with ±0.4 N noise puts x = 0.2 m anywhere in 0.17–0.25 m
    xs = em.computed_x(0.2, np.array([2.0, 2.0]), np.array([2.4, 1.6]))
    assert xs[0] == pytest.approx(0.1667, abs=5e-4)
    assert xs[1] == pytest.approx(0.25, abs=5e-4)
    assert em.error_range(0.2, 2.0, em.PAPER_RAW_NOISE_N) == pytest.approx(0.083, abs=5e-4)


def test_differentiated_force_error_range_is_the_papers_2_6_mm():
    # §3.2: −45 N/s at touch with 0.29 N/s differentiated noise
    assert em.error_range(0.2, em.PAPER_RATE_N_S, em.PAPER_RATE_NOISE_N_S) == pytest.approx(
        0.0026, abs=5e-5
    )


def test_ranges_cross_near_3_8_n():
    crossing = em.crossover_force()
    assert crossing == pytest.approx(3.8, abs=0.1)
    curves = em.figure2_curves(np.array([2.0, crossing - 0.2, crossing + 0.2, 10.0]))
    below = curves["force_range_m"] > curves["diff_range_m"]
    assert below.tolist() == [True, True, False, False]


def test_error_range_falls_as_one_over_force():
    r2, r4 = em.error_range(0.2, 2.0, 0.024), em.error_range(0.2, 4.0, 0.024)
    assert r2 / r4 == pytest.approx(2.0, rel=0.01)
