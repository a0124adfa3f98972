"""Edge taps on the simulated load-cell desks (scripts/tap_accuracy.py's test, docs/loadcells.md):
the shipped profiles, a desk built other than its profile says and set up with a known
weight, and what four converters on their own clocks cost."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

from hapticdesk.files.profile_reader import load_profile
from hapticdesk.sim.loadcells import LoadCellParameters

SCRIPTS = Path(__file__).resolve().parents[2] / "scripts"


def _script(name: str):  # type: ignore[no-untyped-def]
    spec = importlib.util.spec_from_file_location(name, SCRIPTS / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # its dataclasses look themselves up there
    spec.loader.exec_module(module)
    return module


tap_accuracy = _script("tap_accuracy")
sys.path.insert(0, str(SCRIPTS))  # (loadcell_accuracy imports tap_accuracy beside it)
loadcell_accuracy = _script("loadcell_accuracy")


def judged(tally) -> int:  # type: ignore[no-untyped-def]
    return tally.taps - tally.under


@pytest.mark.slow
@pytest.mark.parametrize(
    ("name", "share"),
    [
        ("kitamura2017-loadcells-80hz", 0.97),
        ("kitamura2017-loadcells-1khz", 0.99),
        ("balance-board", 0.97),
    ],
)
def test_edge_taps_on_the_load_cell_desks(name: str, share: float) -> None:
    """The issue's floors: 97 % right at 80 Hz, 99 % at 1 kHz; none wrong, none made up
    (1,000 taps each in docs/loadcells.md: 99.9 %)."""
    desk = load_profile(name)
    tally = tap_accuracy.measure(desk, tap_accuracy.buttons(desk), 200, 5)
    assert tally.wrong == 0 and tally.phantom == 0
    assert tally.right >= share * judged(tally)
    assert tally.light >= 60


@pytest.mark.slow
def test_a_desk_built_off_its_profile_is_set_right_with_a_known_weight() -> None:
    """Gains 5 % off, cells 2 cm off: taps land in wrong buttons or are lost; after 1 kg on
    four spots they are right again."""
    desk = load_profile("kitamura2017-loadcells-80hz")
    built, gains = loadcell_accuracy.built_off(desk, np.random.default_rng(5))
    cells = LoadCellParameters.for_rate(80, gains=gains)
    layout = tap_accuracy.buttons(desk)
    off = tap_accuracy.measure(desk, layout, 200, 5, cells=cells, built=built)
    assert off.right < 0.95 * judged(off)  # (wrong buttons or taps lost)
    fitted, _ = loadcell_accuracy.setup_with_weight(desk, built, cells, 5)
    tally = tap_accuracy.measure(
        fitted, tap_accuracy.buttons(fitted), 200, 5, cells=cells, built=built
    )
    assert tally.wrong == 0 and tally.phantom == 0
    assert tally.right >= 0.97 * judged(tally)


@pytest.mark.slow
def test_converters_on_their_own_clocks_need_their_channels_aligned() -> None:
    """Four HX711s on their own oscillators: a tap's rising force read up to 12.5 ms apart on
    the cells is a false moment, and taps are lost; aligned to t − T at each channel's own
    conversion times they are back."""
    desk = load_profile("kitamura2017-loadcells-80hz")
    own = LoadCellParameters.for_rate(80, sampling="independent")
    raw = tap_accuracy.measure(desk, tap_accuracy.buttons(desk), 200, 5, cells=own)
    fixed = loadcell_accuracy.aligned_taps(desk, 200, 5, own)
    assert raw.right < 0.9 * judged(raw)
    assert fixed.right >= 0.97 * judged(fixed) and fixed.wrong == 0 and fixed.phantom == 0
    assert fixed.taps == raw.taps  # the same taps on the same clocks: only the alignment
