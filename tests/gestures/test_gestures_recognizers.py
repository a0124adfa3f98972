"""Each recognizer on synthetic contact streams (no estimator): what fires, where and when."""

from __future__ import annotations

import numpy as np
import pytest

from hapticdesk.gestures.engine import GestureEngine
from hapticdesk.gestures.strokes.shapes import hand_drawn

BUTTONS = """
units: cm
regions:
  lamp: {rect: [-25, -15, -15, -5]}
  fan: {circle: {center: [20, 10], radius: 5}}
bindings:
  - {gesture: tap, region: lamp, do: {log: {}}}
  - {gesture: tap, region: fan, do: {log: {}}}
"""


def run(layout, block, t_end=None):
    engine = GestureEngine(layout)
    events = engine.feed(block)
    return events + engine.flush(float(block.t[-1]) if t_end is None else t_end)


def test_tap_fires_at_the_release_sample_in_its_region(make_layout, timeline):
    layout = make_layout(BUTTONS)
    tl = timeline(3.0).touch(1.0, 0.12, (-0.2, -0.1)).touch(2.0, 0.12, (0.21, 0.09))
    events = run(layout, tl.block())
    assert [(e.gesture, e.region) for e in events] == [("tap", "lamp"), ("tap", "fan")]
    release = tl.t[np.flatnonzero(tl.in_contact)[[119, -1]] + 1]  # first samples out of contact
    assert events[0].t == pytest.approx(tl.t[tl.t >= 1.12][0])
    assert events[1].t == pytest.approx(release[1])
    assert events[0].x == pytest.approx(-0.2, abs=0.001)
    assert events[0].force_n == pytest.approx(8.0)


def test_tap_position_is_the_precision_weighted_estimate_not_the_first_samples(
    make_layout, timeline
):
    layout = make_layout(BUTTONS)
    tl = timeline(2.0).touch(1.0, 0.15, (-0.2, -0.1), sigma_m=0.0005)
    # the first 20 ms are placed 6 cm off (in no region), as a force-only estimate at 2 N can
    # be; the estimator says so through σ
    first = (tl.t >= 1.0) & (tl.t < 1.02)
    tl.x[first] += 0.06
    tl.sigma[first] = 0.03
    events = run(layout, tl.block())
    assert [(e.gesture, e.region) for e in events] == [("tap", "lamp")]
    assert events[0].x == pytest.approx(-0.2, abs=0.002)


def test_long_touch_moving_touch_or_touch_outside_regions_is_no_tap(make_layout, timeline):
    layout = make_layout(BUTTONS)
    tl = timeline(6.0)
    tl.touch(1.0, 0.7, (-0.2, -0.1))  # too long
    tl.touch(2.0, 0.2, np.array([[-0.24, -0.1], [-0.16, -0.1]]))  # slides 8 cm
    tl.touch(3.0, 0.1, (0.0, 0.0))  # between regions
    tl.touch(4.0, 0.1, (-0.2, -0.1), force_n=3.0)  # a light 3 N tap still counts
    events = run(layout, tl.block())
    assert [(e.gesture, e.region, round(e.t)) for e in events] == [("tap", "lamp", 4)]


DOUBLE = """
units: cm
regions:
  lamp: {rect: [-25, -15, -15, -5]}
  fan: {rect: [15, -15, 25, -5]}
bindings:
  - {gesture: tap, region: lamp, do: {log: {}}}
  - {gesture: double_tap, region: lamp, do: {log: {}}}
  - {gesture: tap, region: fan, do: {log: {}}}
"""


def test_double_tap_replaces_two_taps_and_single_tap_waits_only_where_double_is_bound(
    make_layout, timeline
):
    layout = make_layout(DOUBLE)
    tl = timeline(6.0)
    tl.touch(1.0, 0.1, (-0.2, -0.1)).touch(1.25, 0.1, (-0.2, -0.1))  # double on lamp
    tl.touch(2.0, 0.1, (-0.2, -0.1))  # single on lamp: waits 0.3 s
    tl.touch(3.0, 0.1, (0.2, -0.1))  # single on fan: at once
    tl.touch(4.0, 0.1, (-0.2, -0.1)).touch(4.2, 0.1, (-0.17, -0.07))  # 4.2 cm apart: two taps
    events = run(layout, tl.block())
    got = [(e.gesture, e.region, round(e.t, 4)) for e in events]
    t_up2 = tl.t[tl.t >= 2.1][0]
    wait = tl.t[tl.t >= t_up2 + 0.3][0]
    assert got == [
        ("double_tap", "lamp", round(tl.t[tl.t >= 1.35][0], 4)),
        ("tap", "lamp", round(wait, 4)),
        ("tap", "fan", round(tl.t[tl.t >= 3.1][0], 4)),
        ("tap", "lamp", round(tl.t[tl.t >= 4.3][0], 4)),  # decided when the second one ended
        ("tap", "lamp", round(tl.t[tl.t >= 4.3][0] + 0.3, 4)),
    ]


