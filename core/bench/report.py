"""Showing benchmark results: a terminal table, and PNGs (matplotlib, imported only here)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hapticdesk.bench.runner import pareto_front

COLUMNS = [
    ("label", "configuration", "{}"),
    ("touch+20ms_p95_mm", "+20ms", "{:.2f}"),
    ("touch+50ms_p95_mm", "+50ms", "{:.2f}"),
    ("release-20ms_p95_mm", "rel-20ms", "{:.2f}"),
    ("touch_p95_common_mm", "touch=", "{:.2f}"),
    ("hold_p95_common_mm", "hold=", "{:.2f}"),
    ("release_p95_common_mm", "rel=", "{:.2f}"),
    ("release_max_mm", "rel max", "{:.1f}"),
    ("touch_coverage", "touch cov", "{:.2f}"),
    ("touch_delay_p95_ms", "down p95", "{:.1f}"),
    ("first_point_delay_ms", "1st pt", "{:.0f}"),
    ("release_delay_p95_ms", "up p95", "{:.1f}"),
    ("samples_per_s", "batch S/s", "{:,.0f}"),
    ("us_per_sample_stream", "µs k=1", "{:.1f}"),
    ("us_per_sample_stream_range", "range", "{:.1f}–{:.1f}"),
]
#: what a cell says when a time-offset p95 is a miss (more than 5 % not located)
MISS = "miss"


def table(rows: list[dict[str, Any]]) -> str:
    """Rows as an aligned text table (errors in mm, delays in ms)."""
    cells = [[title for _, title, _ in COLUMNS]]
    for row in rows:
        cells.append([_cell(row, key, fmt) for key, _, fmt in COLUMNS])
    widths = [max(len(r[i]) for r in cells) for i in range(len(COLUMNS))]
    lines = []
    for n, r in enumerate(cells):
        lines.append(
            "  ".join(
                c.ljust(w) if i == 0 else c.rjust(w)
                for i, (c, w) in enumerate(zip(r, widths, strict=True))
            )
        )
        if n == 0:
            lines.append("  ".join("-" * w for w in widths))
    return "\n".join(lines)


def _cell(row: dict[str, Any], key: str, fmt: str) -> str:
    if key.endswith("_range"):  # the figure's min and max over the rounds
        figure = key.removesuffix("_range")
        low, high = row.get(f"{figure}_min"), row.get(f"{figure}_max")
        return "—" if low is None or high is None else fmt.format(low, high)
    if row.get(key) is not None:
        return fmt.format(row[key])
    located = row.get(key.replace("_p95_mm", "_located"))
    return MISS if located is not None else "—"


#: on a panel's logarithmic error axis, a point more than this factor off the panel's median
#: error is drawn at the axis's edge, its value written beside it (one 816 mm point had
#: flattened every other point of its panel into the bottom tenth)
OUTLIER_FACTOR = 10.0
#: where a point's number is tried, in points from the point: right, left, above, below, then
#: the diagonals, then further out
LABEL_OFFSETS = [
    (dx * r, dy * r)
    for r in (1.0, 2.2, 3.4)
    for dx, dy in ((5, -3), (-5, -3), (0, 5), (0, -11), (5, 4), (-5, 4), (5, -10), (-5, -10))
]


#: each method's colour on the Pareto plot
METHOD_COLOURS = {
    "force": "tab:blue",
    "diff": "tab:orange",
    "switched": "tab:green",
    "fused": "tab:red",
}
#: the Pareto plot's panels: the error column each shows, and its title
PARETO_PANELS = (
    ("touch+50ms_p95_mm", "50 ms after touch-down"),
    ("touch_p95_common_mm", "touch, samples all methods locate"),
    ("release_p95_common_mm", "release until the contact ends"),
)
#: the run time the Pareto plot sets the errors against
COST_KEY = "us_per_sample_stream"


@dataclass(frozen=True)
class RunTimes:
    """Each row's run time (µs per sample, the median over the rounds) and its range."""

    median: np.ndarray
    low: np.ndarray
    high: np.ndarray

    @classmethod
    def of(cls, rows: list[dict[str, Any]]) -> RunTimes:
        """The run times of the bench's ``rows`` (:data:`COST_KEY` and its ``_min``/``_max``)."""
        return cls(
            np.array([r[COST_KEY] for r in rows], dtype=float),
            np.array([r.get(f"{COST_KEY}_min", r[COST_KEY]) for r in rows], dtype=float),
            np.array([r.get(f"{COST_KEY}_max", r[COST_KEY]) for r in rows], dtype=float),
        )


