"""A recording and its contacts as a PNG, like the paper's Fig. 7 and Fig. 13.

Left, over time: the force (|F| of the estimator's detection path, and the true normal force
when the recording has ``true_fn``) with the samples in contact shaded and the contact and
switching thresholds drawn; below it the distance from the top board's centre to P_er (from
the force) and P_ed (from the differentiated force), the paper's D_er and D_ed (Fig. 7), with
the true distance when the recording has the truth. Right: the desk's outline seen from
above with the reported contact points coloured by the candidate used (force, diff, fused)
and the true path as a line (Fig. 13). A profile without surfaces (a sensor on the bench)
gets the force components over time only.

The estimator always runs over the whole recording (it tares over the first second); the
time window only chooses what is drawn. matplotlib is imported inside :func:`plot_recording`
through its object-oriented API with the Agg canvas, so no global backend is switched. The
panels are drawn by :mod:`~hapticdesk.analysis.plot_over_time` and
:mod:`~hapticdesk.analysis.plot_from_above`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from hapticdesk.analysis.plot_from_above import desk_panel
from hapticdesk.analysis.plot_over_time import bench_panels, distance_panel, force_panel
from hapticdesk.analysis.plot_style import SOURCES_DRAWN
from hapticdesk.errors import ConfigError
from hapticdesk.estimator import CandidateTrace, ContactEstimator
from hapticdesk.estimator.contacts import SOURCE_NAMES, ContactBlock
from hapticdesk.estimator.inertia import accelerometer_readings
from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.recording import Recording

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure


@dataclass(frozen=True)
class PlotSummary:
    """What was drawn."""

    path: str
    start_s: float
    end_s: float
    samples: int
    contact_samples: int
    #: the samples located, as ``contacts --json`` counts them (over the window drawn)
    located_samples: int
    located: dict[str, int]  # per source name; they add up to located_samples
    truth: bool
    method: str


def plot_recording(
    profile: DeskProfile,
    recording: Recording,
    output: str | Path,
    *,
    method: str | None = None,
    start_s: float | None = None,
    end_s: float | None = None,
    title: str | None = None,
) -> PlotSummary:
    """Estimate contacts over ``recording`` and write the PNG ``output`` (module doc).

    Raises :class:`ConfigError` for an empty time window, a missing matplotlib or an output
    that cannot be written.
    """
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError:
        raise ConfigError(
            "plot", "matplotlib is needed for plots: pip install 'hapticdesk[plot]'"
        ) from None
    t = np.asarray(recording.t, dtype=float)
    window = _time_window(t, start_s, end_s)
    t0, t1 = window.start_s, window.end_s

    estimator = ContactEstimator(profile, method=method, trace=bool(profile.surfaces))
    # as `contacts` estimates: with the desk's accelerometer readings, when it has one (the
    # plot had left them out, and counted other points than `contacts --json`)
    accel = accelerometer_readings(profile, recording.extra)
    block = estimator.push(recording.t, recording.wrench, accel)
    truth = {k: np.asarray(v, dtype=float) for k, v in recording.extra.items()}

    fig = Figure(figsize=(13.0, 6.5), dpi=110, layout="constrained")
    FigureCanvasAgg(fig)
    sel = np.flatnonzero(window.shown)
    if profile.surfaces:
        ax_force = _desk_panels(fig, profile, estimator, block, truth, t, window)
    else:
        ax_force = bench_panels(fig, profile, recording, sel)
    ax_force.set_xlim(t0, t1)
    name = title or f"desk {profile.name}"
    how = f"method {estimator.method}, " if profile.surfaces else ""
    fig.suptitle(f"{name} — {how}{t0:.2f}–{t1:.2f} s")
    try:
        fig.savefig(str(output), format="png")
    except OSError as err:
        raise ConfigError(str(output), f"cannot write: {err.strerror or err}") from None

    return PlotSummary(
        path=str(output),
        start_s=t0,
        end_s=t1,
        samples=len(sel),
        contact_samples=int(np.count_nonzero(block.in_contact[sel])),
        located_samples=int(np.count_nonzero(block.located[sel])),
        located=_located_by_source(block, sel),
        truth="true_fn" in truth,
        method=estimator.method,
    )


class _TimeWindow(NamedTuple):
    """The window drawn: its start and end, and which samples fall in it (bool (n,))."""

    start_s: float
    end_s: float
    shown: np.ndarray


def _time_window(t: np.ndarray, start_s: float | None, end_s: float | None) -> _TimeWindow:
    """The window drawn: its start and end (the recording's by default) and which samples
    fall in it; :class:`ConfigError` for an empty recording or window."""
    if len(t) == 0:
        raise ConfigError("recording", "the recording has no samples")
    finite_t = t[np.isfinite(t)]
    t0 = float(finite_t.min()) if start_s is None else float(start_s)
    t1 = float(finite_t.max()) if end_s is None else float(end_s)
    shown = np.isfinite(t) & (t >= t0) & (t <= t1)
    if not t1 > t0 or not shown.any():
        raise ConfigError(
            "--start/--end",
            f"the window {t0:g}–{t1:g} s holds no samples; the recording runs "
            f"{finite_t.min():g}–{finite_t.max():g} s",
        )
    return _TimeWindow(t0, t1, shown)


def _desk_panels(
    fig: Figure,
    profile: DeskProfile,
    estimator: ContactEstimator,
    block: ContactBlock,
    truth: dict[str, np.ndarray],
    t: np.ndarray,
    window: _TimeWindow,
) -> Axes:
    """Force and distance over time on the left, the desk from above on the right; returns
    the force's axes (the time axis the others share)."""
    sel = np.flatnonzero(window.shown)
    trace = CandidateTrace.concat(estimator.traces)
    grid = fig.add_gridspec(2, 2, width_ratios=[1.35, 1.0])
    ax_force = fig.add_subplot(grid[0, 0])
    ax_dist = fig.add_subplot(grid[1, 0], sharex=ax_force)
    ax_desk = fig.add_subplot(grid[:, 1])
    force_panel(ax_force, t, block.force_n, block.in_contact, truth, sel, profile, estimator)
    distance_panel(ax_dist, profile, trace, truth, t, window.start_s, window.end_s)
    desk_panel(ax_desk, profile, block, truth, sel)
    return ax_force


def _located_by_source(block: ContactBlock, sel: np.ndarray) -> dict[str, int]:
    """The located samples among ``sel``, counted per candidate name."""
    return {
        SOURCE_NAMES[s]: int(np.count_nonzero(block.located[sel] & (block.source[sel] == s)))
        for s in SOURCES_DRAWN
    }
