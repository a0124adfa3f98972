"""The paper's Figs. 2, 8, 14 and 16 as PNGs, drawn from what ``bench --paper`` measured
(:mod:`hapticdesk.bench.paper`); matplotlib is imported only here, with the Agg canvas.

Each figure has the paper's panels, a title that names the figure, and a layout fixed before
anything is written (``layout="constrained"``; the traces' equal aspect adjusts the data
limits, not the axes box, which had pushed the title into the suptitle and the x label off
the image).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from hapticdesk.estimator import error_model
from hapticdesk.estimator.contacts import SOURCE_DIFF, SOURCE_FORCE, SOURCE_FUSED, ContactBlock
from hapticdesk.files.recording import Recording

if TYPE_CHECKING:
    from matplotlib.figure import Figure

FORCE_COLOUR, DIFF_COLOUR = "tab:blue", "tab:orange"
CONVENTIONAL_COLOUR, PROPOSED_COLOUR = "#7f7f7f", "tab:green"
#: a traced point further than this from the true point is counted off the character
OFF_CHARACTER_M = 0.05


def _figure(width: float, height: float) -> Figure:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), dpi=110, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _save(fig: Figure, path: Path) -> None:
    fig.savefig(str(path), format="png")


def draw_figure2(path: Path, bands: list[dict[str, Any]]) -> None:
    """(a) The error range of the computed point against the force, for the force with the
    raw and the low-passed noise and for the differentiated force (the paper's Fig. 2, computed
    through our geometry: :mod:`hapticdesk.estimator.error_model`); (b) on the simulator,
    the p95 of |D error| of D_er and D_ed at release, by force band (``bands``)."""
    fig = _figure(12.0, 4.8)
    ax, sim = fig.subplots(1, 2)
    _error_model_panel(ax)
    _release_bands_panel(sim, bands)
    fig.suptitle("Fig. 2: error of the computed contact point, force against differentiated force")
    _save(fig, path)


def _error_model_panel(ax: Any) -> None:
    """Fig. 2 (a): the error ranges of the force's and the differentiated force's points."""
    forces = np.geomspace(1.0, 20.0, 200)
    curves = error_model.figure2_curves(forces)
    raw = np.array(
        [
            error_model.error_range(error_model.PAPER_X_M, f, error_model.PAPER_RAW_NOISE_N)
            for f in forces
        ]
    )
    crossing = error_model.crossover_force()
    ax.plot(forces, raw * 1e3, color=FORCE_COLOUR, ls="--", label="force, raw noise ±0.4 N")
    ax.plot(
        forces,
        curves["force_range_m"] * 1e3,
        color=FORCE_COLOUR,
        label="force, low-passed noise ±0.024 N",
    )
    ax.plot(
        forces,
        curves["diff_range_m"] * 1e3,
        color=DIFF_COLOUR,
        label="differentiated force, 45 ± 0.29 N/s",
    )
    ax.axvline(crossing, color="black", lw=0.8, ls=":")
    ax.annotate(
        f"ranges cross at {crossing:.2f} N",
        (crossing, float(curves["diff_range_m"][0]) * 1e3),
        xytext=(8, 25),
        textcoords="offset points",
        fontsize=8,
        arrowprops={"arrowstyle": "-", "lw": 0.6},
    )
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("|F_z| (N)")
    ax.set_ylabel("error range of the computed x (mm)")
    ax.set_title("(a) the error model, x = 0.2 m, h = 0.733 m", fontsize=10, loc="left")
    ax.legend(fontsize=8, loc="upper right")
    ax.grid(alpha=0.3, which="both")
    _plain_log_ticks(ax)


def _release_bands_panel(sim: Any, bands: list[dict[str, Any]]) -> None:
    """Fig. 2 (b): the p95 of |D error| of D_er and D_ed at release, by force band."""
    shown = [b for b in bands if b["samples"] > 0]
    edges = [f"{b['from_n']:g}–{b['to_n']:g}\nn = {b['samples']:,}" for b in shown]
    width = 0.38
    x = np.arange(len(shown))
    for offset, key, colour, name in (
        (-width / 2, "p95_er_mm", FORCE_COLOUR, "D_er (force)"),
        (width / 2, "p95_ed_mm", DIFF_COLOUR, "D_ed (differentiated)"),
    ):
        values = [b[key] for b in shown]
        sim.bar(x + offset, values, width, color=colour, label=name)
    sim.set_xticks(x, edges)
    sim.set_yscale("log")
    sim.set_xlabel("|F| while the finger lifts (N)")
    sim.set_ylabel("p95 of |D error| (mm)")
    sim.set_title("(b) simulated releases, the paper's noise", fontsize=10, loc="left")
    sim.legend(fontsize=8, loc="upper right")
    sim.grid(alpha=0.3, which="both", axis="y")
    _plain_log_ticks(sim, x_too=False)
    sim.tick_params(axis="x", labelsize=8)
    sim.set_ylim(bottom=1.0)


def draw_figure8(path: Path, numbers: dict[str, Any]) -> None:
    """The std of the errors of D_er and D_ed at 2–3 N, (a) touching, (b) releasing (the
    paper's Fig. 8)."""
    fig = _figure(9.0, 4.2)
    axes = fig.subplots(1, 2, sharey=True)
    panels = (("touch", "(a) force increasing (touch)"), ("release", "(b) decreasing (release)"))
    for ax, (phase, title) in zip(axes, panels, strict=True):
        values = [numbers.get(f"{phase}_std_er_mm"), numbers.get(f"{phase}_std_ed_mm")]
        heights = [np.nan if v is None else v for v in values]
        bars = ax.bar(
            [0, 1], heights, 0.6, color=[FORCE_COLOUR, DIFF_COLOUR], tick_label=["D_er", "D_ed"]
        )
        ax.bar_label(bars, [("—" if v is None else f"{v:.2f} mm") for v in values], fontsize=8)
        ax.set_title(f"{title}, {numbers.get(f'{phase}_samples', 0):,} samples", fontsize=10)
        ax.grid(alpha=0.3, axis="y")
        ax.margins(y=0.15)
    axes[0].set_ylabel("std of the error at 2–3 N (mm)")
    fig.suptitle("Fig. 8: std of the error of D_er and D_ed at small force (simulated)")
    _save(fig, path)


def draw_figure14(path: Path, stats: dict[str, Any]) -> None:
    """(a) The mean error and (b) its std at touch and release, conventional against the
    switched method with the paper's thresholds (the paper's Fig. 14)."""
    fig = _figure(9.0, 4.2)
    axes = fig.subplots(1, 2)
    x = np.arange(2)
    width = 0.38
    panels = (("mean", "(a) mean error"), ("std", "(b) standard deviation"))
    for ax, (what, title) in zip(axes, panels, strict=True):
        for offset, method, colour, name in (
            (-width / 2, "force", CONVENTIONAL_COLOUR, "conventional"),
            (width / 2, "switched", PROPOSED_COLOUR, "proposed (switched)"),
        ):
            values = [stats[f"{method}_{phase}_{what}_mm"] for phase in ("touch", "release")]
            bars = ax.bar(x + offset, values, width, color=colour, label=name)
            ax.bar_label(bars, [f"{v:.2f}" for v in values], fontsize=8)
        ax.set_xticks(x, ["touch", "release"])
        ax.set_ylabel("error (mm)")
        ax.set_title(title, fontsize=10)
        ax.grid(alpha=0.3, axis="y")
        ax.margins(y=0.15)
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, fontsize=8, loc="outside lower center", ncol=2, frameon=False)
    fig.suptitle("Fig. 14: the computed contact point at touch and release (simulated)")
    _save(fig, path)


