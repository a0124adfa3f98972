"""The page's set-up check: record the raw samples of a guided session, then check them.

The page asks for a quiet desk (the tare) and then presses at marked points, in order; the
samples come from the running service through ``Runtime.block_taps`` (a reference per block
kept in a bounded deque on the sensing thread, nothing copied there).
"""

from __future__ import annotations

import collections
from typing import Any

from hapticdesk.errors import ConfigError

#: the longest session kept (seconds of samples); older blocks are dropped
MAX_SESSION_S = 180.0
#: the most points a session may mark (a desk's check needs a few more than its sensors)
MAX_POINTS = 64


def read_points(payload: dict[str, Any], profile: Any) -> list[list[float]]:
    """The points of a ``POST /api/setup/start`` body: ``{"points": [[x, y], ...]}`` in
    metres on the desk's top, at least one per sensor, at most :data:`MAX_POINTS`, each
    within the top's outline grown by a metre. ConfigError says which and what was expected
    (any JSON had been taken, and ``finish`` then failed with a traceback in the log)."""
    import math

    points = payload.get("points")
    sensors = len(profile.sensors)
    expected = f"`points`: a list of {sensors} to {MAX_POINTS} points [x, y] in metres"
    if not isinstance(points, list):
        raise ConfigError(None, f"{expected}, found {type(points).__name__}")
    if not sensors <= len(points) <= MAX_POINTS:
        raise ConfigError(
            None,
            f"{expected}, found {len(points)} (mark at least as many points as the desk has "
            "sensors)",
        )
    extent = 1.0
    if profile.surfaces:
        polygon = profile.surfaces[0].polygon
        extent += max(abs(float(v)) for row in polygon for v in row)
    out = []
    for i, point in enumerate(points):
        ok = (
            isinstance(point, list)
            and len(point) == 2
            and all(isinstance(v, int | float) and not isinstance(v, bool) for v in point)
            and all(math.isfinite(v) and abs(v) <= extent for v in point)
        )
        if not ok:
            shown = repr(point) if len(repr(point)) <= 60 else repr(point)[:60] + "…"
            raise ConfigError(
                None,
                f"`points` item {i + 1}: expected [x, y] in metres on the desk (within "
                f"{extent:g} m of its centre), found {shown}",
            )
        out.append([float(point[0]), float(point[1])])
    return out


class BlockRecorder:
    """The raw blocks a running desk senses from now on (the last :data:`MAX_SESSION_S`
    seconds of them), for a guided session of the page's set-up."""

    def __init__(self, runtime: Any) -> None:
        self.runtime = runtime
        rate = runtime.scene.profile.sample_rate_hz
        self.blocks: collections.deque[tuple[Any, Any]] = collections.deque(
            maxlen=max(100, int(MAX_SESSION_S * rate / 8))
        )
        runtime.block_taps = (*runtime.block_taps, self._take)

    def _take(self, t: Any, wrench: Any) -> None:  # on the sensing thread: O(1)
        self.blocks.append((t, wrench))

    def finish_quietly(self) -> None:
        """Stop recording without checking (a new session replaces this one)."""
        runtime = self.runtime
        runtime.block_taps = tuple(tap for tap in runtime.block_taps if tap != self._take)

    def samples(self) -> tuple[Any, Any]:
        """Stop recording; the sample times (k,) and raw readings of what was sensed
        (ConfigError when nothing was)."""
        import numpy as np

        self.finish_quietly()
        blocks = list(self.blocks)
        if not blocks:
            raise ConfigError(None, "nothing was sensed since the set-up started")
        return np.concatenate([b[0] for b in blocks]), np.concatenate([b[1] for b in blocks])


class SetupSession(BlockRecorder):
    """One guided session: marked points, and the blocks sensed since it started."""

    def __init__(self, runtime: Any, points: list[list[float]]) -> None:
        super().__init__(runtime)
        self.points = points

    def finish(self) -> dict[str, Any]:
        """Stop recording and check: findings, residuals, the corrected profile, and what
        ``characterize`` says of the desk's noise and natural frequency."""
        import numpy as np

        from hapticdesk.analysis.characterize import characterize
        from hapticdesk.analysis.setup_check import check_setup, report_dict
        from hapticdesk.files.recording import Recording

        t, wrench = self.samples()
        runtime = self.runtime
        profile = runtime.scene.profile
        report = check_setup(profile, t, wrench, np.asarray(self.points, dtype=float))
        out = report_dict(report)
        desk = characterize(profile, Recording(t, wrench, list(profile.sensor_names)))
        noise = [n for n in desk.total_noise if n.channel == "total_fz"]
        out["captured_s"] = round(float(t[-1] - t[0]), 2)
        out["noise_fz_n"] = round(noise[0].sigma, 4) if noise else None
        out["noise_reason"] = desk.noise_reason
        out["natural_frequency_hz"] = (
            None if desk.lowest_mode_hz is None else round(desk.lowest_mode_hz, 2)
        )
        out["frequency_reason"] = desk.modes_reason
        out["ok"] = True
        return out
