"""The plot's panels over time: the force with the contact shading and thresholds, the
distances D_er and D_ed from the top's centre (paper Fig. 7), and for a sensor on the bench
its force and moment channels. Drawn by :mod:`hapticdesk.analysis.plotting`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from hapticdesk.analysis.plot_style import SOURCE_COLOURS, TRUTH_COLOUR, title_and_legend
from hapticdesk.estimator import CandidateTrace, ContactEstimator
from hapticdesk.estimator.contacts import SOURCE_DIFF, SOURCE_FORCE
from hapticdesk.files.profile import AXES, DeskProfile
from hapticdesk.files.recording import Recording

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

GAP_S = 0.05  # samples further apart than this are not joined by a line


def _broken(t: np.ndarray, *ys: np.ndarray) -> tuple[np.ndarray, ...]:
    """Insert NaN between samples further apart than GAP_S so lines do not bridge gaps."""
    if len(t) < 2:
        return (t, *ys)
    cut = np.flatnonzero(np.diff(t) > GAP_S) + 1
    return tuple(np.insert(np.asarray(a, dtype=float), cut, np.nan) for a in (t, *ys))


def force_panel(
    ax: Axes,
    t: np.ndarray,
    force: np.ndarray,
    in_contact: np.ndarray,
    truth: dict[str, np.ndarray],
    sel: np.ndarray,
    profile: DeskProfile,
    estimator: ContactEstimator,
) -> None:
    """|F| over time with the samples in contact shaded and the thresholds drawn."""
    s = estimator.settings
    ts = t[sel]
    ax.fill_between(
        ts,
        0,
        1,
        where=in_contact[sel],
        transform=ax.get_xaxis_transform(),
        color="#dddddd",
        linewidth=0,
        label="in contact",
    )
    ax.plot(ts, force[sel], color="#1f77b4", linewidth=0.9, label="|F| (estimated)")
    if "true_fn" in truth:
        ax.plot(
            ts,
            truth["true_fn"][sel],
            color=TRUTH_COLOUR,
            linewidth=0.8,
            linestyle="--",
            label="true normal force",
        )
    ax.axhline(s.contact_force_n, color="#888888", linewidth=0.7, linestyle=":")
    if estimator.method == "switched":
        for value, label in ((s.touch_threshold_n, "F_tth"), (s.release_threshold_n, "F_rth")):
            ax.axhline(value, color="#aa3333", linewidth=0.7, linestyle=":")
            ax.annotate(
                f" {label}",
                (0.0, value),
                xycoords=("axes fraction", "data"),
                fontsize=8,
                color="#aa3333",
                ha="left",
                va="bottom",
                bbox={"facecolor": "white", "edgecolor": "none", "alpha": 0.7, "pad": 0.5},
            )
    ax.set_ylabel("force (N)")
    title_and_legend(ax, "force over time")
    ax.tick_params(labelbottom=False)


def distance_panel(
    ax: Axes,
    profile: DeskProfile,
    trace: CandidateTrace,
    truth: dict[str, np.ndarray],
    t: np.ndarray,
    t0: float,
    t1: float,
) -> None:
    """D_er and D_ed: distance from the first surface's origin (paper Fig. 7)."""
    centre = profile.surfaces[0].origin
    keep = (trace.t >= t0) & (trace.t <= t1)
    tt = trace.t[keep]
    # D_ed first: it is the noisier one and would hide D_er
    for points, valid, label, colour in (
        (trace.diff_point, trace.diff_valid, "D_ed (differentiated)", SOURCE_COLOURS[SOURCE_DIFF]),
        (trace.force_point, trace.force_valid, "D_er (force)", SOURCE_COLOURS[SOURCE_FORCE]),
    ):
        d = np.linalg.norm(points[:, keep] - centre[:, None], axis=0)
        d = np.where(valid[keep], d, np.nan)
        ax.plot(*_broken(tt, d), color=colour, linewidth=0.9, label=label)
    if "true_x" in truth and "true_y" in truth:
        shown = (t >= t0) & (t <= t1)
        true_z = truth.get("true_z", np.full(len(t), centre[2]))
        rel = np.stack([truth["true_x"], truth["true_y"], true_z])[:, shown] - centre[:, None]
        ax.plot(
            t[shown],
            np.linalg.norm(rel, axis=0),
            color=TRUTH_COLOUR,
            linewidth=0.8,
            linestyle="--",
            label="true",
        )
    surface = profile.surfaces[0]
    corners = surface.to_desk(surface.polygon[:, 0], surface.polygon[:, 1])
    ax.set_ylim(0.0, 1.05 * float(np.linalg.norm(corners - centre, axis=1).max()))
    ax.set_ylabel(f"distance from the {surface.name} centre (m)")
    ax.set_xlabel("time (s)")
    title_and_legend(ax, "D_er and D_ed while in contact (paper Fig. 7)")


def bench_panels(fig: Figure, profile: DeskProfile, recording: Recording, sel: np.ndarray) -> Axes:
    """A sensor on the bench: its force and moment channels over time, each less its mean
    over the first ``tare_s`` so noise and drift show rather than the weight it carries."""
    t = recording.t[sel]
    n_tare = max(1, int(np.searchsorted(recording.t, recording.t[0] + profile.estimation.tare_s)))
    zero = np.nanmean(recording.wrench[:n_tare], axis=0)  # (S, 6)
    ax_f = fig.add_subplot(2, 1, 1)
    ax_m = fig.add_subplot(2, 1, 2, sharex=ax_f)
    for ax, axes, unit in ((ax_f, range(3), "N"), (ax_m, range(3, 6), "N·m")):
        for i, sensor in enumerate(profile.sensors):
            for a in axes:
                ax.plot(
                    t,
                    recording.wrench[sel, i, a] - zero[i, a],
                    linewidth=0.6,
                    label=f"{sensor.name}_{AXES[a]}",
                )
        ax.set_ylabel(f"change since the start ({unit})")
    ax_m.set_xlabel("time (s)")
    ax_f.tick_params(labelbottom=False)
    title_and_legend(ax_f, "forces (no surfaces: no contacts)", ncol=6)
    title_and_legend(ax_m, "moments", ncol=6)
    return ax_f
