"""The plot's view from above (paper Fig. 13): the desk's outlines, the contact points
coloured by the candidate each came from, the true path, and a magnified inset when the
points fill a small part of the top. Drawn by :mod:`hapticdesk.analysis.plotting`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from hapticdesk.analysis.plot_style import SOURCE_COLOURS, SOURCES_DRAWN, TRUTH_COLOUR
from hapticdesk.estimator.contacts import SOURCE_NAMES, ContactBlock
from hapticdesk.files.profile import DeskProfile

if TYPE_CHECKING:
    from matplotlib.axes import Axes


def desk_panel(
    ax: Axes,
    profile: DeskProfile,
    block: ContactBlock,
    truth: dict[str, np.ndarray],
    sel: np.ndarray,
) -> None:
    """The outlines from above with the contact points and the true path (paper Fig. 13)."""
    outline = _draw_outlines(ax, profile)
    if "true_x" in truth and "true_y" in truth:
        ax.plot(
            truth["true_x"][sel],
            truth["true_y"][sel],
            color=TRUTH_COLOUR,
            linewidth=1.0,
            label="true path",
        )
    located = sel[block.located[sel]]
    _scatter_by_source(ax, block, located, size=3, key=True)
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


def _draw_outlines(ax: Axes, profile: DeskProfile) -> np.ndarray:
    """Each surface's outline, named at its centre; returns the outlines' corners (N, 2)."""
    corners = []
    for surface in profile.surfaces:
        poly = np.vstack([surface.polygon, surface.polygon[:1]])
        xyz = surface.to_desk(poly[:, 0], poly[:, 1])
        corners.append(xyz[:, :2])
        ax.plot(xyz[:, 0], xyz[:, 1], color="#555555", linewidth=1.2)
        centre = xyz[:-1, :2].mean(axis=0)
        ax.annotate(surface.name, centre, color="#999999", fontsize=8, ha="center")
    return np.vstack(corners)


def _scatter_by_source(
    ax: Axes, block: ContactBlock, located: np.ndarray, *, size: float, key: bool
) -> None:
    """The located points, coloured by the candidate each came from; with ``key`` each
    candidate is counted in the legend and the most numerous drawn on top."""
    for source in SOURCES_DRAWN:
        at = located[block.source[located] == source]
        if not len(at):
            continue
        keyed: dict[str, Any] = {}
        if key:
            keyed = {
                "label": f"{SOURCE_NAMES[source]} ({len(at):,})",
                # the most numerous on top: the rarer candidates' points lie around them,
                # where they stay visible (the force's 56,431 had been hidden under 15,230)
                "zorder": 2 + len(at) / max(len(located), 1),
            }
        ax.scatter(
            block.x[at],
            block.y[at],
            s=size,
            color=SOURCE_COLOURS[source],
            rasterized=True,
            linewidths=0,
            **keyed,
        )


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
    _scatter_by_source(inset, block, located, size=4, key=False)
    inset.set_xlim(mid[0] - half, mid[0] + half)
    inset.set_ylim(mid[1] - half, mid[1] + half)
    inset.set_aspect("equal")
    inset.tick_params(labelsize=7)
    inset.locator_params(nbins=3)
    inset.ticklabel_format(useOffset=False)
    inset.set_title(f"{2 * half * 1e3:.0f} mm square", fontsize=7)
    inset.grid(True, alpha=0.3)
    ax.indicate_inset_zoom(inset, edgecolor="#777777")
