"""`bench --plot`'s key beside the panels: every configuration's number and name readable, the
methods' legend not drawn over them (the full bench's 34 rows ran under it)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from hapticdesk.bench.report import COST_KEY, PARETO_PANELS, pareto_figure

METHODS = ("force", "diff", "switched", "fused")


def _rows(count: int) -> list[dict[str, Any]]:
    rng = np.random.default_rng(0)
    rows = []
    for i in range(count):
        row: dict[str, Any] = {"method": METHODS[i % 4], "label": f"{METHODS[i % 4]} setting {i}"}
        row.update({key: float(rng.uniform(2, 20)) for key, _ in PARETO_PANELS})
        row[COST_KEY] = float(rng.uniform(3, 8))
        rows.append(row)
    return rows


@pytest.mark.parametrize("count", [15, 34])  # --quick's rows, the full bench's
def test_the_key_lists_every_row_clear_of_the_legend(count: int) -> None:
    pytest.importorskip("matplotlib")
    import matplotlib.pyplot as plt

    fig = pareto_figure(_rows(count))
    try:
        key = fig.axes[-1]
        renderer = fig.canvas.get_renderer()
        listed = key.texts[0].get_window_extent(renderer)
        legend = key.get_legend().get_window_extent(renderer)
        assert key.texts[0].get_text().count("\n") == count - 1
        assert listed.y0 > legend.y1, (listed, legend)  # the list ends above the legend
        assert legend.y0 >= 0
    finally:
        plt.close(fig)
