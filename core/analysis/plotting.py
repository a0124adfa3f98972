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
through its object-oriented API with the Agg canvas, so no global backend is switched.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from hapticdesk.errors import ConfigError
from hapticdesk.estimator import CandidateTrace, ContactEstimator
from hapticdesk.estimator.contacts import (
    SOURCE_DIFF,
    SOURCE_FORCE,
    SOURCE_FUSED,
    SOURCE_NAMES,
    ContactBlock,
)
from hapticdesk.estimator.inertia import accelerometer_readings
from hapticdesk.files.profile import AXES, DeskProfile
from hapticdesk.files.recording import Recording

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

SOURCE_COLOURS = {SOURCE_FORCE: "#1f77b4", SOURCE_DIFF: "#ff7f0e", SOURCE_FUSED: "#2ca02c"}
TRUTH_COLOUR = "#222222"
GAP_S = 0.05  # samples further apart than this are not joined by a line


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

    estimator = ContactEstimator(profile, method=method, trace=bool(profile.surfaces))
    # as `contacts` estimates: with the desk's accelerometer readings, when it has one (the
    # plot had left them out, and counted other points than `contacts --json`)
    accel = accelerometer_readings(profile, recording.extra)
    block = estimator.push(recording.t, recording.wrench, accel)
    trace = CandidateTrace.concat(estimator.traces)
    truth = {k: np.asarray(v, dtype=float) for k, v in recording.extra.items()}
    has_truth = "true_fn" in truth

    fig = Figure(figsize=(13.0, 6.5), dpi=110, layout="constrained")
    FigureCanvasAgg(fig)
    sel = np.flatnonzero(shown)
    if profile.surfaces:
        grid = fig.add_gridspec(2, 2, width_ratios=[1.35, 1.0])
        ax_force = fig.add_subplot(grid[0, 0])
        ax_dist = fig.add_subplot(grid[1, 0], sharex=ax_force)
        ax_desk = fig.add_subplot(grid[:, 1])
        _force_panel(ax_force, t, block.force_n, block.in_contact, truth, sel, profile, estimator)
        _distance_panel(ax_dist, profile, trace, truth, t, t0, t1)
        _desk_panel(ax_desk, profile, block, truth, sel)
    else:
        ax_force = _bench_panels(fig, profile, recording, sel)
    ax_force.set_xlim(t0, t1)
    name = title or f"desk {profile.name}"
    how = f"method {estimator.method}, " if profile.surfaces else ""
    fig.suptitle(f"{name} — {how}{t0:.2f}–{t1:.2f} s")
    try:
        fig.savefig(str(output), format="png")
    except OSError as err:
        raise ConfigError(str(output), f"cannot write: {err.strerror or err}") from None

    located = {
        SOURCE_NAMES[s]: int(np.count_nonzero(block.located[sel] & (block.source[sel] == s)))
        for s in (SOURCE_FORCE, SOURCE_DIFF, SOURCE_FUSED)
    }
    return PlotSummary(
        path=str(output),
        start_s=t0,
        end_s=t1,
        samples=len(sel),
        contact_samples=int(np.count_nonzero(block.in_contact[sel])),
        located_samples=int(np.count_nonzero(block.located[sel])),
        located=located,
        truth=has_truth,
        method=estimator.method,
    )


def _broken(t: np.ndarray, *ys: np.ndarray) -> tuple[np.ndarray, ...]:
    """Insert NaN between samples further apart than GAP_S so lines do not bridge gaps."""
    if len(t) < 2:
        return (t, *ys)
    cut = np.flatnonzero(np.diff(t) > GAP_S) + 1
    return tuple(np.insert(np.asarray(a, dtype=float), cut, np.nan) for a in (t, *ys))


def _force_panel(
    ax: Axes,
    t: np.ndarray,
    force: np.ndarray,
    in_contact: np.ndarray,
    truth: dict[str, np.ndarray],
    sel: np.ndarray,
    profile: DeskProfile,
    estimator: ContactEstimator,
) -> None:
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
    _title_and_legend(ax, "force over time")
    ax.tick_params(labelbottom=False)


