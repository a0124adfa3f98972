"""The sensors' resolution, learned from their readings: each channel's smallest change.

A sensor reports in steps (an ADC count times a scale; 1/2000 of the rating for the paper's
sensors, Table 2). Where its noise is well below one step, the noise measured at the tare
misses two errors: at rest a channel sits on one step, so the tare sees almost no noise,
though a reading in motion is off by up to half a step (variance step²/12, and slow: a force
that changes by less than a step per sample keeps its rounding error for many samples, so
the low-pass does not average it away); and the zero itself is off by up to half a step on
every channel for as long as it is kept. Where the noise is a step or more it dithers the
rounding: the measured noise already holds the step²/12 and the tare's mean is true.
:func:`rounding_deficit` is the part of the rounding the measured noise lacks.

A channel's step is the smallest non-zero change between two consecutive good readings:
readings on a grid change by whole steps. Readings off a grid (floats, a CSV with many
decimals, the gauges of a sensor decoded through its calibration matrix) change by far less
than their noise, so their "step" adds nothing. A channel stops learning after
``CONFIRM_CHANGES`` changes; a quiet one learns its step at the first touches (until then it
has none, 0). Once tared, a step that is new or shrank by more than ``STEP_CHANGE`` makes the
covariances anew, used from the sample whose reading taught it (``_learn_steps`` and
``steps_changed`` in :mod:`hapticdesk.estimator.kernel_channels`).

Measured (``python scripts/tap_accuracy.py --desk paper --noise N``, 1,000 edge taps): a
sensor whose noise no longer dithers its steps (below about 0.3 N on the paper desk's total
F_z) placed taps from the zero's offset and the differentiated force's rounding with a
confidence they did not have; see docs/stability.md.
"""

from __future__ import annotations

import numpy as np

# changes a channel's smallest change is taken over before it counts as its step: a quiet
# channel pressed quickly moves by several steps at a time at first, a held press by one
CONFIRM_CHANGES = 200
# a step that shrank by more than this share since the covariances were made remakes them
STEP_CHANGE = 0.1


def rounding_deficit(wrench_map: np.ndarray, step: np.ndarray, measured: np.ndarray) -> np.ndarray:
    """The part of the rounding's covariance (6, 6) the ``measured`` noise (6, 6) lacks: the
    positive part of M diag(step²/12) Mᵀ − measured. Nothing where the noise dithers the
    rounding (the rounding is then in the measured noise), all of it where the channels sat
    on one step at the tare."""
    rounding = wrench_map @ (wrench_map.T * (step**2 / 12.0)[:, None])
    gap = rounding - measured
    values, vectors = np.linalg.eigh((gap + gap.T) / 2.0)
    return (vectors * np.clip(values, 0.0, None)) @ vectors.T
