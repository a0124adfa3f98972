"""Fixtures for the gesture tests: synthetic contact streams and layouts written to tmp files."""

from __future__ import annotations

import textwrap
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from hapticdesk.estimator.contacts import PHASE_HOLD, SOURCE_FUSED, ContactBlock
from hapticdesk.gestures.layout import Layout
from hapticdesk.gestures.layout_reader import load_layout

ACTIONS = {"mqtt", "log", "exec", "http"}
PathSpec = tuple[float, float] | np.ndarray | Callable[[np.ndarray], np.ndarray]


class Timeline:
    """A contact stream built by hand: touches on a quiet desk, sampled at ``rate_hz``.

    Each touch has a trapezoid force (``rise_s`` up from the 2 N contact threshold to
    ``force_n`` and back), follows a path (a point, an (n, 2) polyline traced at constant
    speed, or a function of progress u in 0..1), and carries the estimator's σ, which is
    ``sigma_m`` at full force and grows as the force falls (like the paper's error ranges).
    """

    def __init__(self, duration_s: float, rate_hz: float = 1200.0, seed: int = 0) -> None:
        self.t = np.arange(int(round(duration_s * rate_hz))) / rate_hz
        k = len(self.t)
        self.in_contact = np.zeros(k, bool)
        self.x = np.zeros(k)
        self.y = np.zeros(k)
        self.force = np.zeros(k)
        self.sigma = np.full(k, 10.0)
        self.rng = np.random.default_rng(seed)

    def touch(
        self,
        t0: float,
        duration_s: float,
        path: PathSpec,
        force_n: float = 8.0,
        sigma_m: float = 0.001,
        noise: bool = True,
        rise_s: float = 0.03,
        force_profile: Callable[[np.ndarray], np.ndarray] | None = None,
    ) -> Timeline:
        sel = (self.t >= t0) & (self.t < t0 + duration_s)
        u = (self.t[sel] - t0) / duration_s
        if callable(path):
            xy = np.asarray(path(u), dtype=float).reshape(-1, 2)
        else:
            pts = np.asarray(path, dtype=float).reshape(-1, 2)
            if len(pts) == 1:
                xy = np.repeat(pts, len(u), axis=0)
            else:
                s = np.concatenate([[0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))])
                xy = np.column_stack(
                    [np.interp(u * s[-1], s, pts[:, 0]), np.interp(u * s[-1], s, pts[:, 1])]
                )
        tau = self.t[sel] - t0
        if force_profile is not None:
            force = force_profile(tau)
        else:
            ramp = np.minimum(1.0, np.minimum(tau, duration_s - tau) / rise_s)
            force = 2.0 + (force_n - 2.0) * np.clip(ramp, 0, 1)
        sigma = sigma_m * np.maximum(1.0, force_n / np.maximum(force, 1e-3))
        if noise:
            xy = xy + self.rng.normal(size=xy.shape) * sigma[:, None]
        self.in_contact[sel] = True
        self.x[sel], self.y[sel] = xy[:, 0], xy[:, 1]
        self.force[sel] = force
        self.sigma[sel] = sigma
        return self

    def block(self) -> ContactBlock:
        k = len(self.t)
        inc = self.in_contact
        return ContactBlock(
            t=self.t.copy(),
            in_contact=inc.copy(),
            located=inc.copy(),
            surface=np.where(inc, 0, -1).astype(np.int16),
            x=np.where(inc, self.x, 0.0),
            y=np.where(inc, self.y, 0.0),
            z=np.where(inc, 0.733, 0.0),
            force_n=self.force.copy(),
            source=np.where(inc, SOURCE_FUSED, 0).astype(np.int8),
            phase=np.where(inc, PHASE_HOLD, 0).astype(np.int8),
            sigma_m=np.where(inc, self.sigma, 10.0),
            flags=np.zeros(k, np.uint8),
        )


@pytest.fixture
def timeline() -> Callable[..., Timeline]:
    return Timeline


@pytest.fixture
def write_layout(tmp_path: Path) -> Callable[..., Path]:
    """Write layout text (dedented) to a file; returns its path."""

    def write(text: str, name: str = "layout.yaml") -> Path:
        path = tmp_path / name
        path.write_text(textwrap.dedent(text).lstrip("\n"), encoding="utf-8")
        return path

    return write


@pytest.fixture
def make_layout(write_layout: Callable[..., Path]) -> Callable[..., Layout]:
    """Write and load a layout (desk kitamura2017 unless the text names one)."""

    def make(text: str, **kwargs: Any) -> Layout:
        body = textwrap.dedent(text).lstrip("\n")
        if not body.startswith("desk:"):
            body = "desk: kitamura2017\n" + body
        kwargs.setdefault("action_names", ACTIONS)
        return load_layout(write_layout(body), **kwargs)

    return make
