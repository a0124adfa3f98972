"""Stroke shapes: a touch long enough to be drawing is classified at its release.

The path is the touch's located samples without their first and last ``END_TRIM_S`` (where
the finger lands and lifts), smoothed in time with a zero-phase Gaussian: a finger dragged
across the desk makes it sway at its natural frequency (5.9 Hz for the paper's desk), and
that wobble, a centimetre or more, is faster than the features of a drawn shape. The
Gaussian's σ is ``SWAY_CYCLES / f_n`` (0.08 s at 5.9 Hz), which leaves about 1 % of the sway
and most of a shape drawn at a few cm/s. Recognition is Protractor over the built-in and the
layout's templates (unistroke.py). Both constants were chosen with scripts/stroke_accuracy.py
on strokes traced on the simulated desk. A stroke that matches nothing well
enough is still reported, with ``shape`` null and its best score, so an events log shows
near misses; bindings never fire on it.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from hapticdesk.estimator.contacts import ContactEvent
from hapticdesk.files.profile import DeskProfile
from hapticdesk.gestures.event import GestureEvent
from hapticdesk.gestures.layout import Binding, Layout
from hapticdesk.gestures.recognizer import BoundRegions, Recognizer
from hapticdesk.gestures.strokes.unistroke import template_set
from hapticdesk.gestures.touch import Touch

#: the smoothing's σ in periods of the desk's natural frequency
SWAY_CYCLES = 0.47
#: natural frequency assumed when the profile does not give one (the paper's desk)
DEFAULT_NATURAL_FREQUENCY_HZ = 5.9
#: the ends of a stroke left out, seconds
END_TRIM_S = 0.05
_GRID_S = 0.005  # strokes are resampled to this time step before smoothing


def smoothing_s(desk: DeskProfile) -> float:
    """σ in seconds of the Gaussian that smooths strokes on ``desk``."""
    return SWAY_CYCLES / (desk.natural_frequency_hz or DEFAULT_NATURAL_FREQUENCY_HZ)


def stroke_path(
    times: np.ndarray, points: np.ndarray, sigma_s: float
) -> tuple[np.ndarray, np.ndarray]:
    """(t, points) of a stroke: ends trimmed, resampled every 5 ms, smoothed with σ
    ``sigma_s`` (see the module docstring)."""
    from scipy.ndimage import gaussian_filter1d

    if len(times) < 2:
        return times, points
    if times[-1] - times[0] > 4 * END_TRIM_S:
        keep = (times >= times[0] + END_TRIM_S) & (times <= times[-1] - END_TRIM_S)
        times, points = times[keep], points[keep]
    grid = np.arange(times[0], times[-1] + _GRID_S / 2, _GRID_S)
    xy = np.column_stack(
        [np.interp(grid, times, points[:, 0]), np.interp(grid, times, points[:, 1])]
    )
    return grid, gaussian_filter1d(xy, sigma_s / _GRID_S, axis=0, mode="nearest")


def extent(points: np.ndarray) -> float:
    """Diagonal of the bounding box of a path (n, 2): unlike the path length, it does not grow
    with the jitter of a finger that stays put."""
    return float(np.hypot(*np.ptp(points, axis=0))) if len(points) else 0.0


class StrokeRecognizer(Recognizer):
    """``stroke``."""

    gestures = ("stroke",)

    def __init__(self, layout: Layout, bindings: Sequence[Binding]) -> None:
        super().__init__(layout, bindings)
        self.bound = BoundRegions(layout, "stroke")
        self.templates = template_set(layout.templates)
        self.sliders = BoundRegions(layout, "slide")
        self.smoothing_s = smoothing_s(layout.desk)

    def on_contact(self, event: ContactEvent, touch: Touch) -> list[GestureEvent]:
        if event.kind != "up" or touch.samples < 2:
            return []
        _, path = stroke_path(touch.times(), touch.points(), self.smoothing_s)
        found, region = self.bound.find(float(path[0, 0]), float(path[0, 1]), touch.surface)
        if not found or (region is None and self.sliders.find(*path[0], touch.surface)[0]):
            return []  # a drag that starts on a slider is the slider's, not a stroke anywhere
        o = self.bound.options(region)
        if touch.duration() > o["max_duration_s"] or extent(path) < o["min_size"]:
            return []
        match = self.templates.classify(path, o["min_score"], o["max_rotation_deg"])
        return [
            GestureEvent(
                event.t, "stroke", region, float(path[0, 0]), float(path[0, 1]),
                shape=match.shape, score=round(match.score, 4),
                extra={} if match.shape else {"nearest": match.best_shape},
            )
        ]  # fmt: skip
