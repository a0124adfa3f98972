"""The desk's exact discrete model: a continuous linear model sampled with a zero-order hold
(the matrix exponential of ``[[A, B], [0, 0]]``), diagonalised and run mode by mode as
first-order ``scipy.signal.lfilter`` recursions with carried state, so any split into blocks
gives the same readings. Built by :meth:`hapticdesk.sim.desk.DeskModel.discretize`.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg
import scipy.signal


class DiscreteDesk:
    """``x[k] = Ad x[k-1] + Bd u[k]``, readings ``y[k] = Cy x[k]``, run mode by mode, from the
    continuous ``ẋ = A x + B u``, ``y = C x`` (``a`` (12, 12), ``b`` (12, 6), ``c`` (6S, 12)).

    The state is scaled, ``x̃ = [q; q̇/ω_max]``, so position and velocity have comparable
    magnitudes in the matrix exponential even with modes 10⁴ times apart.
    """

    def __init__(self, a: np.ndarray, b: np.ndarray, c: np.ndarray, dt: float) -> None:
        if not dt > 0:
            raise ValueError(f"the sample time must be positive, found {dt}")
        self.n_sensors = len(c) // 6
        self.dt = float(dt)
        omega = float(np.max(np.abs(np.linalg.eigvals(a))))
        scale = np.concatenate([np.ones(6), np.full(6, omega)])  # x = scale * x̃
        a_s = a * scale[None, :] / scale[:, None]
        b_s = b / scale[:, None]
        aug = np.zeros((18, 18))
        aug[:12, :12] = a_s * dt
        aug[:12, 12:] = b_s * dt
        phi = scipy.linalg.expm(aug)  # ZOH: exact for an input held over each sample
        self.ad = phi[:12, :12]
        self.bd = phi[:12, 12:]
        self._scale = scale
        self.cy = c * scale[None, :]  # (6S, 12)

        lam, vec = np.linalg.eig(self.ad)
        self._modal = bool(np.linalg.cond(vec) < 1e10)
        if self._modal:
            vec_inv = np.linalg.inv(vec)
            self.poles = lam
            self._to_modal = vec_inv
            self._from_modal = vec
            self._b_modal = vec_inv @ self.bd  # (12, 6)
            self._c_modal = self.cy @ vec  # (6S, 12)

    def initial_state(self, load: np.ndarray) -> np.ndarray:
        """The state at rest under a constant load (6,): the discrete model's fixed point, to
        start :meth:`run` from."""
        x = np.linalg.solve(np.eye(12) - self.ad, self.bd @ np.asarray(load, dtype=float))
        return self._to_internal(x)

    def _to_internal(self, x: np.ndarray) -> np.ndarray:
        return self._to_modal @ x if self._modal else x.astype(complex)

    def run(self, loads: np.ndarray, state: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Readings (k, S, 6) for loads (k, 6); returns the state to continue from.

        Each sample's load is held over the sample interval that ends at it (a zero-order
        hold aligned so a reading responds to the load at its own time, not one sample
        late). ``state`` comes from :meth:`initial_state` or a previous ``run``; running two
        blocks in turn equals running them joined.
        """
        loads = np.asarray(loads, dtype=float)
        k = len(loads)
        x, state = self._states(loads, state)
        flat = (x @ self._c_modal.T).real if self._modal else (x @ self.cy.T).real
        return flat.reshape(k, self.n_sensors, 6), state

    def motion(self, loads: np.ndarray, state: np.ndarray) -> np.ndarray:
        """The desk's motion ``[q, q̇]`` (k, 12) at each sample (for tests and accelerometers)."""
        x, _ = self._states(np.asarray(loads, dtype=float), state)
        return self._physical(x)

    def run_moving(
        self, loads: np.ndarray, state: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`run` that also gives the motion ``[q, q̇]`` (k, 12) of each sample (for an
        accelerometer on the desk), from one pass over the modes."""
        loads = np.asarray(loads, dtype=float)
        k = len(loads)
        x, state = self._states(loads, state)
        flat = (x @ self._c_modal.T).real if self._modal else (x @ self.cy.T).real
        return flat.reshape(k, self.n_sensors, 6), self._physical(x), state

    def _physical(self, x: np.ndarray) -> np.ndarray:
        """Internal states (k, 12) -> ``[q, q̇]`` in metres, radians and their rates."""
        if self._modal:
            x = (x @ self._from_modal.T).real
        return np.asarray(x.real) * self._scale

    def _states(self, loads: np.ndarray, state: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """States after each sample, ``x[n] = Ad x[n-1] + Bd u[n]`` from ``x[-1] = state``
        (modal coordinates when diagonalised). Returns them and the last one."""
        k = len(loads)
        if k == 0:
            return np.zeros((0, 12), dtype=complex), state
        if self._modal:
            drive = loads @ self._b_modal.T  # (k, 12) complex
            z = np.empty((k, 12), dtype=complex)
            for j, pole in enumerate(self.poles):
                # one first-order recursion per mode, z[n] = pole·z[n-1] + drive[n]
                z[:, j], _ = scipy.signal.lfilter(
                    [1.0], np.array([1.0, -pole]), drive[:, j], zi=pole * state[j : j + 1]
                )
            return z, z[-1].copy()
        # A defective (non-diagonalisable) system: fall back to the plain recursion.
        xs = np.empty((k, 12))
        x = state.real.copy()
        for n in range(k):
            x = self.ad @ x + self.bd @ loads[n]
            xs[n] = x
        return xs, x.astype(complex)
