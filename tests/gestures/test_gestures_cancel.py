"""A release nobody made fires nothing: a stream that ends or breaks off (a gap) mid-touch
cancels the touch; continuous gestures end with phase ``cancel`` (issue 10, item 4). And a
long press held on repeats (item 5)."""

from __future__ import annotations

import numpy as np
import pytest

from hapticdesk.estimator.contacts import FLAG_GAP
from hapticdesk.gestures.engine import GestureEngine

EVERY_KIND = """
units: cm
regions:
  lamp: {rect: [-25, -15, -15, -5]}
  knob: {circle: {center: [0, -10], radius: 4}}
  dimmer: {rect: [-30, 10, 30, 20], axis: x}
bindings:
  - {gesture: tap, region: lamp, do: {log: {}}}
  - {gesture: long_press, region: lamp, do: {log: {}}}
  - {gesture: long_press, region: lamp, release: true, do: {log: {}}}
  - {gesture: force, region: knob, do: {log: {}}}
  - {gesture: slide, region: dimmer, do: {log: {}}}
"""


def test_a_tap_cut_off_by_the_end_of_the_stream_fires_no_tap(make_layout, timeline):
    layout = make_layout(EVERY_KIND)
    tl = timeline(1.1).touch(1.0, 0.2, (-0.2, -0.1))  # still down at the last sample
    engine = GestureEngine(layout)
    events = engine.feed(tl.block()) + engine.flush(float(tl.t[-1]))
    assert events == []
    # the same touch released inside the stream is a tap (the test can fail)
    tl = timeline(1.5).touch(1.0, 0.2, (-0.2, -0.1))
    engine = GestureEngine(layout)
    events = engine.feed(tl.block()) + engine.flush(float(tl.t[-1]))
    assert [(e.gesture, e.region) for e in events] == [("tap", "lamp")]


def test_a_tap_before_the_end_still_fires_when_the_next_touch_is_cut_off(make_layout, timeline):
    layout = make_layout(EVERY_KIND)
    tl = timeline(2.05).touch(1.0, 0.1, (-0.2, -0.1)).touch(2.0, 0.2, (-0.2, -0.1))
    engine = GestureEngine(layout)
    events = engine.feed(tl.block()) + engine.flush(float(tl.t[-1]))
    assert [(e.gesture, round(e.t, 3)) for e in events] == [("tap", round(tl.t[tl.t >= 1.1][0], 3))]


def test_held_gestures_cut_off_end_with_cancel_not_end(make_layout, timeline):
    layout = make_layout(EVERY_KIND)
    for path, gesture in (
        ((-0.2, -0.1), "long_press"),
        ((0.0, -0.1), "force"),
        (np.array([[-0.2, 0.15], [0.2, 0.15]]), "slide"),
    ):
        tl = timeline(2.5).touch(1.0, 3.0, path)  # still down when the stream ends
        engine = GestureEngine(layout)
        events = engine.feed(tl.block()) + engine.flush(float(tl.t[-1]))
        assert {e.gesture for e in events} == {gesture}
        assert events[-1].phase == "cancel", gesture
        assert events[-1].t == pytest.approx(tl.t[-1])
        assert all(e.phase != "end" for e in events)
        # a cancel triggers no binding that waits for the release
        assert not any(b.matches(events[-1]) for b in layout.bindings if b.options.get("release"))
    assert events[-1].action_name == "dimmer_slide_cancel"


def test_a_gap_in_the_stream_cancels_the_touch_instead_of_releasing_it(make_layout, timeline):
    layout = make_layout(EVERY_KIND)
    tl = timeline(3.0).touch(1.0, 1.5, (-0.2, -0.1))
    block = tl.block()
    gap = int(np.searchsorted(block.t, 1.1))  # 0.1 s into the touch: a tap so far
    block.flags[gap] |= FLAG_GAP
    block.in_contact[gap : gap + 600] = False  # the estimator restarts: no contact a while
    block.located[gap : gap + 600] = False
    engine = GestureEngine(layout)
    events = engine.feed(block) + engine.flush(float(block.t[-1]))
    assert [e.gesture for e in events if e.gesture == "tap"] == []
    # without the gap flag the same samples are a tap then a new touch
    block.flags[gap] = 0
    engine = GestureEngine(layout)
    events = engine.feed(block) + engine.flush(float(block.t[-1]))
    assert [e.gesture for e in events if e.gesture == "tap"] == ["tap"]