def _distance_panel(
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
    _title_and_legend(ax, "D_er and D_ed while in contact (paper Fig. 7)")


def _desk_panel(
    ax: Axes,
    profile: DeskProfile,
    block: ContactBlock,
    truth: dict[str, np.ndarray],
    sel: np.ndarray,
) -> None:
    """The outlines from above with the contact points and the true path (paper Fig. 13)."""
    corners = []
    for surface in profile.surfaces:
        poly = np.vstack([surface.polygon, surface.polygon[:1]])
        xyz = surface.to_desk(poly[:, 0], poly[:, 1])
        corners.append(xyz[:, :2])
        ax.plot(xyz[:, 0], xyz[:, 1], color="#555555", linewidth=1.2)
        centre = xyz[:-1, :2].mean(axis=0)
        ax.annotate(surface.name, centre, color="#999999", fontsize=8, ha="center")
    if "true_x" in truth and "true_y" in truth:
        ax.plot(
            truth["true_x"][sel],
            truth["true_y"][sel],
            color=TRUTH_COLOUR,
            linewidth=1.0,
            label="true path",
        )
    located = sel[block.located[sel]]
    for source in (SOURCE_FORCE, SOURCE_DIFF, SOURCE_FUSED):
        at = located[block.source[located] == source]
        if len(at):
            ax.scatter(
                block.x[at],
                block.y[at],
                s=3,
                color=SOURCE_COLOURS[source],
                label=f"{SOURCE_NAMES[source]} ({len(at):,})",
                rasterized=True,
                linewidths=0,
                # the most numerous on top: the rarer candidates' points lie around them,
                # where they stay visible (the force's 56,431 had been hidden under 15,230)
                zorder=2 + len(at) / max(len(located), 1),
            )
    outline = np.vstack(corners)
    lo, hi = outline.min(axis=0), outline.max(axis=0)
    margin = 0.05 * float((hi - lo).max())
    ax.set_xlim(lo[0] - margin, hi[0] + margin)
    ax.set_ylim(lo[1] - margin, hi[1] + margin)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m), to the right")
    ax.set_ylabel("y (m), away from the user")
    if len(located) == 0:
        ax.annotate(
            "no contact located in this window",
            (0.5, 0.5),
            xycoords="axes fraction",
            ha="center",
            color="#999999",
        )
    else:
        _zoom_inset(ax, block, located, truth, sel, lo, hi)
    ax.set_title("contact points from above (paper Fig. 13)", fontsize=10, loc="left")
    ax.legend(
        loc="upper center",
        bbox_to_anchor=(0.5, -0.1),
        fontsize=8,
        frameon=False,
        ncol=4,
        markerscale=4,
        # the total first: one candidate's count alone had been read as all the points
        title=f"{len(located):,} located points, by the candidate each came from",
        title_fontsize=8,
    )
    ax.grid(True, alpha=0.3)


def _zoom_inset(
    ax: Axes,
    block: ContactBlock,
    located: np.ndarray,
    truth: dict[str, np.ndarray],
    sel: np.ndarray,
    outline_lo: np.ndarray,
    outline_hi: np.ndarray,
) -> None:
    """When the points fill a small part of the outline (one press, one button), repeat
    them magnified in an inset so their scatter can be read."""
    x, y = block.x[located], block.y[located]
    lo = np.array([x.min(), y.min()])
    hi = np.array([x.max(), y.max()])
    if float((hi - lo).max()) > 0.25 * float((outline_hi - outline_lo).max()):
        return
    half = max(0.6 * float((hi - lo).max()), 0.005)  # at least a 1 cm square
    mid = (lo + hi) / 2
    # in the corner of the axes across from the points, so it hides none of them
    right, top = mid > (outline_lo + outline_hi) / 2
    inset = ax.inset_axes((0.03 if right else 0.61, 0.04 if top else 0.56, 0.36, 0.36))
    if "true_x" in truth and "true_y" in truth:
        inset.plot(truth["true_x"][sel], truth["true_y"][sel], color=TRUTH_COLOUR, linewidth=1.0)
    for source in (SOURCE_FORCE, SOURCE_DIFF, SOURCE_FUSED):
        at = located[block.source[located] == source]
        if len(at):
            inset.scatter(
                block.x[at],
                block.y[at],
                s=4,
                color=SOURCE_COLOURS[source],
                rasterized=True,
                linewidths=0,
            )
    inset.set_xlim(mid[0] - half, mid[0] + half)
    inset.set_ylim(mid[1] - half, mid[1] + half)
    inset.set_aspect("equal")
    inset.tick_params(labelsize=7)
    inset.locator_params(nbins=3)
    inset.ticklabel_format(useOffset=False)
    inset.set_title(f"{2 * half * 1e3:.0f} mm square", fontsize=7)
    inset.grid(True, alpha=0.3)
    ax.indicate_inset_zoom(inset, edgecolor="#777777")


def _title_and_legend(ax: Axes, title: str, **legend: Any) -> None:
    """Title on the left and the legend on the right above the axes, off the data."""
    ax.set_title(title, fontsize=10, loc="left")
    options = {"ncol": 3, **legend}
    ax.legend(
        loc="lower right",
        bbox_to_anchor=(1.0, 1.0),
        fontsize=8,
        frameon=False,
        borderaxespad=0.2,
        **options,
    )
    ax.grid(True, alpha=0.3)


def _bench_panels(fig: Figure, profile: DeskProfile, recording: Recording, sel: np.ndarray) -> Axes:
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
    _title_and_legend(ax_f, "forces (no surfaces: no contacts)", ncol=6)
    _title_and_legend(ax_m, "moments", ncol=6)
    return ax_f