def test_pending_single_tap_is_decided_by_flush(make_layout, timeline):
    layout = make_layout(DOUBLE)
    tl = timeline(1.2).touch(1.0, 0.1, (-0.2, -0.1))
    engine = GestureEngine(layout)
    assert engine.feed(tl.block()) == []
    flushed = engine.flush(1.2)
    assert [(e.gesture, e.t) for e in flushed] == [("tap", 1.2)]


LONG = """
units: cm
regions:
  lamp: {rect: [-25, -15, -15, -5]}
bindings:
  - {gesture: long_press, region: lamp, do: {log: {}}}
  - {gesture: long_press, region: lamp, hold_s: 1.5, do: {log: {}}}
  - {gesture: long_press, region: lamp, release: true, do: {log: {}}}
  - {gesture: tap, region: lamp, do: {log: {}}}
"""


def test_long_press_tiers_then_release(make_layout, timeline):
    layout = make_layout(LONG)
    tl = timeline(8.0).touch(1.0, 2.0, (-0.2, -0.1)).touch(4.0, 1.0, (-0.2, -0.1))
    tl.touch(6.0, 1.2, np.array([[-0.24, -0.1], [-0.16, -0.1]]))  # moves: cancelled
    events = run(layout, tl.block())
    got = [(e.gesture, e.hold_s, e.phase, round(e.t, 3)) for e in events]
    assert got == [
        ("long_press", 0.8, None, round(tl.t[tl.t >= 1.8][0], 3)),
        ("long_press", 1.5, None, round(tl.t[tl.t >= 2.5][0], 3)),
        ("long_press", 1.5, "end", round(tl.t[tl.t >= 3.0][0], 3)),
        ("long_press", 0.8, None, round(tl.t[tl.t >= 4.8][0], 3)),
        ("long_press", 0.8, "end", round(tl.t[tl.t >= 5.0][0], 3)),
    ]
    # which binding reacts to what: tier 0.8, tier 1.5, release after >= 0.8
    fired = [[b.index for b in layout.bindings if b.matches(e)] for e in events]
    assert fired == [[0], [1], [2], [0], [2]]


PRESS = """
units: cm
regions:
  pad: {rect: [-10, -10, 10, 10]}
bindings:
  - {gesture: press, region: pad, levels: {light: 4, firm: 10}, hysteresis_n: 1.5,
     do: {log: {}}}
  - {gesture: press, region: pad, level: firm, do: {log: {}}}
"""


def test_press_levels_fire_on_crossing_with_hysteresis(make_layout, timeline):
    layout = make_layout(PRESS)

    def profile(tau):
        # rises to 11 N, trembles around 10 N (±0.6 N, less than the hysteresis), drops to
        # 7 N (re-arms firm), rises to 12 N again
        f = np.interp(tau, [0, 0.2, 0.4, 1.0, 1.2, 1.4, 1.6, 1.9], [2, 11, 10, 10, 7, 12, 12, 2])
        return f + 0.6 * np.sin(2 * np.pi * 8 * tau) * ((tau > 0.4) & (tau < 1.0))

    tl = timeline(4.0).touch(1.0, 1.9, (0.0, 0.0), force_profile=profile)
    events = run(layout, tl.block())
    assert [e.level for e in events] == ["light", "firm", "firm"]
    assert all(e.region == "pad" for e in events)
    assert events[0].force_n == pytest.approx(4.0, abs=0.1)
    assert [b.index for b in layout.bindings if b.matches(events[0])] == [0]
    assert [b.index for b in layout.bindings if b.matches(events[1])] == [0, 1]


FORCE = """
units: cm
regions:
  pad: {rect: [-10, -10, 10, 10]}
bindings:
  - {gesture: force, region: pad, min_n: 2, max_n: 12, interval_s: 0.1, do: {log: {}}}
"""


