"""Stroke shapes: a touch long enough to be drawing is classified at its release.

The path is the touch's located samples without their first and last ``END_TRIM_S`` (where
the finger lands and lifts), smoothed in time with a zero-phase Gaussian: a finger dragged
across the desk makes it sway at its natural frequency (5.9 Hz for the paper's desk), and
the position error that follows (1-8 Hz, a few centimetres at human speed) is larger than
the features of a drawn shape. The Gaussian's σ is ``SWAY_CYCLES / f_n`` (0.2 s at 5.9 Hz):
it leaves a shape's outline and takes most of the loops; both constants were chosen with
scripts/stroke_accuracy.py (``--human-speed``: real strokes at their real speed on the
simulated desk). Recognition is over the built-in and the layout's templates (unistroke.py;
``builtin_templates: false`` in a layout leaves only its own). A stroke that matches nothing
well enough is still reported, with ``shape`` null and its best score, so an events log
shows near misses; bindings never fire on it.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from hapticdesk.estimator.contacts import ContactEvent
from hapticdesk.estimator.sway import compensates
from hapticdesk.files.profile import DeskProfile
from hapticdesk.gestures.event import GestureEvent
from hapticdesk.gestures.layout import Binding, Layout
from hapticdesk.gestures.recognizer import BoundRegions, Recognizer
from hapticdesk.gestures.strokes.unistroke import template_set
from hapticdesk.gestures.touch import Touch

#: the smoothing's σ in periods of the desk's natural frequency (0.2 s at 5.9 Hz). Chosen on
#: the $1 logs traced at their real speed (0.1-0.3 m/s) on the simulated desk, 3 own
#: templates right: 0.47 periods 65 %, 1.0 89 %, 1.2 91 %; built-in 40 %, 68 %, 67 %
SWAY_CYCLES = 1.2
#: natural frequency assumed when the profile does not give one (the paper's desk)
DEFAULT_NATURAL_FREQUENCY_HZ = 5.9
#: the smoothing's σ, in periods of f_n, for a path that does not sway (a clean trace)
CALM_CYCLES = 0.47
#: a path is swaying when what the calm σ takes from a light one (``_WOBBLE_SIGMA_S``) has
#: this RMS or more: 12-30 mm for the $1 logs traced on the simulated desk, ≤ 1.3 mm for a
#: clean trace with 0.5 mm noise
SWAY_RMS_M = 0.005
#: the least of that wobble on the paper's desk (the $1 logs traced at their real speed), and
#: its lever (:func:`sway_lever_m`: its profile gives no centre of mass, so its top's height
#: above the sensors): the sway's offset of the located point grows with the lever
PAPER_SWAY_RMS_M = 0.012
PAPER_SWAY_LEVER_M = 0.733
_WOBBLE_SIGMA_S = 0.015
#: the smoothing's σ is at most the stroke's duration divided by this
MAX_SIGMA_SHARE_INV = 4.0
#: the ends of a stroke left out, seconds
END_TRIM_S = 0.05
_GRID_S = 0.005  # strokes are resampled to this time step before smoothing


def smoothing_s(desk: DeskProfile) -> float:
    """σ in seconds of the Gaussian that smooths a swaying stroke on ``desk``; on a desk whose
    sway the estimator takes out (:func:`sway_compensated`) or whose located path barely
    sways (:func:`sway_reaches_path` false: sensors just under the top), the calm σ.

    Why not judge each path by its wobble there too: a fast stroke's corners move tens of
    millimetres within the calm σ, so a clean fast stroke looks like a swaying one and got the
    heavy σ, which rounded the corners the built-in shapes are told apart by (the $1 logs at
    their real speed, legs as the accelerometer: built-in templates 78.2 → 87.4 % right,
    3 own 93.5 → 92.1 %)."""
    if sway_compensated(desk) or not sway_reaches_path(desk):
        return calm_smoothing_s(desk)
    return SWAY_CYCLES / (desk.natural_frequency_hz or DEFAULT_NATURAL_FREQUENCY_HZ)


def sway_compensated(desk: DeskProfile) -> bool:
    """The estimator removes the desk's inertial force on ``desk``'s located path: it has an
    accelerometer, or the legs as one (:func:`compensates`: ``estimation.sway_compensation``,
    on for ``fused`` unless set, with a known sway frequency)."""
    return desk.accelerometer is not None or compensates(desk)


def sway_lever_m(desk: DeskProfile) -> float | None:
    """Height of the swaying mass above the sensors, metres: the profile's centre of mass
    (``desk.center_of_mass_m``) above the sensors' mean height, else its first surface's (the
    mass is under the top, so this bounds it); None when the profile gives neither."""
    if not desk.sensors:
        return None
    base = float(np.mean([s.position[2] for s in desk.sensors]))
    if desk.center_of_mass_m is not None:
        return abs(float(desk.center_of_mass_m[2]) - base)
    if desk.surfaces:
        return abs(float(desk.surfaces[0].origin[2]) - base)
    return None


def sway_reaches_path(desk: DeskProfile) -> bool:
    """Whether the desk's sway moves the located path enough to need the heavy smoothing.

    The sway's inertial force m·a acts at the desk's centre of mass; at the sensors it is a
    moment m·a·h about them (h: :func:`sway_lever_m`), which the located point takes as
    h·m·a/F of offset. On the paper's desk (sensors under 0.73 m legs, h = PAPER_SWAY_LEVER_M)
    what the calm σ leaves of it is PAPER_SWAY_RMS_M or more on every $1 stroke traced at
    real speed; scaled by h, a desk whose expected wobble stays under ``SWAY_RMS_M`` (the
    level at which a path counts as swaying) keeps the calm σ: load cells just under the top
    (h 17-22 mm: under 1 mm) or any desk whose mass sits on its sensors. Without a lever in
    the profile, the paper's desk is assumed. A stiff desk (high ``natural_frequency_hz``)
    gets short σs either way: both are in periods of f_n."""
    lever = sway_lever_m(desk)
    if lever is None:
        return True
    return PAPER_SWAY_RMS_M * lever / PAPER_SWAY_LEVER_M >= SWAY_RMS_M


def calm_smoothing_s(desk: DeskProfile) -> float:
    """σ in seconds for a stroke whose path does not sway."""
    return CALM_CYCLES / (desk.natural_frequency_hz or DEFAULT_NATURAL_FREQUENCY_HZ)


def stroke_path(
    times: np.ndarray, points: np.ndarray, sigma_s: float, calm_sigma_s: float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """(t, points) of a stroke: ends trimmed, smoothed with a Gaussian of σ ``sigma_s`` and
    given every 5 ms (see the module docstring). With ``calm_sigma_s``, a path whose wobble
    (what a σ of ``calm_sigma_s`` takes away from one of ``_WOBBLE_SIGMA_S``) stays under
    ``SWAY_RMS_M`` is smoothed with ``calm_sigma_s`` instead.

    The samples are binned on the 5 ms grid and the Gaussian is a normalised convolution
    (sum of weighted points / sum of weights): the path's ends are averages of the samples
    that exist, not of copies of the last sample, which pulled each end into a hook on a
    finger still moving when it lifts (measured: 3 own templates 52 % → 65 % right on the
    $1 logs traced at their real speed, σ 0.08 s)."""
    if len(times) < 2:
        return times, points
    if times[-1] - times[0] > 4 * END_TRIM_S:
        keep = (times >= times[0] + END_TRIM_S) & (times <= times[-1] - END_TRIM_S)
        times, points = times[keep], points[keep]
    grid = np.arange(times[0], times[-1] + _GRID_S / 2, _GRID_S)
    slot = np.clip(np.rint((times - times[0]) / _GRID_S).astype(int), 0, len(grid) - 1)
    binned = np.column_stack(
        [np.bincount(slot, minlength=len(grid)).astype(float)]
        + [np.bincount(slot, points[:, k], minlength=len(grid)) for k in (0, 1)]
    )
    # never longer than a part of the stroke itself: a quick straight stroke would shrink
    longest = (times[-1] - times[0]) / MAX_SIGMA_SHARE_INV
    sigma = min(sigma_s, longest)
    if calm_sigma_s is not None:
        calm = _smoothed(binned, min(calm_sigma_s, longest))
        wobble = _smoothed(binned, _WOBBLE_SIGMA_S)[1] - calm[1]
        if float(np.sqrt(np.mean(np.sum(wobble**2, axis=1)))) < SWAY_RMS_M:
            return grid[calm[0]], calm[1][calm[0]]
    keep, xy = _smoothed(binned, sigma)
    return grid[keep], xy[keep]


def _smoothed(binned: np.ndarray, sigma_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Normalised Gaussian convolution of binned (count, Σx, Σy) (n, 3): (grid steps that
    some sample reaches (n,) bool, points (n, 2))."""
    from scipy.ndimage import gaussian_filter1d

    smooth = gaussian_filter1d(binned, max(sigma_s / _GRID_S, 1e-3), axis=0, mode="constant")
    weight = smooth[:, 0]
    keep = weight > 1e-9 * float(weight.max())
    return keep, smooth[:, 1:] / np.where(keep, weight, 1.0)[:, None]


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
        self.templates = template_set(layout.templates, builtin=layout.builtin_templates)
        self.sliders = BoundRegions(layout, "slide")
        self.smoothing_s = smoothing_s(layout.desk)
        self.calm_smoothing_s = calm_smoothing_s(layout.desk)

    def on_contact(self, event: ContactEvent, touch: Touch) -> list[GestureEvent]:
        if event.kind != "up" or touch.samples < 2:
            return []
        _, path = stroke_path(
            touch.times(), touch.points(), self.smoothing_s, self.calm_smoothing_s
        )
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
