"""End to end on the simulated paper desk with the paper's noise: sensor samples → estimator →
gesture engine → events, checked against the simulator's ground truth (issue 4, "What it must
show")."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from hapticdesk.estimator import ContactEstimator, estimate
from hapticdesk.gestures.engine import GestureEngine
from hapticdesk.gestures.event import GestureEvent
from hapticdesk.gestures.layout_reader import load_layout
from hapticdesk.gestures.strokes.shapes import hand_drawn
from hapticdesk.sim import Drag, Idle, LongPress, Press, Ramp, Scene, Stroke, Swipe, Tap, simulate
from hapticdesk.sim.sensors import SensorParameters

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "layouts"
GRID = np.array([(x, y) for y in (0.08, 0.0, -0.08) for x in (-0.08, 0.0, 0.08)])  # b1..b9


def recognise(desk, layout, scene: Scene, seed: int = 0):
    """Simulate, estimate, recognise. Returns (recording, events, true touches (start, end))."""
    rec = simulate(desk, scene, seed=seed)
    contacts = estimate(desk, rec)
    engine = GestureEngine(layout, position_delay_s=ContactEstimator(desk).position_delay_s)
    events = engine.feed(contacts) + engine.flush(float(contacts.t[-1]))
    touching = np.flatnonzero(rec.extra["true_fn"] > 0)
    gaps = np.diff(touching) > 1
    starts = touching[np.concatenate([[True], gaps])]
    ends = touching[np.concatenate([gaps, [True]])]
    return (
        rec,
        events,
        list(zip(rec.t[starts], rec.t[np.minimum(ends + 1, len(rec) - 1)], strict=True)),
    )


def match_taps(events: list[GestureEvent], touches, margin_s: float = 0.5):
    """Pair each true touch with the first unused event between its start and release +
    margin. Returns (event or None per touch, events paired with no touch)."""
    used: set[int] = set()
    paired = []
    for start, release in touches:
        found = next(
            (
                i
                for i, e in enumerate(events)
                if i not in used and start <= e.t <= release + margin_s
            ),
            None,
        )
        if found is not None:
            used.add(found)
        paired.append(None if found is None else events[found])
    return paired, [e for i, e in enumerate(events) if i not in used]


def tap_scene(rng, n: int, peak_n=None) -> tuple[Scene, np.ndarray]:
    """``n`` taps on random buttons, 0.4–0.9 s apart, with a 6 s pause after every 40 (the
    estimator follows the sensors' offset drift while the desk rests)."""
    which = rng.integers(9, size=n)
    # anywhere on the 5 cm button but its outer 1 cm (where a person aims)
    points = GRID[which] + rng.uniform(-0.015, 0.015, size=(n, 2))
    actions: list = []
    for i, (x, y) in enumerate(points):
        if i and i % 40 == 0:
            actions.append(Idle(duration_s=6.0))
        peak = float(rng.uniform(3.5, 8.0)) if peak_n is None else peak_n
        actions.append(
            Tap(point=(float(x), float(y)), peak_n=peak, wait_s=float(rng.uniform(0.4, 0.9)))
        )
    return Scene(actions=actions, seed=int(rng.integers(1 << 30))), which


@pytest.fixture(scope="module")
def buttons():
    return load_layout(EXAMPLES / "buttons.yaml")


def test_taps_on_a_3x3_grid_land_in_the_right_button(paper_desk, buttons):
    rng = np.random.default_rng(2024)
    scene, which = tap_scene(rng, 400)
    rec, events, touches = recognise(paper_desk, buttons, scene)
    assert len(touches) == 400
    paired, spurious = match_taps(events, touches)
    right = sum(
        e is not None and e.region == f"b{w + 1}" for e, w in zip(paired, which, strict=True)
    )
    assert right / 400 >= 0.995, f"{right}/400 in the right button"
    assert spurious == []  # no tap where none was made
    assert {e.gesture for e in events} == {"tap"}
    # latency, no double tap bound: event time against the true release (the first sample
    # after the finger's force is back to 0)
    latency = np.array(
        [e.t - rel for e, (_, rel) in zip(paired, touches, strict=True) if e is not None]
    )
    assert np.percentile(np.abs(latency), 95) <= 0.030


def test_light_3_newton_taps_are_still_recognised(paper_desk, buttons):
    rng = np.random.default_rng(3)
    scene, which = tap_scene(rng, 120, peak_n=3.0)
    rec, events, touches = recognise(paper_desk, buttons, scene)
    paired, spurious = match_taps(events, touches)
    found = [(e, w) for e, w in zip(paired, which, strict=True) if e is not None]
    # the fused estimate places light taps through the fast candidate
    assert len(found) / len(touches) >= 0.98, f"{len(found)}/{len(touches)} recognised"
    assert all(e.region == f"b{w + 1}" for e, w in found)  # and never in the wrong button
    assert spurious == []


def test_long_presses_fire_at_their_tiers_and_on_release(paper_desk, write_layout):
    layout = load_layout(
        write_layout(
            """
            desk: kitamura2017
            units: cm
            regions:
              lamp: {rect: [-25, -15, -15, -5]}
              fan: {rect: [15, -15, 25, -5]}
            bindings:
              - {gesture: long_press, region: lamp, do: log}
              - {gesture: long_press, region: lamp, hold_s: 2, do: log}
              - {gesture: long_press, region: lamp, release: true, do: log}
              - {gesture: tap, region: lamp, do: log}
              - {gesture: long_press, region: fan, do: log}
            """
        )
    )
    scene = Scene(
        actions=[
            LongPress(point=(-0.2, -0.1), hold_s=3.0),
            LongPress(point=(0.2, -0.1), hold_s=1.2),
            # about 0.6 s in all: too long for a tap, too short for a hold
            Press(point=(-0.2, -0.1), peak_n=8, hold_s=0.3, rise_n_per_s=40, release_n_per_s=80),
        ]
    )
    rec, events, touches = recognise(paper_desk, layout, scene)
    got = [(e.gesture, e.region, e.hold_s, e.phase) for e in events]
    assert got == [
        ("long_press", "lamp", 0.8, None),
        ("long_press", "lamp", 2.0, None),
        ("long_press", "lamp", 2.0, "end"),
        ("long_press", "fan", 0.8, None),
        ("long_press", "fan", 0.8, "end"),
    ]
    (s1, r1), (s2, r2), _ = touches
    # tiers count from the estimator's touch-down, a few tens of ms after the true one
    assert 0.8 <= events[0].t - s1 <= 0.9 and 2.0 <= events[1].t - s1 <= 2.1
    assert abs(events[2].t - r1) <= 0.05 and abs(events[4].t - r2) <= 0.05
    assert np.hypot(events[0].x + 0.2, events[0].y + 0.1) < 0.01


def test_press_levels_and_force_from_a_ramp(paper_desk, write_layout):
    layout = load_layout(
        write_layout(
            """
            desk: kitamura2017
            units: cm
            regions:
              knob: {circle: {center: [10, 10], radius: 5}}
              pad: {rect: [-20, 0, -10, 10]}
            bindings:
              - {gesture: press, region: knob, do: log}
              - {gesture: force, region: pad, min_n: 2, max_n: 22, do: log}
            """
        )
    )
    scene = Scene(
        actions=[
            Ramp(point=(0.1, 0.1), from_n=3, to_n=25, duration_s=3.0),
            Press(point=(0.1, 0.1), peak_n=15.0, hold_s=1.0),
            Ramp(point=(-0.15, 0.05), from_n=3, to_n=22, duration_s=2.0),
        ]
    )
    rec, events, touches = recognise(paper_desk, layout, scene)
    presses = [e for e in events if e.gesture == "press"]
    assert [(e.level, e.region) for e in presses] == [
        ("light", "knob"), ("firm", "knob"), ("hard", "knob"), ("light", "knob"), ("firm", "knob")
    ]  # fmt: skip
    # each fired when the true force passed its level (the estimator's force trails it a little)
    true_fn = rec.extra["true_fn"]
    for e, level in zip(presses[:3], (4.0, 10.0, 20.0), strict=True):
        at = np.searchsorted(rec.t, e.t)
        assert level - 1.0 <= true_fn[at] <= level + 3.0
    force = [e for e in events if e.gesture == "force"]
    assert force[0].phase == "begin" and force[-1].phase == "end"
    assert all(e.region == "pad" for e in force)
    values = np.array([e.value for e in force[:-1]])
    rising = values[: int(np.argmax(values)) + 1]
    assert values.max() >= 0.9 and len(rising) >= 10
    assert np.all(np.diff(rising) > -0.03)  # tremor aside, it only grows


def test_swipes_in_four_directions(paper_desk, write_layout):
    layout = load_layout(
        write_layout("desk: kitamura2017\nbindings:\n  - {gesture: swipe, do: log}\n")
    )
    moves = {"right": (0.15, 0), "left": (-0.15, 0), "up": (0, 0.12), "down": (0, -0.12)}
    scene = Scene(
        actions=[
            Swipe(from_point=(-dx / 2, -dy / 2), to_point=(dx / 2, dy / 2))
            for dx, dy in moves.values()
        ]
    )
    rec, events, touches = recognise(paper_desk, layout, scene)
    assert [(e.gesture, e.direction) for e in events] == [("swipe", d) for d in moves]
    paired, spurious = match_taps(events, touches, margin_s=0.1)
    assert None not in paired and spurious == []


def test_swipes_come_out_as_long_as_they_were(paper_desk, write_layout):
    # the low-passed position lags a moving finger by the low-pass's delay: the swipe's end
    # is carried on by it, so lengths are not cut short (they were by a quarter without)
    layout = load_layout(
        write_layout(
            "desk: kitamura2017\nbindings:\n  - {gesture: swipe, directions: 8, do: log}\n"
        )
    )
    moves = [(0.2, 0.0), (-0.2, 0.0), (0.0, 0.16), (0.0, -0.16), (0.16, 0.12)]
    ratios = []
    for seed in range(3):
        scene = Scene(
            actions=[
                Swipe(from_point=(-dx / 2, -dy / 2), to_point=(dx / 2, dy / 2)) for dx, dy in moves
            ]
        )
        _, events, _ = recognise(paper_desk, layout, scene, seed=seed)
        swipes = [e for e in events if e.gesture == "swipe"]
        assert [e.direction for e in swipes] == [
            "right", "left", "up", "down", "up_right"
        ]  # fmt: skip
        ratios += [e.extra["distance"] / math.hypot(*m) for e, m in zip(swipes, moves, strict=True)]
    assert 0.85 < float(np.median(ratios)) < 1.15, ratios


MOVES = {"right": (1, 0), "up": (0, 1), "left": (-1, 0), "down": (0, -1)}


def twelve_cm_swipe(rng, name: str, speeds: tuple[float, float]) -> Swipe:
    """A 12 cm swipe ``name`` across the top's centre, a little to the side, at a speed
    drawn from ``speeds`` (m/s)."""
    v = np.array(MOVES[name], float)
    start = -0.06 * v + rng.uniform(-0.04, 0.04) * v[::-1]
    end = start + 0.12 * v
    return Swipe(from_point=tuple(start), to_point=tuple(end), speed=float(rng.uniform(*speeds)))


def swipe_directions(desk, write_layout, want, speeds, seed: int) -> list[str | None]:
    """``want``'s swipes on ``desk`` with ``swipe`` bound anywhere, 2 s apart: the direction
    each fired (None: none), after checking that none is wrong and nothing else fired."""
    layout = load_layout(
        write_layout(f"desk: {desk.name}\nbindings:\n  - {{gesture: swipe, do: log}}\n"),
        profile=desk,
    )
    rng = np.random.default_rng(seed)
    actions = [a for name in want for a in (twelve_cm_swipe(rng, name, speeds), Idle(2.0))]
    _, events, touches = recognise(desk, layout, Scene(actions=actions, seed=seed), seed=seed)
    paired, spurious = match_taps(events, touches, margin_s=0.3)
    got = [None if e is None else e.direction for e in paired]
    # never a wrong direction or a gesture nobody made
    assert spurious == [] and all(g in (None, w) for g, w in zip(got, want, strict=True)), got
    return got


def test_flicks_are_swipes(any_desk, write_layout):
    """12 cm flicks at 0.75-1.0 m/s: the finger is on the desk for about 0.2 s, and the
    located points lag it by the low-pass's delay. The end fitted over the last 0.2 s (much
    of it the still touch-down) fell short of `min_distance`: 15 of 84 flicks were swipes on
    the paper desk (scripts/swipe_accuracy.py). On desks whose points hardly follow a quick
    finger (eight legs, 4.2 Hz: 12 of 84) the finger's drag along the board says it slid."""
    want = [*MOVES] * 3
    got = swipe_directions(any_desk, write_layout, want, (0.75, 1.0), seed=7)
    assert sum(g == w for g, w in zip(got, want, strict=True)) >= 11, got


def test_swipes_on_a_swaying_desk_never_go_the_wrong_way(octo_desk, write_layout):
    """On the eight-legged 4.2 Hz desk a quick swipe's points can run off with the sway: 19
    of 252 swipes at 0.2-1 m/s were fired in a wrong direction (a wrong command). Friction
    drags the desk the finger's way (Touch.drag): the swipe goes that way, or not at all."""
    swipe_directions(octo_desk, write_layout, [*MOVES] * 6, (0.4, 0.7), seed=2)


def test_a_circle_drawn_quickly_is_no_swipe(paper_desk, write_layout):
    """A quick stroke drags the board every way in turn: no slide one way (the drag's
    straightness: 0.01-0.24 on these), and its points bow too far for a swipe. (Swipes are
    let last 2 s here, so that the duration alone does not rule the strokes out.)"""
    layout = load_layout(
        write_layout(
            "desk: kitamura2017\nbindings:\n  - {gesture: swipe, max_duration_s: 2, do: log}\n"
        )
    )
    angles = np.linspace(0.0, 2 * np.pi, 40)
    circle = tuple((0.05 * float(np.cos(a)), 0.05 * float(np.sin(a))) for a in angles)
    scene = Scene(actions=[Stroke(path=circle, speed=0.6), Idle(duration_s=1.0)] * 4, seed=2)
    _, events, touches = recognise(paper_desk, layout, scene, seed=2)
    assert len(touches) == 4 and [e for e in events if e.gesture == "swipe"] == []


def test_flicks_over_buttons_fire_no_tap_on_a_desk_whose_points_lag_them(octo_desk, write_layout):
    """On the eight-legged 4.2 Hz desk the located points hardly follow a finger at 1 m/s,
    so a flick over the buttons looked like a still tap: 46 of 84 flicks fired one
    (scripts/swipe_accuracy.py --desk examples/desks/eight-legs.yaml). The drag along the
    surface (Touch.dragged) tells them apart; taps there still fire."""
    text = (EXAMPLES / "buttons.yaml").read_text().replace("kitamura2017", octo_desk.name)
    layout = load_layout(write_layout(text), profile=octo_desk)
    rng = np.random.default_rng(11)
    actions: list = []
    for i in range(16):
        x, y = GRID[i % 9] + rng.uniform(-0.01, 0.01, 2)
        actions += [
            twelve_cm_swipe(rng, [*MOVES][i % 4], (0.6, 1.0)),
            Idle(duration_s=1.5),
            Tap(point=(float(x), float(y)), peak_n=float(rng.uniform(3.0, 8.0))),
            Idle(duration_s=1.0),
        ]
    _, events, touches = recognise(octo_desk, layout, Scene(actions=actions, seed=5), seed=5)
    paired, spurious = match_taps([e for e in events if e.gesture == "tap"], touches, 0.3)
    assert spurious == []
    assert [p is not None for p in paired[0::2]] == [False] * 16  # the flicks
    assert sum(p is not None for p in paired[1::2]) >= 14  # the taps


def test_slide_along_the_demo_dimmer(paper_desk):
    layout = load_layout(EXAMPLES / "demo.yaml")
    scene = Scene(
        actions=[
            Drag(path=((-0.25, 0.15), (0.25, 0.15)), speed=0.08),
            Drag(path=((0.15, 0.15), (-0.15, 0.15)), speed=0.08),
        ]
    )
    rec, events, touches = recognise(paper_desk, layout, scene)
    slides = [e for e in events if e.gesture == "slide"]
    assert {e.region for e in slides} == {"dimmer"}
    assert [e.phase for e in slides if e.phase != "update"] == ["begin", "end"] * 2
    first = [e for e in slides if e.t < touches[0][1] + 0.1]
    second = [e for e in slides if e.t > touches[1][0]]
    # value = (x + 0.3) / 0.6 along the dimmer
    assert first[0].value == pytest.approx(0.083, abs=0.05)
    assert first[-1].value == pytest.approx(0.917, abs=0.05)
    assert second[-1].value == pytest.approx(0.25, abs=0.05)
    # every update agrees with where the finger truly was a moment before (the estimator lags)
    tx = rec.extra["true_x"]
    for e in first[1:-1]:
        at = np.searchsorted(rec.t, e.t)
        was = (tx[at - 120 : at + 1] + 0.3) / 0.6  # the last 100 ms
        assert np.nanmin(was) - 0.03 <= e.value <= np.nanmax(was) + 0.03
    assert not [e for e in events if e.gesture != "slide"]


def test_strokes_traced_on_the_desk(paper_desk, write_layout):
    layout = load_layout(
        write_layout("desk: kitamura2017\nbindings:\n  - {gesture: stroke, do: log}\n")
    )
    rng = np.random.default_rng(5)
    shapes = ["circle", "triangle", "v", "check", "zigzag", "star"]
    scene = Scene(
        actions=[
            Stroke(path=tuple(map(tuple, hand_drawn(s, rng, size_m=0.15, wobble=0.02))), speed=0.08)
            for s in shapes
        ]
    )
    rec, events, touches = recognise(paper_desk, layout, scene)
    assert [e.shape for e in events] == shapes


def test_light_quick_taps_make_no_swipe(paper_desk, write_layout):
    # a swipe's end is carried on by the low-pass's delay; on a light tap of 40-80 ms the line
    # under it is the touch-down's scatter, and carried on it made 5-9 cm "swipes" (26 of 600
    # such taps): the measured track must move too
    layout = load_layout(
        write_layout(
            "desk: kitamura2017\nbindings:\n  - {gesture: tap, region: pad, do: log}\n"
            "  - {gesture: swipe, directions: 8, do: log}\n"
            "regions:\n  pad: {rect: [-0.15, -0.12, 0.15, 0.12]}\n"
        )
    )
    rng = np.random.default_rng(4)
    n = 150
    scene = Scene(
        actions=[
            Tap(
                point=(float(x), float(y)),
                peak_n=float(peak),
                duration_s=float(duration),
                wait_s=float(wait),
            )
            for x, y, peak, duration, wait in zip(
                rng.uniform(-0.12, 0.12, n),
                rng.uniform(-0.1, 0.1, n),
                rng.uniform(1.5, 3.0, n),
                rng.uniform(0.04, 0.08, n),
                rng.uniform(0.5, 0.9, n),
                strict=True,
            )
        ]
    )
    _, events, _ = recognise(paper_desk, layout, scene, seed=4)
    taps = [e for e in events if e.gesture == "tap"]
    swipes = [e for e in events if e.gesture == "swipe"]
    assert len(taps) >= 0.6 * n  # (the lightest never reach 2 N: no touch, no tap)
    assert swipes == []


def test_firm_long_presses_fire_on_a_sensor_quieter_than_its_resolution(paper_desk, write_layout):
    # at half the paper's noise each reading is its rounding: a firm press's rise is placed
    # 2-3 cm off with a σ of a few mm, and judged on every pressed sample the still hold looked
    # moved off (39 of 60 fired); it is judged on the samples pressed at least half the peak
    layout = load_layout(
        write_layout(
            "desk: kitamura2017\nunits: cm\nregions:\n  lamp: {rect: [-25, -15, -15, -5]}\n"
            "bindings:\n  - {gesture: long_press, region: lamp, hold_s: 0.8, do: log}\n"
        )
    )
    rng = np.random.default_rng(2)
    n = 20
    scene = Scene(
        actions=[
            LongPress(
                point=(-0.2 + float(dx), -0.1 + float(dy)),
                peak_n=float(peak),
                hold_s=1.5,
                wait_s=float(wait),
            )
            for dx, dy, peak, wait in zip(
                rng.uniform(-0.005, 0.005, n),
                rng.uniform(-0.005, 0.005, n),
                rng.uniform(15.0, 25.0, n),
                rng.uniform(0.8, 1.5, n),
                strict=True,
            )
        ]
    )
    rec = simulate(paper_desk, scene, seed=2, sensors=SensorParameters(noise_amplitude_n=0.2))
    contacts = estimate(paper_desk, rec)
    engine = GestureEngine(layout, position_delay_s=ContactEstimator(paper_desk).position_delay_s)
    events = engine.feed(contacts) + engine.flush(float(contacts.t[-1]))
    tiers = [e for e in events if e.gesture == "long_press" and e.phase is None]
    assert len(tiers) == n and {e.region for e in tiers} == {"lamp"}
    assert [e.phase for e in events if e.phase is not None] == ["end"] * n