def test_force_value_begin_update_end_rate_limited(make_layout, timeline):
    layout = make_layout(FORCE)
    tl = timeline(4.0).touch(
        1.0, 2.0, (0, 0), force_profile=lambda tau: np.interp(tau, [0, 1, 2], [2, 12, 2])
    )
    events = run(layout, tl.block())
    phases = [e.phase for e in events]
    assert phases[0] == "begin" and phases[-1] == "end" and set(phases[1:-1]) == {"update"}
    times = np.array([e.t for e in events[:-1]])
    assert np.all(np.diff(times) >= 0.1 - 1e-9)
    values = np.array([e.value for e in events])
    peak = int(np.argmax(values))
    assert values[peak] == pytest.approx(1.0, abs=0.06)
    assert np.all(np.diff(values[: peak + 1]) > 0) and np.all(np.diff(values[peak:]) < 0)
    assert values[-1] <= 0.01
    assert 15 <= len(events) <= 22  # 2 s at most every 0.1 s


SWIPES = """
units: cm
regions:
  pad: {rect: [-20, -20, 20, 20]}
bindings:
  - {gesture: swipe, region: pad, direction: [left, right], do: {log: {}}}
  - {gesture: swipe, directions: 8, do: {log: {}}}
"""


@pytest.mark.parametrize(
    ("dx", "dy", "name4", "name8"),
    [
        (1, 0, "right", "right"),
        (-1, 0, "left", "left"),
        (0, 1, "up", "up"),
        (0, -1, "down", "down"),
        (1, 1.2, "up", "up_right"),
        (-1.2, -1, "left", "down_left"),
    ],
)
def test_swipe_directions_4_in_region_8_anywhere(make_layout, timeline, dx, dy, name4, name8):
    layout = make_layout(SWIPES)
    d = np.array([dx, dy]) / np.hypot(dx, dy) * 0.1
    tl = timeline(5.0)
    tl.touch(1.0, 0.3, np.array([[0, 0], d]))  # in the pad
    tl.touch(3.0, 0.3, np.array([[0.25, 0.0], [0.25, 0.0] + d]))  # outside: anywhere
    events = run(layout, tl.block())
    assert [(e.region, e.direction) for e in events] == [("pad", name4), (None, name8)]
    assert events[0].extra["distance"] == pytest.approx(0.1, abs=0.005)
    # the pad binding only takes left and right; the anywhere binding takes every swipe
    assert layout.bindings[0].matches(events[0]) == (name4 in ("left", "right"))
    assert layout.bindings[1].matches(events[1])


def test_no_swipe_when_too_short_too_slow_or_curved(make_layout, timeline):
    layout = make_layout(SWIPES)
    tl = timeline(8.0)
    tl.touch(1.0, 0.3, np.array([[0, 0], [0.03, 0]]))  # 3 cm
    tl.touch(2.0, 1.5, np.array([[0, 0], [0.1, 0]]))  # 1.5 s
    arc = np.column_stack([np.linspace(0, 0.1, 30), 0.05 * np.sin(np.linspace(0, np.pi, 30))])
    tl.touch(5.0, 0.4, arc)  # bows 5 cm over 10 cm
    assert run(layout, tl.block()) == []


def _with_drag(block, drag_xy, shear):
    """The block with every touching sample dragging the board by ``drag_xy`` (N) and a
    shear of ``shear``, as the estimator reports a finger's friction."""
    inc = block.in_contact
    block.shear = np.where(inc, shear, 0.0)
    block.drag_x = np.where(inc, drag_xy[0], 0.0)
    block.drag_y = np.where(inc, drag_xy[1], 0.0)
    return block


@pytest.mark.parametrize(
    ("drag", "shear", "fires"),
    [
        ((0.5, 0.0), 0.3, True),  # friction the way the points went: a swipe
        ((0.4, 0.3), 0.3, True),  # 37 degrees off: still its way
        ((0.0, 0.0), 0.0, True),  # no drag measured (not a horizontal board): the points decide
        ((-0.5, 0.0), 0.3, False),  # against the points: a still touch's noise made the "swipe"
        ((0.0, 0.5), 0.3, False),  # across them
        ((0.5, 0.0), 0.1, False),  # its way, but pressed as a tap presses, not slid (desk 92)
    ],
)
def test_a_swipe_by_the_points_must_have_dragged_the_board_its_way(
    make_layout, timeline, drag, shear, fires
):
    # a light quick touch whose points strayed 6 cm (the sweep's swipes fired on taps: shear
    # 0.02-0.19, the drag against or across the points in 10 of 13; simulated swipes 0.61-0.9)
    layout = make_layout(SWIPES)
    tl = timeline(3.0).touch(1.0, 0.1, np.array([[0.0, 0.0], [0.06, 0.0]]))
    block = _with_drag(tl.block(), drag, shear)
    events = run(layout, block)
    assert [e.direction for e in events] == (["right"] if fires else [])


