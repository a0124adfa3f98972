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
    ("touch_median_mm", "touch med", "{:.2f}"),
    ("touch_p95_mm", "touch p95", "{:.2f}"),
    ("touch_coverage", "touch cov", "{:.2f}"),
    ("hold_median_mm", "hold med", "{:.2f}"),
    ("hold_p95_mm", "hold p95", "{:.2f}"),
    ("release_p95_mm", "rel p95", "{:.2f}"),
    ("release_max_mm", "rel max", "{:.1f}"),
    ("touch_delay_ms", "down ms", "{:.1f}"),
    ("first_point_delay_ms", "1st pt ms", "{:.0f}"),
    ("release_delay_ms", "up ms", "{:.1f}"),
    ("samples_per_s", "batch S/s", "{:,.0f}"),
    ("us_per_sample_stream", "µs/s k=1", "{:.1f}"),
    ("us_per_sample_block12", "µs/s k=12", "{:.2f}"),
]


def table(rows: list[dict[str, Any]]) -> str:
    """Rows as an aligned text table (errors in mm, delays in ms)."""
    cells = [[title for _, title, _ in COLUMNS]]
    for row in rows:
        cells.append(
            ["—" if row.get(key) is None else fmt.format(row[key]) for key, _, fmt in COLUMNS]
        )
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


def plot_pareto(rows: list[dict[str, Any]], path: Path) -> None:
    """Error against µs per sample (single-sample streaming), Pareto front marked."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(12, 5), constrained_layout=True)
    colours = {
        "force": "tab:blue",
        "diff": "tab:orange",
        "switched": "tab:green",
        "fused": "tab:red",
    }
    for ax, key, title in (
        (axes[0], "touch_p95_mm", "touch"),
        (axes[1], "release_p95_mm", "release"),
    ):
        cost = [r["us_per_sample_stream"] for r in rows]
        err = [r[key] for r in rows]
        for r, c, e in zip(rows, cost, err, strict=True):
            if e is None:
                continue
            ax.scatter(c, e, color=colours.get(r["method"], "grey"), s=40, zorder=3)
            ax.annotate(r["label"], (c, e), fontsize=7, xytext=(4, 3), textcoords="offset points")
        front = sorted(
            pareto_front(rows, key, "us_per_sample_stream"),
            key=lambda i: rows[i]["us_per_sample_stream"],
        )
        ax.step(
            [cost[i] for i in front],
            [err[i] for i in front],
            where="post",
            color="black",
            lw=1.2,
            label="Pareto front",
            zorder=2,
        )
        ax.scatter(
            [cost[i] for i in front],
            [err[i] for i in front],
            facecolors="none",
            edgecolors="black",
            s=120,
            zorder=4,
        )
        ax.set_yscale("log")
        ax.set_xlabel("µs per sample, single-sample streaming")
        ax.set_ylabel(f"{title} error, p95 (mm)")
        ax.set_title(f"{title}: error against run time")
        ax.grid(alpha=0.3)
        for method, colour in colours.items():
            ax.scatter([], [], color=colour, label=method)
        ax.legend(fontsize=8)
    fig.suptitle("hapticdesk bench: the paper's experiment, simulated with the paper's noise")
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