def draw_figure16(path: Path, rec: Recording, blocks: dict[str, ContactBlock]) -> None:
    """The traced character (kita, 北) with (a) the conventional and (b) the proposed method (the
    paper's Fig. 16), the true path as a line. Points more than :data:`OFF_CHARACTER_M` from
    the true point of their sample are counted in the panel's corner, by candidate."""
    fig = _figure(12.0, 6.2)
    axes = np.atleast_1d(fig.subplots(1, len(blocks)))
    tx, ty = rec.extra["true_x"], rec.extra["true_y"]
    # both panels around the character (a point far off is clipped, and counted below)
    lo = np.array([np.nanmin(tx), np.nanmin(ty)])
    hi = np.array([np.nanmax(tx), np.nanmax(ty)])
    margin = 0.12 * float((hi - lo).max())
    titles = {"force": "(a) conventional (force)", "switched": "(b) proposed (switched)"}
    for ax, (method, block) in zip(axes, blocks.items(), strict=True):
        _traced_panel(ax, block, tx, ty)
        ax.set_title(titles.get(method, method), fontsize=10, loc="left")
    axes[0].set_ylabel("y (m)")
    # (the character's name, not its glyph: the fonts matplotlib brings have no CJK)
    fig.suptitle("Fig. 16: the character kita traced at 3.4 cm/s (simulated)")
    fig.draw_without_rendering()  # the layout first, then metres the same on both axes
    fig.set_layout_engine("none")
    for ax in axes:
        _equal_scale(ax, lo - margin, hi + margin)
    _save(fig, path)