def test_the_rest_of_a_tap_after_a_gap_is_no_tap(make_layout, timeline):
    """A tap cut by a gap: down before it, up after it. The contact the stream resumes with
    began unseen, so its short rest fires nothing (a serial board's lost lines, issue 28)."""
    layout = make_layout(EVERY_KIND)
    tl = timeline(3.0).touch(1.0, 0.15, (-0.2, -0.1))
    block = tl.block()
    gap = int(np.searchsorted(block.t, 1.05))
    block.flags[gap] |= FLAG_GAP
    engine = GestureEngine(layout)
    assert engine.feed(block) + engine.flush(float(block.t[-1])) == []
    # a touch that comes after the gap, the finger up at its first sample, is a tap
    block.in_contact[gap : gap + 5] = False
    engine = GestureEngine(layout)
    events = engine.feed(block) + engine.flush(float(block.t[-1]))
    assert [e.gesture for e in events] == ["tap"]


def test_gap_handling_does_not_depend_on_how_the_stream_is_split(make_layout, timeline):
    layout = make_layout(EVERY_KIND)
    tl = timeline(4.0).touch(1.0, 1.5, np.array([[-0.2, 0.15], [0.2, 0.15]]))
    tl.touch(3.0, 0.1, (-0.2, -0.1))
    block = tl.block()
    block.flags[int(np.searchsorted(block.t, 1.7))] |= FLAG_GAP
    whole = GestureEngine(layout)
    expected = whole.feed(block) + whole.flush(float(block.t[-1]))
    # the slide before the gap is cancelled; the finger still down after it starts a new one
    phases = [e.phase for e in expected if e.gesture == "slide"]
    assert phases.count("cancel") == 1 and phases[-1] == "end"
    split = GestureEngine(layout)
    got = []
    for a, b in ((0, 1000), (1000, 2041), (2041, 2042), (2042, len(block))):
        got += split.feed(block.take(slice(a, b)))
    got += split.flush(float(block.t[-1]))
    assert got == expected


REPEAT = """
units: cm
regions:
  dim: {rect: [-25, -15, -15, -5]}
bindings:
  - {gesture: long_press, region: dim, hold_s: 0.5, repeat: true, interval_s: 0.2,
     do: {log: {}}}
  - {gesture: long_press, region: dim, hold_s: 0.5, do: {log: {}}}
  - {gesture: long_press, region: dim, release: true, hold_s: 0.5, do: {log: {}}}
"""


def test_long_press_repeats_every_interval_while_held(make_layout, timeline):
    layout = make_layout(REPEAT)
    tl = timeline(3.0).touch(1.0, 1.25, (-0.2, -0.1))  # held 1.25 s: tier at 0.5 s, 3 repeats
    engine = GestureEngine(layout)
    events = engine.feed(tl.block()) + engine.flush(float(tl.t[-1]))
    got = [(e.phase, round(e.t, 2)) for e in events]
    assert got == [(None, 1.5), ("repeat", 1.7), ("repeat", 1.9), ("repeat", 2.1), ("end", 2.25)]
    fired = [[b.index for b in layout.bindings if b.matches(e)] for e in events]
    assert fired == [[0, 1], [0], [0], [0], [2]]
    assert events[1].action_name == "dim_long_press_repeat"


def test_repeats_stop_with_cancel_when_the_finger_slides_away(make_layout, timeline):
    layout = make_layout(REPEAT)
    path = lambda u: np.column_stack(  # noqa: E731 - still for 0.8 s of 1.5 s, then slides 5 cm
        [-0.2 + 0.05 * np.clip((u - 0.55) / 0.45, 0, 1), np.full_like(u, -0.1)]
    )
    tl = timeline(3.0).touch(1.0, 1.5, path)
    engine = GestureEngine(layout)
    events = engine.feed(tl.block()) + engine.flush(float(tl.t[-1]))
    phases = [e.phase for e in events]
    assert phases[0] is None and phases[-1] == "cancel"
    assert "end" not in phases
    assert 1 <= phases.count("repeat") <= 2  # 1.7 s and maybe 1.9 s, before it left


