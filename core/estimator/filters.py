"""Streaming filters: second-order sections with carried state, and the pseudo-differentiator.

Settings (the SOS coefficients) are kept apart from state (``zi``, the history ring) that is
created from the first block (ezmsg-sigproc's habit, STYLE.md 7). Arrays are channels-first,
``(C, k)``, so each channel is contiguous in memory for the C filter loop.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy import signal

try:  # the C loop behind scipy.signal.sosfilt, without its per-call checks and copies
    from scipy.signal._sosfilt import _sosfilt as _sosfilt_inplace
except ImportError:  # pragma: no cover - scipy moved it; the public function is equivalent
    _sosfilt_inplace = None


def butter_lowpass_sos(cutoff_hz: float, sample_rate_hz: float, order: int = 2) -> np.ndarray:
    """Butterworth low-pass as second-order sections (stable at any cut-off/rate ratio)."""
    nyquist = sample_rate_hz / 2.0
    if not 0.0 < cutoff_hz < nyquist:
        raise ValueError(
            f"low-pass cut-off must lie between 0 and the Nyquist frequency {nyquist:g} Hz, "
            f"found {cutoff_hz:g} Hz"
        )
    return np.ascontiguousarray(signal.butter(order, cutoff_hz, fs=sample_rate_hz, output="sos"))


def noise_gain(sos: np.ndarray, extra_fir: np.ndarray | None = None, length: int = 0) -> float:
    """Variance gain Σ h² of the filter for white noise (optionally after an FIR stage)."""
    n = length or 1
    impulse = np.zeros(max(n, 64))
    impulse[0] = 1.0
    if extra_fir is not None:
        impulse = np.convolve(impulse, extra_fir)[: len(impulse)]
    h = signal.sosfilt(sos, impulse)
    return float(np.sum(h * h))


def group_delay_s(sos: np.ndarray, sample_rate_hz: float, length: int) -> float:
    """The low-pass's delay at low frequencies, seconds: the centroid of its impulse response
    over ``length`` samples (how far a ramp lags behind once the filter has settled)."""
    impulse = np.zeros(length)
    impulse[0] = 1.0
    h = signal.sosfilt(sos, impulse)
    return float(np.sum(np.arange(length) * h) / np.sum(h)) / sample_rate_hz


class SosFilter:
    """A low-pass over C channels, pushed one block at a time.

    The first sample sets the state to steady state (no start-up transient), as does
    :meth:`restart` after a gap. Output is identical for any split of the input into blocks.
    """

    def __init__(self, sos: np.ndarray, channels: int) -> None:
        self.sos = np.ascontiguousarray(sos, dtype=float)
        # for lanes packed in pairs as complex numbers (see :func:`pack_pairs`)
        self._sos_complex = self.sos.astype(complex)
        self.channels = channels
        self._zi_unit = signal.sosfilt_zi(self.sos)  # (n_sections, 2) for a unit step
        self.zi: np.ndarray | None = None  # (C, n_sections, 2)
        # single samples (:meth:`step`) run on plain numbers, where numpy's per-call cost
        # would dominate: the state then lives here, per channel [z0, z1] of each section,
        # until a block needs it back in ``zi`` (:meth:`_to_array`)
        self._coefs = [(b0, b1, b2, a1, a2) for b0, b1, b2, _, a1, a2 in self.sos.tolist()]
        self._state: list[list[Any]] | None = None

    def restart(self, x0: np.ndarray) -> None:
        """Set the state as if ``x0`` (C,) had been the input forever."""
        x0 = np.asarray(x0)
        x0 = x0.astype(complex if np.iscomplexobj(x0) else float, copy=False)
        self.zi = np.ascontiguousarray(x0[:, None, None] * self._zi_unit)
        self._state = None

    def shift(self, delta: np.ndarray) -> None:
        """Move the state as if ``delta`` had been subtracted from all past input."""
        self._to_array()
        if self.zi is not None:
            self.zi -= np.asarray(delta)[:, None, None] * self._zi_unit

    def step(self, x: list[Any]) -> list[Any]:
        """:meth:`process` for one sample of the C channels as plain numbers (float or
        complex), once the state is set: the same recursion as scipy's ``sosfilt``, so the
        same output to rounding."""
        state = self._state
        if state is None:
            assert self.zi is not None
            state = self._state = self.zi.reshape(self.channels, -1).tolist()
            self.zi = None  # (the state is in _state until _to_array)
        out = []
        for lane, value in zip(state, x, strict=True):
            j = 0
            for b0, b1, b2, a1, a2 in self._coefs:
                y = b0 * value + lane[j]
                lane[j] = b1 * value - a1 * y + lane[j + 1]
                lane[j + 1] = b2 * value - a2 * y
                value = y
                j += 2
            out.append(value)
        return out

    def _to_array(self) -> None:
        """The state of :meth:`step` back into ``zi`` for a block."""
        if self._state is not None:
            self.zi = np.array(self._state).reshape(self.channels, -1, 2)
            self._state = None

    def process(self, x: np.ndarray, in_place: bool = False) -> np.ndarray:
        """Filter ``x`` (C, k), real or complex (lanes packed in pairs: one recursion filters
        two lanes, as the real and imaginary part); returns a new (C, k) array, or ``x``
        itself filtered when ``in_place`` (it must then be C-contiguous)."""
        dtype = complex if np.iscomplexobj(x) else float
        y = x if in_place else np.array(x, dtype=dtype, order="C", copy=True)
        if y.shape[1] == 0:
            return y
        self._to_array()
        if self.zi is None:
            self.restart(y[:, 0])
        assert self.zi is not None
        if _sosfilt_inplace is not None:
            # filters y and updates zi in place; a real coefficient times a complex sample
            # gives exactly the real lane's products, so packing changes no bit (for finite
            # samples: the estimator filters no other)
            _sosfilt_inplace(self._sos_complex if dtype is complex else self.sos, y, self.zi)
            return y
        out, zf = signal.sosfilt(self.sos, y, axis=1, zi=np.moveaxis(self.zi, 0, 1))
        self.zi = np.ascontiguousarray(np.moveaxis(zf, 1, 0))
        y[...] = out
        return y


def pack_pairs(x: np.ndarray) -> np.ndarray:
    """(2C, k) real lanes as (C, k) complex ones: lane i + 1j·lane C+i. A recursive filter is
    latency-bound per lane, so filtering a complex lane costs little more than a real one:
    force and moment of a wrench go through together."""
    c = x.shape[0] // 2
    out = np.empty((c, x.shape[1]), complex)
    out.real = x[:c]
    out.imag = x[c:]
    return out


class DelayLine:
    """Remembers the last ``n`` samples of C channels to give x[i − n] for every new x[i].

    Used by the pseudo-differentiator, paper eq. (8): f'(t) = (f(t) − f(t − n·T_s)) / (n·T_s).
    A ring buffer, so a one-sample push costs the same as any other.
    """

    def __init__(self, n: int, channels: int) -> None:
        if n < 1:
            raise ValueError(f"the delay must be at least one sample, found {n}")
        self.n = n
        self.channels = channels
        self.ring: np.ndarray | None = None  # (C, n); ring[:, pos] is the oldest sample
        self.pos = 0
        # single samples (:meth:`step_one`) keep the history as plain numbers, one list of the
        # C channels per slot, until a block needs it back in ``ring`` (:meth:`_to_array`)
        self._slots: list[list[Any]] | None = None

    def restart(self, x0: np.ndarray) -> None:
        """Fill the history with ``x0`` so the first differences are zero."""
        x0 = np.asarray(x0)
        x0 = x0.astype(complex if np.iscomplexobj(x0) else float, copy=False)
        self.ring = np.repeat(x0[:, None], self.n, axis=1)
        self.pos = 0
        self._slots = None

    def step_one(self, x: list[Any], m: int = 0) -> tuple[list[Any], list[Any]]:
        """:meth:`step` for one sample as plain numbers, once started: x − x[−n], and also
        x − x[−m] (1 ≤ m ≤ n; ``m`` 0: not wanted, an empty list)."""
        slots = self._slots
        if slots is None:
            assert self.ring is not None
            slots = self._slots = self.ring.T.tolist()
        pos, n = self.pos, self.n
        old = slots[pos]
        out = [a - b for a, b in zip(x, old, strict=True)]
        recent = [a - b for a, b in zip(x, slots[(pos + n - m) % n], strict=True)] if m else []
        slots[pos] = x
        self.pos = pos + 1 if pos + 1 < n else 0
        return out, recent

    def _to_array(self) -> None:
        """The history of :meth:`step_one` back into ``ring`` for a block."""
        if self._slots is not None:
            self.ring = np.array(self._slots).T.copy()
            self._slots = None

    def difference(self, x: np.ndarray) -> np.ndarray:
        """x[i] − x[i − n] for each column of ``x`` (C, k); updates the history. Saves the
        copy :meth:`delayed` makes when the block is longer than the delay."""
        k = x.shape[1]
        if k <= self.n:
            return x - self.delayed(x)
        self._to_array()
        if self.ring is None:
            self.restart(x[:, 0])
        assert self.ring is not None
        out = np.empty_like(x)
        pos = self.pos
        np.subtract(x[:, : self.n - pos], self.ring[:, pos:], out=out[:, : self.n - pos])
        if pos:
            np.subtract(
                x[:, self.n - pos : self.n], self.ring[:, :pos], out=out[:, self.n - pos : self.n]
            )
        np.subtract(x[:, self.n :], x[:, : k - self.n], out=out[:, self.n :])
        self.ring = np.array(x[:, -self.n :])
        self.pos = 0
        return out

    def step(self, x: np.ndarray) -> np.ndarray:
        """:meth:`difference` for one sample ``x`` (C,): x − x[−n]; updates the history."""
        self._to_array()
        if self.ring is None:
            self.restart(x)
        assert self.ring is not None
        pos = self.pos
        out = x - self.ring[:, pos]
        self.ring[:, pos] = x
        self.pos = pos + 1 if pos + 1 < self.n else 0
        return out

    def recent_difference(self, x: np.ndarray, m: int) -> np.ndarray:
        """x[i] − x[i − m] for each column of ``x`` (C, k), m ≤ n, from the same history as
        :meth:`difference` (call it first: this one does not update the history)."""
        self._to_array()
        assert self.ring is not None and 1 <= m <= self.n
        k, pos = x.shape[1], self.pos
        last = np.concatenate([self.ring[:, pos:], self.ring[:, :pos]], axis=1)[:, self.n - m :]
        if k <= m:
            return x - np.concatenate([last, x], axis=1)[:, :k]
        out = np.empty_like(x)
        np.subtract(x[:, :m], last, out=out[:, :m])
        np.subtract(x[:, m:], x[:, : k - m], out=out[:, m:])
        return out

    def delayed(self, x: np.ndarray) -> np.ndarray:
        """x[i − n] for each column of ``x`` (C, k); updates the history."""
        k = x.shape[1]
        if k == 0:
            return x.copy()
        self._to_array()
        if self.ring is None:
            self.restart(x[:, 0])
        assert self.ring is not None
        n, pos = self.n, self.pos
        if k == 1:
            out = self.ring[:, pos : pos + 1].copy()
            self.ring[:, pos] = x[:, 0]
            self.pos = pos + 1 if pos + 1 < n else 0
            return out
        history = np.concatenate([self.ring[:, pos:], self.ring[:, :pos]], axis=1)
        joined = np.concatenate([history, x], axis=1)
        self.ring = np.array(joined[:, -n:])
        self.pos = 0
        return joined[:, :k]
