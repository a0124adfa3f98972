"""Capturing strokes from contact blocks, for ``hapticdesk strokes record``.

Every touch that is big enough to be a stroke becomes one, smoothed exactly as the stroke
recognizer smooths what it classifies, so a recorded template compares like with like.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hapticdesk.estimator.contacts import ContactBlock, ContactEvent
from hapticdesk.files.profile import DeskProfile
from hapticdesk.gestures.recognizers.stroke import (
    calm_smoothing_s,
    extent,
    smoothing_s,
    stroke_path,
)
from hapticdesk.gestures.touch import Touch
from hapticdesk.gestures.touch_tracker import TouchTracker

_KEEP_EVERY = 4  # of the smoothed path's 5 ms steps


@dataclass(frozen=True)
class CapturedStroke:
    """One stroke: sample times (n,) and points (n, 2) in metres on its surface."""

    t: np.ndarray
    points: np.ndarray
    surface: int

    @property
    def size(self) -> float:
        """Diagonal of its bounding box, metres."""
        return extent(self.points)


class StrokeCapture:
    """Feed contact blocks; get the strokes that ended in them."""

    def __init__(self, desk: DeskProfile, min_size: float = 0.04) -> None:
        self.min_size = min_size
        self.small = 0  # touches too small to be strokes (taps, presses)
        self._tracker = TouchTracker(desk)
        self._smoothing_s = smoothing_s(desk)
        self._calm_smoothing_s = calm_smoothing_s(desk)

    def feed(self, block: ContactBlock) -> list[CapturedStroke]:
        out: list[CapturedStroke] = []
        for event in self._tracker.events(block):
            out += self._take(event)
        return out

    def flush(self, t_end: float) -> list[CapturedStroke]:
        """The source ended at ``t_end``: a touch still going ends here."""
        up = self._tracker.end(t_end)
        return self._take(up) if up is not None else []

    def _take(self, event: ContactEvent) -> list[CapturedStroke]:
        touch = self._tracker.add(event)
        if event.kind != "up" or touch is None:
            return []
        stroke = self._stroke(touch)
        if stroke is None:
            self.small += 1
            return []
        return [stroke]

    def _stroke(self, touch: Touch) -> CapturedStroke | None:
        if touch.samples < 2:
            return None
        t, points = stroke_path(
            touch.times(), touch.points(), self._smoothing_s, self._calm_smoothing_s
        )
        if extent(points) < self.min_size:
            return None
        # every 20 ms is plenty after smoothing over 80 ms or more, and keeps template files small
        keep = np.unique(np.append(np.arange(0, len(t), _KEEP_EVERY), len(t) - 1))
        return CapturedStroke(t[keep], points[keep], touch.surface)
