"""What the analysis plots share: the candidates' colours, the truth's, and the title and
legend placed above a panel, off the data.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from hapticdesk.estimator.contacts import SOURCE_DIFF, SOURCE_FORCE, SOURCE_FUSED

if TYPE_CHECKING:
    from matplotlib.axes import Axes

#: the candidates, in the order they are drawn and counted
SOURCES_DRAWN = (SOURCE_FORCE, SOURCE_DIFF, SOURCE_FUSED)
SOURCE_COLOURS = {SOURCE_FORCE: "#1f77b4", SOURCE_DIFF: "#ff7f0e", SOURCE_FUSED: "#2ca02c"}
TRUTH_COLOUR = "#222222"


def title_and_legend(ax: Axes, title: str, **legend: Any) -> None:
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