@pytest.mark.parametrize(
    ("duration_s", "fires"),
    [
        (0.05, True),  # 10 cm in 50 ms: 2 m/s, a quick flick
        (0.03, False),  # 3.3 m/s: faster than a finger
        (0.01, False),  # a real stroke's 9 ms fragment whose points jumped 20 cm ($1 strokes)
    ],
)
def test_a_swipe_faster_than_a_finger_is_none(make_layout, timeline, duration_s, fires):
    layout = make_layout(SWIPES)
    tl = timeline(3.0).touch(1.0, duration_s, np.array([[0.0, 0.0], [0.1, 0.0]]), rise_s=0.005)
    events = run(layout, tl.block())
    assert [e.direction for e in events] == (["right"] if fires else [])


SLIDER = """
units: cm
regions:
  dimmer: {rect: [-30, 10, 30, 20], axis: x}
bindings:
  - {gesture: slide, region: dimmer, do: {log: {}}}
"""


def test_slide_value_follows_the_finger_along_the_axis(make_layout, timeline):
    layout = make_layout(SLIDER)
    tl = timeline(4.0).touch(1.0, 2.0, np.array([[-0.15, 0.15], [0.3, 0.15]]))
    events = run(layout, tl.block())
    assert events[0].phase == "begin" and events[-1].phase == "end"
    assert events[0].value == pytest.approx(0.25, abs=0.02)
    assert events[-1].value == pytest.approx(1.0, abs=0.02)
    values = np.array([e.value for e in events])
    assert np.all(np.diff(values) > -0.01)
    updates = [e for e in events if e.phase == "update"]
    assert len(updates) >= 10
    assert np.all(np.diff([e.t for e in updates]) >= 0.05 - 1e-9)
    # the value matches where the finger was at that time
    for e in updates:
        true_x = -0.15 + 0.45 * (e.t - 1.0) / 2.0
        assert e.value == pytest.approx((true_x + 0.3) / 0.6, abs=0.03)


def test_slide_that_starts_outside_the_slider_does_nothing(make_layout, timeline):
    layout = make_layout(SLIDER)
    tl = timeline(3.0).touch(1.0, 1.0, np.array([[-0.1, 0.0], [0.1, 0.15]]))
    assert run(layout, tl.block()) == []


STROKES = """
units: cm
regions:
  pad: {rect: [-30, -20, 0, 20]}
bindings:
  - {gesture: stroke, region: pad, shape: circle, do: {log: {}}}
  - {gesture: stroke, shape: [v, check], do: {log: {}}}
"""


@pytest.mark.parametrize("shape", ["circle", "v", "check", "triangle"])
def test_stroke_shape_recognised_from_a_traced_path(make_layout, timeline, shape):
    layout = make_layout(STROKES)
    rng = np.random.default_rng(3)
    path = hand_drawn(shape, rng, size_m=0.1, wobble=0.01) + [0.1, 0.0]  # outside the pad
    tl = timeline(6.0).touch(1.0, 3.0, path, sigma_m=0.0005)
    events = run(layout, tl.block())
    assert [(e.gesture, e.region, e.shape) for e in events] == [("stroke", None, shape)]
    assert events[0].score >= 0.9
    assert layout.bindings[1].matches(events[0]) == (shape in ("v", "check"))


def test_scribble_is_reported_unrecognised_and_fires_nothing(make_layout, timeline):
    layout = make_layout(STROKES)
    rng = np.random.default_rng(0)
    scribble = np.cumsum(rng.normal(size=(40, 2)), axis=0) * 0.01 + [0.15, 0.0]
    tl = timeline(6.0).touch(1.0, 3.0, scribble, sigma_m=0.0005)
    events = run(layout, tl.block())
    assert len(events) == 1 and events[0].shape is None and events[0].score < 0.9
    assert "nearest" in events[0].extra
    assert not any(b.matches(events[0]) for b in layout.bindings)


