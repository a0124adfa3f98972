"""One gesture per touch: each pair of gestures that can see one touch, and check's order."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hapticdesk.cli import main
from hapticdesk.estimator.contacts import ContactBlock
from hapticdesk.files.profile_reader import profile_from_mapping
from hapticdesk.files.yamlfile import load_marked_yaml
from hapticdesk.gestures.arbitration import ORDER, describe
from hapticdesk.gestures.engine import GestureEngine
from hapticdesk.gestures.layout_reader import load_layout

#: a tap may move 3 cm here and a swipe be 4 cm long: a quick 5 cm flick is both
TAP_AND_SWIPE = """
units: cm
regions:
  pad: {rect: [-20, -20, 20, 20]}
settings:
  tap: {max_move: 3}
  swipe: {min_distance: 4}
bindings:
  - {gesture: tap, region: pad, do: log}
  - {gesture: swipe, region: pad, do: log}
"""
FLICK = np.array([[-0.025, 0.0], [0.025, 0.0]])  # 5 cm to the right


def run(layout, block, position_delay_s=0.0):
    engine = GestureEngine(layout, position_delay_s=position_delay_s)
    return engine.feed(block) + engine.flush(float(block.t[-1]))


def test_a_touch_that_is_both_a_tap_and_a_swipe_is_the_swipe(make_layout, timeline):
    block = timeline(2.0).touch(1.0, 0.15, FLICK).block()
    # each alone takes it
    tap_only = make_layout(TAP_AND_SWIPE.replace("  - {gesture: swipe, region: pad, do: log}", ""))
    swipe_only = make_layout(TAP_AND_SWIPE.replace("  - {gesture: tap, region: pad, do: log}", ""))
    assert [e.gesture for e in run(tap_only, block)] == ["tap"]
    assert [(e.gesture, e.direction) for e in run(swipe_only, block)] == [("swipe", "right")]
    # both bound: the swipe, the more specific, excludes the tap
    events = run(make_layout(TAP_AND_SWIPE), block)
    assert [(e.gesture, e.direction) for e in events] == [("swipe", "right")]


def test_a_swipe_nobody_bound_leaves_the_touch_to_the_tap(make_layout, timeline):
    # the swipe is recognised, but its one binding wants `up`: it claims nothing
    up_only = "{gesture: swipe, region: pad, direction: up,"
    layout = make_layout(TAP_AND_SWIPE.replace("{gesture: swipe, region: pad,", up_only))
    events = run(layout, timeline(2.0).touch(1.0, 0.15, FLICK).block())
    assert [e.gesture for e in events] == ["tap"]


def test_a_first_tap_that_was_a_swipe_waits_for_no_double(make_layout, timeline):
    layout = make_layout(TAP_AND_SWIPE + "  - {gesture: double_tap, region: pad, do: log}\n")
    block = timeline(3.0).touch(1.0, 0.15, FLICK).touch(1.3, 0.1, (0.0, 0.0)).block()
    events = run(layout, block)
    # the flick is a swipe only; the still touch after it is a tap on its own (it waited for
    # a second one that never came), not the second half of a double tap
    assert [e.gesture for e in events] == ["swipe", "tap"]
    assert events[1].t > 1.4 + 0.29  # it waited the double tap's interval


def test_a_tap_waiting_for_its_double_is_single_when_the_next_touch_is_a_swipe(
    make_layout, timeline
):
    layout = make_layout(TAP_AND_SWIPE + "  - {gesture: double_tap, region: pad, do: log}\n")
    block = timeline(3.0).touch(1.0, 0.1, (0.0, 0.0)).touch(1.25, 0.15, FLICK).block()
    events = run(layout, block)
    assert [e.gesture for e in events] == ["tap", "swipe"]
    assert events[0].t == events[1].t  # decided at the swipe's release, reported first
    assert abs(events[0].x) < 0.005  # the first touch's place


def test_a_double_tap_replaces_its_two_taps(make_layout, timeline):
    layout = make_layout(TAP_AND_SWIPE + "  - {gesture: double_tap, region: pad, do: log}\n")
    block = timeline(3.0).touch(1.0, 0.1, (0.0, 0.0)).touch(1.25, 0.1, (0.0, 0.0)).block()
    assert [e.gesture for e in run(layout, block)] == ["double_tap"]


STROKE_AND_SWIPE = """
units: cm
bindings:
  - {gesture: swipe, do: log}
  - {gesture: stroke, shape: [line], do: log}
"""


def test_a_stroke_excludes_a_swipe_where_both_are_bound(make_layout, timeline):
    block = timeline(2.0).touch(0.5, 0.3, np.array([[0.0, 0.0], [0.12, 0.0]])).block()
    events = run(make_layout(STROKE_AND_SWIPE), block)
    assert [(e.gesture, e.shape) for e in events] == [("stroke", "line")]
    # where no binding wants that shape, the stroke claims nothing: the swipe fires, and the
    # unbound stroke is not reported beside it
    circles = make_layout(STROKE_AND_SWIPE.replace("[line]", "[circle]"))
    assert [(e.gesture, e.direction) for e in run(circles, block)] == [("swipe", "right")]


HOLD_AND_TAP = """
units: cm
regions:
  lamp: {rect: [-5, -5, 5, 5]}
bindings:
  - {gesture: tap, region: lamp, do: log}
  - {gesture: long_press, region: lamp, hold_s: 0.3, do: log}
