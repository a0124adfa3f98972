"""Taps 2–10 mm inside a button's edge, light ones included, on the paper desk and on a desk
nothing was tuned on (scripts/tap_accuracy.py; issue 10, item 4); a tap is judged on its
pressed part, not on the lift-off tail below the contact force."""

from __future__ import annotations

import importlib.util
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from hapticdesk.files.profile_reader import load_profile
from hapticdesk.gestures.engine import GestureEngine

ROOT = Path(__file__).resolve().parents[2]
_spec = importlib.util.spec_from_file_location("tap_accuracy", ROOT / "scripts" / "tap_accuracy.py")
assert _spec is not None and _spec.loader is not None
tap_accuracy = importlib.util.module_from_spec(_spec)
sys.modules["tap_accuracy"] = tap_accuracy  # its dataclass looks itself up there
_spec.loader.exec_module(tap_accuracy)


def judged(tally) -> int:
    """Taps whose true force reached the contact force (the script's share is over these)."""
    return tally.taps - tally.under


def test_edge_taps_on_the_paper_desk_land_in_their_button():
    desk = load_profile("kitamura2017")
    tally = tap_accuracy.measure(desk, tap_accuracy.buttons(desk), 200, 5)
    assert tally.wrong == 0 and tally.phantom == 0
    assert tally.under <= 0.03 * tally.taps  # only taps the tremor kept below 2 N
    assert tally.right >= 0.975 * judged(tally)  # 99.2–99.6 % over 1,000 (README)
    assert tally.light >= 60  # light 2–3 N taps are among them


def test_snap_is_what_keeps_edge_taps():
    """Without snapping (0.5 mm) the same taps are lost far more often."""
    desk = load_profile("kitamura2017")
    tally = tap_accuracy.measure(desk, tap_accuracy.buttons(desk, snap_mm=0.5), 200, 5)
    assert tally.right < 0.93 * judged(tally)
    assert tally.wrong == 0 and tally.phantom == 0


def test_a_slowly_sampled_desk_misses_light_taps_but_places_none_wrong():
    """The paper desk polled at 150 Hz: a light tap is a handful of readings, its 1-σ stays
    above the estimator's gate and it is not located; a tap the estimator does place still
    lands in its button (README, "The sample rate sets what a light tap can give")."""
    desk = load_profile("kitamura2017")
    slow = replace(desk, sample_rate_hz=150.0)
    tally = tap_accuracy.measure(slow, tap_accuracy.buttons(slow), 200, 5)
    assert tally.wrong == 0 and tally.phantom == 0
    assert tally.light_right < 0.5 * tally.light  # the gate refuses, rather than guess
    assert tally.unlocated >= 0.9 * tally.missed
    assert tally.right - tally.light_right >= 0.8 * (judged(tally) - tally.light)  # firm ones


def test_a_sensor_quieter_than_its_resolution_step_presses_no_wrong_button():
    """A quiet sensor (no noise beyond its 1/2000 resolution) leaves the zero off by up to
    half a step a channel, an error every sample of a touch shares: the located 1-σ holds it
    (estimator/resolution.py ``zero_rounding``), so a light tap near an edge, 1-2 cm
    uncertain, presses no button rather than a wrong one. Measured (200 taps): 0 in a wrong
    button and 32 % right, of the firm ones (3-8 N) 60 %; before, 76 % right with a 1-σ a
    third of the error and 2 in a wrong button (9 of 1,000)."""
    desk = load_profile("kitamura2017")
    quiet = tap_accuracy.SensorParameters(noise_amplitude_n=0.2)
    tally = tap_accuracy.measure(desk, tap_accuracy.buttons(desk), 200, 5, sensors=quiet)
    assert tally.wrong == 0 and tally.phantom == 0
    firm_right = tally.right - tally.light_right
    assert firm_right >= 0.5 * (judged(tally) - tally.light)  # a firm tap is still placed
    assert tally.right >= 0.25 * judged(tally)


@pytest.mark.xfail(
    strict=True,
    reason="known weakness: a sensor quieter than its resolution step is not dithered; the "
    "zero is then off by up to half a step per channel, which the 1-sigma now holds: none in "
    "a wrong button, but a light tap near an edge is 1-2 cm uncertain and presses none "
    "(32 % right; docs/results/gestures.md)",
)
def test_a_sensor_quieter_than_its_resolution_step_places_taps_as_well():
    """The paper desk's sensors with no noise beyond their 1/2000 resolution (the simulator's
    0.4 N amplitude already holds the rounding: any amplitude under about 0.26 N is rounding
    alone). A quieter sensor must not place taps worse; today 32 % of them land right and
    none in a wrong button (`python scripts/tap_accuracy.py --desk paper --noise 0.1`: 34 %,
    none; before the zero's rounding offset, 75 % and 9 of 1,000)."""
    desk = load_profile("kitamura2017")
    quiet = tap_accuracy.SensorParameters(noise_amplitude_n=0.2)
    tally = tap_accuracy.measure(desk, tap_accuracy.buttons(desk), 200, 5, sensors=quiet)
    assert tally.wrong == 0 and tally.phantom == 0
    assert tally.right >= 0.975 * judged(tally)