def test_a_tap_is_not_a_stroke(make_layout, timeline):
    layout = make_layout(STROKES)
    tl = timeline(3.0).touch(1.0, 0.1, (-0.1, 0.0))
    assert run(layout, tl.block()) == []


TWO_BUTTONS = """
units: cm
regions:
  lamp: {rect: [-8, -2.5, -3, 2.5]}
  fan: {rect: [0, -2.5, 5, 2.5]}
bindings:
  - {gesture: tap, region: lamp, do: log}
  - {gesture: tap, region: fan, do: log}
"""


@pytest.mark.parametrize(("sigma_m", "fired"), [(0.001, ["lamp"]), (0.009, [])])
def test_a_tap_whose_uncertainty_reaches_two_buttons_presses_neither(
    make_layout, timeline, sigma_m, fired
):
    # in the 3 cm gap, 1 cm from the lamp (within its 12 mm snap) and 2 cm from the fan: placed
    # to 1 mm it is the lamp's; placed to 9 mm (each sample, and so the tap) the lamp is only
    # about 40 times likelier than the fan (ODDS asks about 120): a miss, not a guess
    tl = timeline(2.0).touch(1.0, 0.12, (-0.02, 0.0), sigma_m=sigma_m, noise=False)
    events = run(make_layout(TWO_BUTTONS), tl.block())
    assert [e.region for e in events if e.gesture == "tap"] == fired


@pytest.mark.parametrize(("x_m", "sigma_m", "fired"), [
    (-0.035, 0.0175, ["lamp"]),  # inside, 35 mm from the fan: odds e^4.0, ODDS ** INSIDE_SHARE
    (-0.035, 0.03, []),  # inside but more uncertain: e^1.4, the fan is within reach
    (-0.0255, 0.01255, []),  # snapped from the gap 4.5 mm out, 25.5 mm from the fan: the same
])  # fmt: skip
def test_a_point_outside_every_button_needs_more_odds_than_one_inside(
    make_layout, timeline, x_m, sigma_m, fired
):
    # the same odds against the fan (e^4.0) fire a tap inside the lamp, not one the snap
    # brings in from the gap: its place is off by its distance to the lamp at least
    tl = timeline(2.0).touch(1.0, 0.12, (x_m, 0.0), sigma_m=sigma_m, noise=False)
    events = run(make_layout(TWO_BUTTONS), tl.block())
    assert [e.region for e in events if e.gesture == "tap"] == fired


def test_a_tap_is_placed_where_its_samples_settled(make_layout, timeline):
    # a light tap 2 mm inside the lamp's edge whose first 60 % of samples sit 26 mm away in
    # the gap, claiming the σ of the rest (a rounded sensor's zero, a low-pass still rising):
    # the mean of all is 14 mm out, past the snap; the last 30 % are where the finger is
    t0, duration = 1.0, 0.12
    tl = timeline(2.0).touch(t0, duration, (-0.032, 0.0), force_n=2.5, sigma_m=0.008, noise=False)
    early = (tl.t >= t0) & (tl.t < t0 + 0.6 * duration)
    tl.x[early] += 0.026
    events = run(make_layout(TWO_BUTTONS), tl.block())
    assert [e.region for e in events if e.gesture == "tap"] == ["lamp"]
    assert events[0].x == pytest.approx(-0.032, abs=1e-6)


def test_a_tap_well_inside_a_button_is_taken_however_uncertain_within_reason(make_layout, timeline):
    tl = timeline(2.0).touch(1.0, 0.12, (-0.065, 0.0), sigma_m=0.008, noise=False)
    assert [e.region for e in run(make_layout(TWO_BUTTONS), tl.block())] == ["lamp"]


def test_a_touch_is_placed_as_well_as_its_samples_not_their_count(make_layout, timeline):
    from hapticdesk.gestures.touch_tracker import TouchTracker

    layout = make_layout(TWO_BUTTONS)
    tracker = TouchTracker(layout.desk)
    tl = timeline(2.0).touch(1.0, 0.2, (0.0, 0.0), sigma_m=0.002, force_n=8.0)
    touch = None
    for event in tracker.events(tl.block()):
        touch = tracker.add(event) or touch
    assert touch is not None and touch.samples > 100
    assert touch.place_sigma() == pytest.approx(0.002, rel=0.15)  # 2 mm, more on the ramps
    assert touch.best().sigma_m < touch.place_sigma() / 8  # the mean's, as if independent