"""


def test_a_long_press_excludes_the_tap(make_layout, timeline):
    block = timeline(2.0).touch(0.5, 0.4, (0.0, 0.0)).block()  # 0.4 s: a tap's length too
    tap_only = make_layout(HOLD_AND_TAP.split("  - {gesture: long")[0])
    assert [e.gesture for e in run(tap_only, block)] == ["tap"]
    events = run(make_layout(HOLD_AND_TAP), block)
    assert [(e.gesture, e.phase) for e in events] == [("long_press", None), ("long_press", "end")]
    # a long press bound to its release holds the touch from its tier on as well
    released = make_layout(HOLD_AND_TAP.replace("hold_s: 0.3,", "hold_s: 0.3, release: true,"))
    assert [(e.gesture, e.phase) for e in run(released, block)] == [
        ("long_press", None),
        ("long_press", "end"),
    ]
    # shorter than the tier: a tap
    short = timeline(2.0).touch(0.5, 0.15, (0.0, 0.0)).block()
    assert [e.gesture for e in run(make_layout(HOLD_AND_TAP), short)] == ["tap"]


def test_a_long_press_excludes_a_stroke_drawn_after_it(make_layout, timeline):
    layout = make_layout(
        STROKE_AND_SWIPE
        + "  - {gesture: long_press, region: spot, hold_s: 0.3, do: log}\n"
        + "regions:\n  spot: {rect: [-5, -5, 5, 5]}\n"
    )
    line = np.column_stack([np.linspace(0.0, 0.12, 40), np.zeros(40)])
    still_then_line = np.vstack([np.zeros((60, 2)), line])  # 0.7 s still, then 12 cm
    block = timeline(3.0).touch(0.5, 1.2, still_then_line).block()
    assert {e.gesture for e in run(layout, block)} == {"long_press"}


def test_the_order_is_the_engines_calling_order(make_layout):
    layout = make_layout(
        TAP_AND_SWIPE
        + "  - {gesture: double_tap, region: pad, do: log}\n"
        + "  - {gesture: stroke, do: log}\n"
        + "  - {gesture: long_press, region: pad, do: log}\n"
        + "  - {gesture: press, region: pad, do: log}\n"
    )
    engine = GestureEngine(layout)
    ranks = [
        min((ORDER.index(g) for g in type(r).gestures if g in ORDER), default=len(ORDER))
        for r in engine._active
    ]
    assert ranks == [0, 1, 2, 3, len(ORDER)]  # stroke, swipe, long press, taps; press beside


def test_check_prints_the_order_for_a_layout(make_layout, capsys, write_layout):
    layout = make_layout(
        TAP_AND_SWIPE
        + "  - {gesture: double_tap, region: pad, do: log}\n"
        + "  - {gesture: stroke, shape: [circle], do: log}\n"
    )
    lines = describe(layout)
    assert lines[1] == "  1. stroke (anywhere): asked first"
    assert lines[2] == "  2. swipe (pad): waits for stroke to fail"
    assert lines[3] == "  3. double_tap (pad): waits for stroke, swipe to fail"
    assert lines[4].startswith("  4. tap (pad): waits for stroke, swipe, double_tap to fail;")
    assert main(["check", str(layout.path)]) == 0
    out = capsys.readouterr().out
    assert "\n".join(lines) in out


DATA = Path(__file__).resolve().parent / "data"
BUTTONS = Path(__file__).resolve().parents[2] / "examples" / "layouts" / "buttons.yaml"


@pytest.mark.parametrize(("desk", "button"), [(74, "b3"), (92, "b5")])
def test_the_sweeps_taps_that_also_swiped_fire_one_gesture(tmp_path, desk, button):
    """Two of the 3 touches in 36,000 of the 120-desk sweep (scripts/desk_sweep.py --seed 1,
    desks 74 and 92, 250 taps at seeds 1741 and 1921) that fired a tap and a swipe: the
    estimator's contacts around them, cut from that run (t ± 0.5 s), on the sweep's layout
    (buttons.yaml, a 0.8 s long press on every button, swipes anywhere). Both were taps;
    arbitrated, the swipe took them (left, up) until a swipe by the points needed the board
    dragged as a slide drags it (swipe.DIRECTION_DRAG): they pressed it, so the tap."""
    data = np.load(DATA / f"sweep_tap_and_swipe_{desk}.npz")
    profile_path = tmp_path / f"sweep-1-{desk}.yaml"
    profile_path.write_text(str(data["profile"]))
    desk_profile = profile_from_mapping(load_marked_yaml(profile_path), profile_path)
    fields = {k: data[k] for k in data.files if k in ContactBlock.__dataclass_fields__}
    block = ContactBlock(**fields)
    delay = float(data["position_delay_s"])  # ContactEstimator.position_delay_s of the desk
    text = BUTTONS.read_text()
    taps_only = tmp_path / "buttons.yaml"
    taps_only.write_text(text)
    swipes_too = tmp_path / "full.yaml"
    swipes_too.write_text(
        text
        + "".join(
            f"  - {{gesture: long_press, region: b{k}, hold_s: 0.8, do: log}}\n"
            for k in range(1, 10)
        )
        + "  - {gesture: swipe, direction: [right, up, left, down], do: log}\n"
    )
    alone = run(load_layout(taps_only, profile=desk_profile), block, delay)
    assert [(e.gesture, e.region) for e in alone] == [("tap", button)]  # the tap was seen
    events = run(load_layout(swipes_too, profile=desk_profile), block, delay)
    assert [(e.gesture, e.region) for e in events] == [("tap", button)]  # one gesture