@dataclass(frozen=True)
class NumberedPoints:
    """The points drawn on one panel (data coordinates) and the number each is to carry."""

    ax: Any
    xs: np.ndarray
    ys: np.ndarray
    names: list[str]


def plot_pareto(rows: list[dict[str, Any]], path: Path) -> None:
    """Error at equal coverage against µs per sample (single-sample streaming): each point
    the median run time with a bar over its range across the rounds, the Pareto front
    (:func:`~hapticdesk.bench.runner.pareto_front`: costs within each other's range tie)
    drawn as a line and ringed. Points carry numbers explained in a key beside the panels,
    each placed where it overlaps no other number or point; the error axis is logarithmic
    with plain numbers as ticks, limited to the bulk of the points, with any point
    :data:`OUTLIER_FACTOR` off drawn at the edge as an arrow with its value."""
    import matplotlib.pyplot as plt

    fig = pareto_figure(rows)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def pareto_figure(rows: list[dict[str, Any]]) -> Any:
    """The figure :func:`plot_pareto` writes, drawn; tall enough for the key beside the
    panels to list every row above the methods' legend (the full bench's 34 rows ran under
    it at the quick one's 5.4 inches)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(15, max(5.4, 2.4 + 0.14 * len(rows))), layout="constrained")
    panels = PARETO_PANELS
    grid = fig.add_gridspec(1, len(panels) + 1, width_ratios=[1] * len(panels) + [0.8])
    times = RunTimes.of(rows)
    numbered = [
        _pareto_panel(fig.add_subplot(grid[0, n]), rows, key, title, times)
        for n, (key, title) in enumerate(panels)
    ]
    _method_key(fig.add_subplot(grid[0, -1]), rows)
    fig.suptitle(
        "hapticdesk bench: error at equal coverage against run time "
        "(the paper's experiment, simulated with the paper's noise)"
    )
    # the layout fixed first: the numbers are placed where the points end up
    fig.draw_without_rendering()
    fig.set_layout_engine("none")
    for points in numbered:
        place_labels(points.ax, points.xs, points.ys, points.names, fontsize=7)
    return fig


def _pareto_panel(
    ax: Any, rows: list[dict[str, Any]], key: str, title: str, times: RunTimes
) -> NumberedPoints:
    """One panel: the error column ``key`` against the run times, the front drawn."""
    cost, low, high = times.median, times.low, times.high
    err = np.array([np.nan if r.get(key) is None else r[key] for r in rows], dtype=float)
    shown = np.flatnonzero(np.isfinite(err) & (err > 0))
    lo_lim, hi_lim = _robust_log_limits(err[shown])
    drawn = np.clip(err, lo_lim, hi_lim)
    for i in shown:
        colour = METHOD_COLOURS.get(rows[i]["method"], "grey")
        ax.errorbar(
            cost[i],
            drawn[i],
            xerr=[[cost[i] - low[i]], [high[i] - cost[i]]],
            fmt="none",
            ecolor=colour,
            alpha=0.5,
            lw=1.0,
            capsize=2,
            zorder=2,
        )
        outside = err[i] > hi_lim or err[i] < lo_lim
        ax.scatter(
            cost[i],
            drawn[i],
            color=colour,
            s=36,
            marker=("^" if err[i] > hi_lim else "v") if outside else "o",
            zorder=3,
            clip_on=False,
        )
    front = sorted(pareto_front(rows, key, COST_KEY), key=lambda i: cost[i])
    if front:
        ax.step(cost[front], drawn[front], where="post", color="black", lw=1.0, zorder=1)
        ax.scatter(cost[front], drawn[front], s=110, facecolors="none", edgecolors="black", lw=0.8)
    inside = err[shown][(err[shown] >= lo_lim) & (err[shown] <= hi_lim)]
    _log_error_axis(ax, inside, lo_lim, hi_lim)
    ax.set_title(title, fontsize=10)
    names = [
        f"{i + 1}" if lo_lim <= err[i] <= hi_lim else f"{i + 1}: {err[i]:.0f} mm" for i in shown
    ]
    return NumberedPoints(ax, cost[shown], drawn[shown], names)


def _log_error_axis(ax: Any, inside: np.ndarray, lo_lim: float, hi_lim: float) -> None:
    """The panel's axes: a logarithmic error axis from ``lo_lim`` to ``hi_lim`` with plain
    numbers as ticks (``inside``: the errors drawn within it), run time across."""
    from matplotlib.ticker import FixedLocator, FuncFormatter, LogLocator, MaxNLocator

    plain = FuncFormatter(lambda v, _: f"{v:g}")
    ax.set_yscale("log")
    ax.set_ylim(lo_lim, hi_lim)
    if len(inside) and inside.max() < 10 * inside.min():
        # within one decade 1-2-5 leaves a single labelled tick: evenly spaced plain ones
        even = MaxNLocator(nbins=6, steps=[1, 2, 2.5, 5, 10]).tick_values(lo_lim, hi_lim)
        ax.yaxis.set_major_locator(FixedLocator(even))
    else:
        ax.yaxis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
    ax.yaxis.set_major_formatter(plain)
    ax.yaxis.set_minor_formatter(FuncFormatter(lambda v, _: ""))
    ax.xaxis.set_major_formatter(plain)
    ax.set_xlabel("µs per sample, single-sample push")
    ax.set_ylabel("error p95 (mm)")
    ax.grid(alpha=0.3, which="both")


def _method_key(key_ax: Any, rows: list[dict[str, Any]]) -> None:
    """The key beside the panels: the methods' colours, then each point's number and row."""
    key_ax.axis("off")
    # the colours' legend beside the numbered key, off the data (on a panel it hid points)
    for method, colour in METHOD_COLOURS.items():
        key_ax.scatter([], [], color=colour, label=method)
    key_ax.plot([], [], color="grey", lw=1.0, marker="|", label="run time: min–max of the rounds")
    key_ax.plot([], [], color="black", lw=1.0, label="Pareto front")
    key_ax.legend(fontsize=8, loc="lower left", title="method", title_fontsize=8)
    key_ax.text(
        0,
        1,
        "\n".join(f"{i + 1:>2}  {r['label']}" for i, r in enumerate(rows)),
        va="top",
        ha="left",
        fontsize=8,
        family="monospace",
        transform=key_ax.transAxes,
    )


def _robust_log_limits(values: np.ndarray) -> tuple[float, float]:
    """A logarithmic axis's limits around the bulk of ``values`` (positive): every value
    within :data:`OUTLIER_FACTOR` of their median, with a margin."""
    if len(values) == 0:
        return 1.0, 10.0
    median = float(np.median(values))
    bulk = values[(values <= OUTLIER_FACTOR * median) & (values >= median / OUTLIER_FACTOR)]
    lo, hi = float(bulk.min()), float(bulk.max())
    margin = max(hi / lo, 1.2) ** 0.08
    return lo / margin, hi * margin


def place_labels(
    ax: Any, xs: np.ndarray, ys: np.ndarray, texts: list[str], *, fontsize: float = 7
) -> None:
    """Write ``texts`` beside the points (``xs``, ``ys``, data coordinates) of a figure whose
    layout is fixed, each at the first of :data:`LABEL_OFFSETS` where it overlaps no point,
    no label placed before it and nothing outside the axes; one that fits nowhere goes to
    the last place tried, with a thin line to its point."""
    from matplotlib.transforms import Bbox

    renderer = ax.figure.canvas.get_renderer()
    frame = ax.get_window_extent(renderer)
    half = 4.0  # a marker's half size in pixels, at the sizes these figures use
    taken = [
        Bbox.from_extents(x - half, y - half, x + half, y + half)
        for x, y in ax.transData.transform(np.column_stack([xs, ys]))
    ]
    for x, y, text in zip(xs, ys, texts, strict=True):
        for n, (dx, dy) in enumerate(LABEL_OFFSETS):
            last = n == len(LABEL_OFFSETS) - 1
            label = ax.annotate(
                text,
                (x, y),
                xytext=(dx, dy),
                textcoords="offset points",
                fontsize=fontsize,
                ha="left" if dx > 0 else "right" if dx < 0 else "center",
                arrowprops={"arrowstyle": "-", "lw": 0.5, "color": "grey"} if last else None,
            )
            box = label.get_window_extent(renderer)
            inside = frame.contains(box.x0, box.y0) and frame.contains(box.x1, box.y1)
            if last or (inside and not any(box.overlaps(other) for other in taken)):
                taken.append(box)
                break
            label.remove()
