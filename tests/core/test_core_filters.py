"""The estimator's filters designed with numpy equal scipy.signal's design to the bit (the
estimator no longer imports scipy.signal: over a second of start-up)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from hapticdesk.estimator.filters import (
    butter_lowpass_sos,
    group_delay_s,
    impulse_response,
    noise_gain,
    sosfilt_zi,
)

CASES = [
    (fs, fc)
    for fs in (50.0, 80.0, 100.0, 1000.0, 1200.0, 10000.0)
    for fc in (0.1, 0.5, 5.0, 20.0, 0.3 * fs, 0.45 * fs, 0.49 * fs)
    if fc < fs / 2
]


@pytest.mark.parametrize(("fs", "fc"), CASES)
def test_design_equals_scipy(fs: float, fc: float) -> None:
    ours, theirs = butter_lowpass_sos(fc, fs), signal.butter(2, fc, fs=fs, output="sos")
    assert ours.shape == theirs.shape == (1, 6)
    # the same steps: equal to the bit, but for a last bit where the cut-off nears Nyquist
    np.testing.assert_allclose(ours, theirs, rtol=1e-15, atol=1e-16)
    ours = theirs  # (what follows from a design: to the bit)
    assert np.array_equal(sosfilt_zi(ours), signal.sosfilt_zi(theirs))
    length = 3000
    impulse = np.zeros(length)
    impulse[0] = 1.0
    h = signal.sosfilt(theirs, impulse)
    assert np.array_equal(impulse_response(ours, length), h)
    fir = np.zeros(13)
    fir[0], fir[-1] = 1.0, -1.0
    want = np.convolve(impulse, fir)[:length]
    want = signal.sosfilt(theirs, want)
    assert noise_gain(ours, fir, length) == float(np.sum(want**2))
    centroid = float(np.sum(np.arange(length) * h) / np.sum(h)) / fs
    assert group_delay_s(ours, fs, length) == centroid


def test_cascade_steady_state_and_response() -> None:
    """Two sections: the second's steady state is scaled by the first's DC gain, and the
    response is the sections' responses convolved (as scipy's)."""
    sos = np.vstack([butter_lowpass_sos(5.0, 1200.0), butter_lowpass_sos(40.0, 1200.0)])
    sos[0, :3] *= 2.5  # (a DC gain other than 1)
    assert np.array_equal(sosfilt_zi(sos), signal.sosfilt_zi(sos))
    impulse = np.zeros(500)
    impulse[0] = 1.0
    assert np.array_equal(impulse_response(sos, 500), signal.sosfilt(sos, impulse))


def test_refuses_a_cutoff_beyond_nyquist() -> None:
    with pytest.raises(ValueError, match="Nyquist"):
        butter_lowpass_sos(600.0, 1200.0)