@pytest.mark.slow
@pytest.mark.parametrize("which", ["paper", "unseen-six"])
def test_a_thousand_edge_taps(which):
    [desk] = tap_accuracy.desks(which).values()
    tally = tap_accuracy.measure(desk, tap_accuracy.buttons(desk), 1000, 1)
    assert tally.wrong == 0 and tally.phantom == 0
    assert tally.right >= 0.99 * judged(tally)


LAMP = """
units: cm
regions:
  lamp: {rect: [-25, -15, -15, -5]}
bindings:
  - {gesture: tap, region: lamp, do: {log: {}}}
"""


def lifting_off(tau: np.ndarray) -> np.ndarray:
    """4 N for 100 ms, then the last 30 ms below the 2 N contact force (the lift-off)."""
    return np.where(tau < 0.1, 4.0, 1.9 - 30.0 * (tau - 0.1))


def drifting_tail(u: np.ndarray) -> np.ndarray:
    """Still at (-20, -10) cm while pressed; the lift-off tail slides 3 cm away (what the
    differentiated candidate does below the contact force), slowly enough for the gate."""
    tail = np.clip((u - 0.1 / 0.13) / (0.03 / 0.13), 0.0, 1.0)
    return np.column_stack([-0.2 + 0.03 * tail, np.full_like(u, -0.1)])


def test_a_tap_is_judged_on_its_pressed_part_not_on_the_lift_off_tail(make_layout, timeline):
    layout = make_layout(LAMP)
    tl = timeline(1.5).touch(1.0, 0.13, drifting_tail, force_profile=lifting_off)
    engine = GestureEngine(layout)
    events = engine.feed(tl.block()) + engine.flush(float(tl.t[-1]))
    assert [(e.gesture, e.region) for e in events] == [("tap", "lamp")]
    assert events[0].x == pytest.approx(-0.2, abs=0.002)
    # the same tail pressed at 4 N is a real slide of 3 cm: no tap (the test can fail)
    tl = timeline(1.5).touch(1.0, 0.13, drifting_tail, force_profile=lambda tau: 4.0 + 0 * tau)
    engine = GestureEngine(layout)
    assert engine.feed(tl.block()) + engine.flush(float(tl.t[-1])) == []


SHAPES = """
units: cm
regions:
  square: {rect: [0, 0, 10, 10]}
  dot: {circle: {center: [30, 5], radius: 5}}
  wedge: {polygon: [[0, 20], [10, 20], [10, 20], [0, 30]]}
bindings:
  - {gesture: tap, region: square, do: {log: {}}}
  - {gesture: tap, region: dot, do: {log: {}}}
  - {gesture: tap, region: wedge, do: {log: {}}}
"""


@pytest.mark.parametrize(
    ("region", "point", "expected"),
    [
        ("square", (0.05, 0.05), 0.0),  # inside
        ("square", (0.13, 0.05), 0.03),  # beside an edge
        ("square", (0.13, 0.14), 0.05),  # off a corner: 3-4-5
        ("dot", (0.30, 0.05), 0.0),
        ("dot", (0.30, 0.12), 0.02),
        ("wedge", (0.02, 0.22), 0.0),
        ("wedge", (0.05, 0.17), 0.03),  # below the bottom edge
        ("wedge", (0.14, 0.20), 0.04),  # beyond the repeated vertex: no NaN from it
    ],
)
def test_how_far_a_point_lies_outside_a_region(make_layout, region, point, expected):
    got = make_layout(SHAPES).regions[region].distance(*point)
    assert got == pytest.approx(expected, abs=1e-9)


def test_snap_takes_the_nearest_region_and_only_within_its_distance(make_layout, timeline):
    layout = make_layout(SHAPES)  # snap 12 mm by default
    fired = []
    # between the square (x ≤ 10 cm) and the dot (x ≥ 25 cm): 5, 11, 13, 55 and 11 mm off
    for x in (0.105, 0.111, 0.113, 0.195, 0.239):
        tl = timeline(1.5).touch(1.0, 0.1, (x, 0.05), noise=False)
        engine = GestureEngine(layout)
        events = engine.feed(tl.block()) + engine.flush(float(tl.t[-1]))
        fired.append(events[0].region if events else None)
    assert fired == ["square", "square", None, None, "dot"]
