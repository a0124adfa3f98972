"""Showing benchmark results: a terminal table, and PNGs (matplotlib, imported only here)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from hapticdesk.bench.runner import pareto_front
from hapticdesk.estimator.contacts import SOURCE_DIFF, SOURCE_FORCE, SOURCE_FUSED, ContactBlock
from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.recording import Recording

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
    if row.get(key) is not None:
        return fmt.format(row[key])
    located = row.get(key.replace("_p95_mm", "_located"))
    return MISS if located is not None else "—"


def plot_pareto(rows: list[dict[str, Any]], path: Path) -> None:
    """Error at equal coverage against µs per sample (single-sample streaming), the Pareto
    front marked. Points carry numbers, explained in a key beside the panels, so labels
    never pile up; the error axis is logarithmic with plain numbers as ticks."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import FixedLocator, FuncFormatter, LogLocator, MaxNLocator

    colours = {
        "force": "tab:blue",
        "diff": "tab:orange",
        "switched": "tab:green",
        "fused": "tab:red",
    }
    panels = (
        ("touch+50ms_p95_mm", "50 ms after touch-down"),
        ("touch_p95_common_mm", "touch, samples all methods locate"),
        ("release_p95_common_mm", "release until the contact ends"),
    )
    fig = plt.figure(figsize=(15, 5.2), constrained_layout=True)
    grid = fig.add_gridspec(1, len(panels) + 1, width_ratios=[1] * len(panels) + [0.8])
    plain = FuncFormatter(lambda v, _: f"{v:g}")
    for n, (key, title) in enumerate(panels):
        ax = fig.add_subplot(grid[0, n])
        cost = [r["us_per_sample_stream"] for r in rows]
        err = [r.get(key) for r in rows]
        for i, (r, c, e) in enumerate(zip(rows, cost, err, strict=True)):
            if e is None:
                continue
            ax.scatter(c, e, color=colours.get(r["method"], "grey"), s=36, zorder=3)
            ax.annotate(str(i + 1), (c, e), fontsize=7, xytext=(3, 2), textcoords="offset points")
        front = sorted(
            pareto_front(rows, key, "us_per_sample_stream")
            if any(e is not None for e in err)
            else [],
            key=lambda i: rows[i]["us_per_sample_stream"],
        )
        if front:
            ax.step(
                [cost[i] for i in front],
                [err[i] for i in front],
                where="post",
                color="black",
                lw=1.0,
                zorder=2,
            )
        ax.set_yscale("log")
        shown = [e for e in err if e is not None and e > 0]
        if shown and max(shown) < 10 * min(shown):
            # within one decade 1-2-5 leaves a single labelled tick: evenly spaced plain ones
            even = MaxNLocator(nbins=6, steps=[1, 2, 2.5, 5, 10]).tick_values(
                min(shown), max(shown)
            )
            ax.yaxis.set_major_locator(FixedLocator(even))
        else:
            ax.yaxis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
        ax.yaxis.set_major_formatter(plain)
        ax.yaxis.set_minor_formatter(FuncFormatter(lambda v, _: ""))
        ax.xaxis.set_major_formatter(plain)
        ax.set_xlabel("µs per sample, single-sample push")
        ax.set_ylabel("error p95 (mm)")
        ax.set_title(title, fontsize=10)
        ax.grid(alpha=0.3, which="both")
    key_ax = fig.add_subplot(grid[0, -1])
    key_ax.axis("off")
    # the colours' legend beside the numbered key, off the data (on a panel it hid points)
    for method, colour in colours.items():
        key_ax.scatter([], [], color=colour, label=method)
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
    fig.suptitle(
        "hapticdesk bench: error at equal coverage against run time "
        "(the paper's experiment, simulated with the paper's noise)"
    )
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_trace_comparison(
    profile: DeskProfile, rec: Recording, blocks: dict[str, ContactBlock], path: Path
) -> None:
    """The traced character with each method (paper Fig. 16), truth as a line."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(blocks), figsize=(6 * len(blocks), 6), constrained_layout=True)
    axes = np.atleast_1d(axes)
    tx, ty = rec.extra["true_x"], rec.extra["true_y"]
    for ax, (method, block) in zip(axes, blocks.items(), strict=True):
        ax.plot(tx, ty, color="black", lw=1, label="true path")
        for source, colour, name in (
            (SOURCE_FORCE, "tab:blue", "from force"),
            (SOURCE_DIFF, "tab:orange", "from differentiated force"),
            (SOURCE_FUSED, "tab:red", "fused"),
        ):
            sel = block.located & (block.source == source)
            if sel.any():
                ax.scatter(block.x[sel], block.y[sel], s=2, color=colour, label=name)
        ax.set_aspect("equal")
        ax.set_title(method)
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.legend(fontsize=8, markerscale=4)
        ax.grid(alpha=0.3)
    fig.suptitle("kita (the character in the paper's Fig. 15) traced at 3.4 cm/s, simulated")
    fig.savefig(path, dpi=110)
    plt.close(fig)