#: Fig. 16's candidates: the name and colour of each
TRACED_SOURCES = {
    SOURCE_FORCE: ("from force", FORCE_COLOUR),
    SOURCE_DIFF: ("from differentiated force", DIFF_COLOUR),
    SOURCE_FUSED: ("fused", "tab:red"),
}


def _traced_panel(ax: Any, block: ContactBlock, tx: np.ndarray, ty: np.ndarray) -> None:
    """One method's panel of Fig. 16: the true path (``tx``, ``ty``), the located points by
    candidate, and the points off the character counted in the corner."""
    ax.plot(tx, ty, color="black", lw=1, label="true path", zorder=3)
    # the true point of each sample, held through a lift (no truth once the finger is up)
    held_x, held_y = _held(tx), _held(ty)
    off = block.located & (np.hypot(block.x - held_x, block.y - held_y) > OFF_CHARACTER_M)
    notes = []
    for source, (name, colour) in TRACED_SOURCES.items():
        sel = block.located & (block.source == source)
        if sel.any():
            ax.scatter(
                block.x[sel],
                block.y[sel],
                s=2,
                color=colour,
                label=name,
                rasterized=True,
                linewidths=0,
            )
        far = off & (block.source == source)
        if far.any():
            worst = float(np.max(np.hypot(block.x - held_x, block.y - held_y)[far]))
            notes.append(f"{int(far.sum())} {name}, up to {100 * worst:.0f} cm off")
    ax.set_xlabel("x (m)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, markerscale=4, loc="upper right")
    if notes:
        ax.text(
            0.02,
            0.02,
            f"points > {100 * OFF_CHARACTER_M:.0f} cm from the true one:\n" + "\n".join(notes),
            transform=ax.transAxes,
            fontsize=8,
            va="bottom",
            bbox={"facecolor": "white", "edgecolor": "#cccccc", "alpha": 0.9},
        )


def _equal_scale(ax: Any, lo: np.ndarray, hi: np.ndarray) -> None:
    """Limits that hold the box ``lo``–``hi`` (x, y) with one metre as long on both axes,
    the axes' box left as the layout made it (an equal aspect that shrinks the box had moved
    the title into the figure's and the x label off the image)."""
    box = ax.get_window_extent()
    centre, span = (lo + hi) / 2, hi - lo
    per_pixel = max(span[0] / box.width, span[1] / box.height)
    half = 0.5 * per_pixel * np.array([box.width, box.height])
    ax.set_xlim(centre[0] - half[0], centre[0] + half[0])
    ax.set_ylim(centre[1] - half[1], centre[1] + half[1])


def _held(values: np.ndarray) -> np.ndarray:
    """``values`` with each NaN (no truth: the finger is up) replaced by the last value before."""
    v = np.asarray(values, dtype=float)
    index = np.where(np.isfinite(v), np.arange(len(v)), 0)
    np.maximum.accumulate(index, out=index)
    return v[index]


def _plain_log_ticks(ax: Any, *, x_too: bool = True) -> None:
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    for axis in (ax.xaxis, ax.yaxis) if x_too else (ax.yaxis,):
        axis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
        axis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        axis.set_minor_formatter(NullFormatter())