LEAVING = """
units: cm
regions:
  dimmer: {rect: [-30, 10, 30, 20], axis: x}
  knob: {circle: {center: [0, -10], radius: 4}}
bindings:
  - {gesture: slide, region: dimmer, leave: cancel, do: {log: {}}}
  - {gesture: force, region: knob, leave: cancel, do: {log: {}}}
"""


def test_a_slide_that_leaves_its_region_ends_with_cancel_when_asked(make_layout, timeline):
    # along the dimmer from x = -20 to 0 cm, then off it sideways to y = 30 cm
    path = np.array([[-0.2, 0.15], [0.0, 0.15], [0.0, 0.30]])
    tl = timeline(3.0).touch(1.0, 1.5, path)
    engine = GestureEngine(make_layout(LEAVING))
    events = engine.feed(tl.block()) + engine.flush(float(tl.t[-1]))
    phases = [e.phase for e in events]
    assert phases[0] == "begin" and phases[-1] == "cancel" and "end" not in phases
    cancel = events[-1]
    assert cancel.value == pytest.approx(0.5, abs=0.03)  # the last value on the dimmer
    assert 0.20 <= cancel.y <= 0.21  # where it was last on the region (or just off it)
    # the finger passes 1 cm beyond the edge (y = 21 cm) 0.26 m of 0.35 m into the 1.5 s
    # touch, at 2.114 s; the smoothed track (30 ms) follows a little later
    assert 2.114 < cancel.t < 2.2
    # by default (clip) the same slide goes on to the release
    default = make_layout(LEAVING.replace(", leave: cancel", ""))
    engine = GestureEngine(default)
    events = engine.feed(tl.block()) + engine.flush(float(tl.t[-1]))
    assert [e.phase for e in events][-1] == "end" and "cancel" not in [e.phase for e in events]


def test_a_force_that_slides_off_its_knob_ends_with_cancel_when_asked(make_layout, timeline):
    path = np.array([[0.0, -0.1], [0.0, -0.1], [0.1, -0.1]])  # still, then 10 cm away
    tl = timeline(3.0).touch(1.0, 1.5, path)
    engine = GestureEngine(make_layout(LEAVING))
    events = engine.feed(tl.block()) + engine.flush(float(tl.t[-1]))
    assert [e.gesture for e in events] == ["force"] * len(events)
    phases = [e.phase for e in events]
    assert phases[0] == "begin" and phases[-1] == "cancel" and "end" not in phases
    assert phases.count("cancel") == 1


def test_leave_must_be_clip_or_cancel(make_layout):
    from hapticdesk.errors import ConfigError

    with pytest.raises(ConfigError, match="`leave` .* must be one of clip, cancel, found 'away'"):
        make_layout(LEAVING.replace("leave: cancel", "leave: away", 1))


def test_home_assistant_is_told_of_the_repeats_of_a_long_press(make_layout):
    from hapticdesk.plugins.mqtt.discovery import device_triggers

    triggers = device_triggers(
        make_layout(REPEAT).bindings,
        device={"identifiers": ["d"]},
        origin={"name": "hapticdesk"},
        event_topic="e",
        node="study",
    )
    announced = {t.config["payload"]: t.config["type"] for t in triggers}
    assert announced == {
        "dim_long_press": "button_long_press",
        "dim_long_press_repeat": "button_long_press_repeat",  # what the repeats send
        "dim_long_press_end": "button_long_release",
    }


def _firm_press(timeline, path, force_n: float = 20.0, ease_to_n: float | None = None):
    """A 20 N press held 1.5 s whose points in the first 40 ms of its 0.1 s rise (2-9 N) land
    2.5 cm off with a σ of 2 mm: what a sensor quieter than its resolution step gives (it
    errs as 1/force, and by more than its σ says)."""

    def rise(tau: np.ndarray) -> np.ndarray:
        force = np.minimum(force_n, 2.0 + (force_n - 2.0) * tau / 0.1)
        if ease_to_n is not None:  # eased off as it slides (from 0.8 s on)
            force = force - (force_n - ease_to_n) * np.clip((tau - 0.8) / 0.2, 0, 1)
        return force

    tl = timeline(3.0).touch(1.0, 1.5, path, force_n=force_n, force_profile=rise, noise=False)
    during_rise = (tl.t >= 1.0) & (tl.t < 1.04)
    tl.x[during_rise] += 0.025
    tl.sigma[during_rise] = 0.002
    return tl


