"""The tare: the zero and the noise taken over the first ``tare_s`` of a quiet desk.

Before the tare every window the kernel ends comes here (:mod:`hapticdesk.estimator.zero`):
a quiet one (its spread under ``tare_quiet_n``, not held over) is kept with its wrench; once
``n_tare`` quiet windows in a row agree (their means within ``tare_quiet_n`` of each other)
their samples' mean is the zero and their covariance the noise. A window that is not quiet
starts the collection again; so does a load that moved between quiet windows.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from hapticdesk.estimator.yardsticks import wander


class TareWindow(NamedTuple):
    """A quiet window kept for the tare."""

    raw: np.ndarray  # (6, w) its wrench, a copy
    force: list[float]  # (3) its mean force
    spread: float


class Taken(NamedTuple):
    """A tare taken: the zero, the noise, and the windows it was taken over (in a row, the
    last one the window that completed it)."""

    zero: list[float]  # (6) of [F_o; M_o]
    noise: np.ndarray  # (6, 6)
    windows: list[TareWindow]


class Tare:
    """The quiet windows so far (the last ``n_tare``)."""

    def __init__(self, n_tare: int, quiet_n: float) -> None:
        self.n_tare = n_tare
        self.quiet_n = quiet_n
        self.windows: list[TareWindow] = []

    def add(self, spread: float, bad: bool, mean: list[float], raw: np.ndarray) -> Taken | None:
        """One more window before the tare (``raw`` (6, w) its wrench, copied if kept); the
        tare when it completes one."""
        if bad or not spread < self.quiet_n:
            self.windows = []
            return None
        window = TareWindow(raw.copy(), mean[:3], spread)
        self.windows.append(window)
        del self.windows[: -self.n_tare]
        if wander([w.force for w in self.windows]) >= self.quiet_n:
            # each window was quiet, but the load moved between them: start again here
            self.windows = [window]
        if len(self.windows) < self.n_tare:
            return None
        taken, self.windows = self.windows, []
        samples = np.concatenate([w.raw for w in taken], axis=1)
        zero = samples.mean(axis=1)
        return Taken(zero.tolist(), _covariance(samples, zero), taken)


def _covariance(samples: np.ndarray, mean: np.ndarray) -> np.ndarray:
    """The rows' covariance (6, 6) of ``samples`` (6, n) about their ``mean`` (6,): np.cov's
    own steps (the centred rows' product with themselves, times 1 / (n − 1): the same bits),
    without its argument handling and its second mean (half its time, which at the tare's
    one call with its code cold was 0.1 ms of a minute's push). A single sample's is 0, where
    np.cov's was NaN."""
    centred = samples - mean[:, None]
    product = np.dot(centred, centred.T)
    product *= 1.0 / max(samples.shape[1] - 1, 1)
    return product
