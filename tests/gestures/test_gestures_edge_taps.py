"""Taps 2–10 mm inside a button's edge, light ones included, on the paper desk and on a desk
nothing was tuned on (scripts/tap_accuracy.py; issue 10, item 4)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

from hapticdesk.files.profile import load_profile
from hapticdesk.gestures.layout import load_layout

ROOT = Path(__file__).resolve().parents[2]
_spec = importlib.util.spec_from_file_location("tap_accuracy", ROOT / "scripts" / "tap_accuracy.py")
assert _spec is not None and _spec.loader is not None
tap_accuracy = importlib.util.module_from_spec(_spec)
sys.modules["tap_accuracy"] = tap_accuracy  # its dataclass looks itself up there
_spec.loader.exec_module(tap_accuracy)


def test_edge_taps_on_the_paper_desk_land_in_their_button():
    desk = load_profile("kitamura2017")
    tally = tap_accuracy.measure(desk, load_layout(tap_accuracy.BUTTONS, profile=desk), 200, 5)
    assert tally.wrong == 0 and tally.phantom == 0
    assert tally.right >= 0.96 * tally.taps  # 98 % over 1,000 (README)


def test_snap_is_what_keeps_edge_taps(tmp_path):
    """Without snapping (snap tiny) the same taps are lost far more often."""
    desk = load_profile("kitamura2017")
    text = tap_accuracy.BUTTONS.read_text().replace(
        "bindings:", "settings: {tap: {snap: 0.001}}\nbindings:"
    )
    (tmp_path / "buttons.yaml").write_text(text)
    tally = tap_accuracy.measure(desk, load_layout(tmp_path / "buttons.yaml", profile=desk), 200, 5)
    assert tally.right < 0.93 * tally.taps


@pytest.mark.slow
@pytest.mark.parametrize("which", ["paper", "unseen"])
def test_a_thousand_edge_taps(which):
    [desk] = tap_accuracy.desks(which).values()
    tally = tap_accuracy.measure(desk, load_layout(tap_accuracy.BUTTONS, profile=desk), 1000, 1)
    assert tally.wrong == 0 and tally.phantom == 0
    # the unseen desk's light taps are often never located by the estimator (README)
    assert tally.right >= (0.97 if which == "paper" else 0.75) * tally.taps