def test_a_firm_hold_is_not_cancelled_by_its_own_rise(make_layout, timeline):
    # judged on every pressed sample, the rise's points (2.5 cm off, at 2-9 N) made the still
    # 20 N hold look moved off: no long press (21 of 60 on the paper desk at half its noise)
    tl = _firm_press(timeline, (-0.2, -0.1))
    engine = GestureEngine(make_layout(REPEAT))
    events = engine.feed(tl.block()) + engine.flush(float(tl.t[-1]))
    assert [e.phase for e in events][0] is None and events[-1].phase == "end"


@pytest.mark.parametrize("ease_to_n", [None, 6.0], ids=["at full force", "easing off"])
def test_a_firm_hold_that_slides_away_is_still_cancelled(make_layout, timeline, ease_to_n):
    path = lambda u: np.column_stack(  # noqa: E731 - still for 0.8 s of 1.5 s, then slides 5 cm
        [-0.2 + 0.05 * np.clip((u - 0.55) / 0.45, 0, 1), np.full_like(u, -0.1)]
    )
    tl = _firm_press(timeline, path, ease_to_n=ease_to_n)
    engine = GestureEngine(make_layout(REPEAT))
    events = engine.feed(tl.block()) + engine.flush(float(tl.t[-1]))
    phases = [e.phase for e in events]
    assert phases[0] is None and phases[-1] == "cancel" and "end" not in phases


HELD = """
units: cm
regions:
  lamp: {rect: [-25, -15, -15, -5]}
bindings:
  - {gesture: press, region: lamp, do: {log: {}}}
  - {gesture: long_press, region: lamp, hold_s: 0.8, do: {log: {}}}
"""


@pytest.mark.parametrize("gap_at", [0.5, 1.5])
def test_a_press_held_across_a_gap_fires_its_levels_and_its_long_press_once(
    make_layout, timeline, gap_at
):
    """A firm press held 3 s with a gap in the middle (lost lines, or a spell of saturated
    samples the estimator skips): the touch after the gap began unseen. Before, its first
    sample fired every press level it was above again and its hold fired the long press a
    second time 0.8 s later (found on a desk leaning 500 N on sensors rated 300 N)."""
    layout = make_layout(HELD)
    block = timeline(5.0).touch(1.0, 3.0, (-0.2, -0.1), force_n=30.0).block()
    gap = int(np.searchsorted(block.t, 1.0 + gap_at))
    engine = GestureEngine(layout)
    clean = engine.feed(block) + engine.flush(float(block.t[-1]))
    block.flags[gap] |= FLAG_GAP
    engine = GestureEngine(layout)
    events = engine.feed(block) + engine.flush(float(block.t[-1]))
    levels = [e.level for e in clean if e.gesture == "press"]
    assert len(levels) >= 2  # light and firm, on the way up
    assert [e.level for e in events if e.gesture == "press"] == levels
    holds = [(e.phase, e.t) for e in events if e.gesture == "long_press"]
    if gap_at < 0.8:  # cut before its tier: held, but how long is not seen
        assert holds == []
    else:  # fired once, then cancelled at the gap: its release was not seen
        assert [p for p, _ in holds] == [None, "cancel"]


def test_a_level_the_force_rises_past_after_a_gap_still_fires(make_layout, timeline):
    layout = make_layout(HELD)
    tl = timeline(4.0).touch(1.0, 2.0, (-0.2, -0.1), force_n=30.0, rise_s=0.5)
    block = tl.block()
    gap = int(np.searchsorted(block.t, 1.05))  # early in the rise: below the firm level
    assert block.force_n[gap] < 8.0
    block.flags[gap] |= FLAG_GAP
    engine = GestureEngine(layout)
    events = engine.feed(block) + engine.flush(float(block.t[-1]))
    assert "firm" in [e.level for e in events if e.gesture == "press"]
