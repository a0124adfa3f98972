"""The tare's zero and noise over its quiet windows (tare.py)."""

import numpy as np

from hapticdesk.estimator.tare import Tare


def _quiet_windows(rng: np.random.Generator, n: int, w: int) -> list[np.ndarray]:
    """``n`` windows (6, w) of a still, noisy wrench far from 0 (the noise's scale per axis
    as a desk's: newtons and newton-metres)."""
    level = rng.normal(size=(6, 1)) * 50.0
    scale = np.array([0.05, 0.05, 0.1, 0.002, 0.002, 0.001])[:, None]
    return [level + scale * rng.standard_normal((6, w)) for _ in range(n)]


def test_the_tare_noise_is_numpys_covariance_to_the_bit():
    """The noise the tare takes is np.cov of the windows' samples, bit for bit (the kernel's
    covariances, and so the golden outputs, are made from it), and the zero their mean."""
    rng = np.random.default_rng(5)
    for w in (240, 97):
        tare = Tare(n_tare=5, quiet_n=10.0)
        windows = _quiet_windows(rng, 5, w)
        taken = None
        for raw in windows:
            taken = tare.add(0.0, False, raw[:, 0].tolist(), raw)
        assert taken is not None
        samples = np.concatenate(windows, axis=1)
        assert np.array_equal(taken.noise, np.cov(samples))
        assert taken.zero == samples.mean(axis=1).tolist()


def test_a_tare_of_one_sample_has_no_noise_rather_than_nan():
    """A window of one sample and a tare of one window (a desk read at under 10 Hz): the noise
    is 0, where np.cov's was NaN (with a warning)."""
    tare = Tare(n_tare=1, quiet_n=10.0)
    taken = tare.add(0.0, False, [1.0, 2.0, 3.0], np.arange(6.0)[:, None])
    assert taken is not None
    assert np.array_equal(taken.noise, np.zeros((6, 6)))
