"""Two-finger taps end to end on the simulated paper desk: a finger rests on a button, a second
one taps beside it; plain taps on the same button stay taps."""

from __future__ import annotations

import numpy as np
import pytest

from hapticdesk.estimator import ContactEstimator
from hapticdesk.gestures.engine import GestureEngine
from hapticdesk.gestures.layout_reader import load_layout
from hapticdesk.sim import Press, Scene, Tap, simulate
from hapticdesk.sim.actions import Step

LAYOUT = """
desk: kitamura2017
units: cm
regions:
  lamp: {rect: [-30, -20, -10, 0]}
  fan: {rect: [10, -20, 30, 0]}
bindings:
  - {gesture: two_finger_tap, region: lamp, do: log}
  - {gesture: tap, region: lamp, do: log}
  - {gesture: tap, region: fan, do: log}
"""
SPACING_S = 2.5


def _scene(rng: np.random.Generator, n_two: int, n_single: int):
    """Two-finger taps on the lamp (the first finger held 0.3–0.5 s at 6–10 N, the second a
    light tap 8–20 cm away, beyond MIN_APART_M, 0.25–0.4 s after it) and plain taps on both
    buttons, shuffled."""
    kinds = rng.permutation(["two"] * n_two + ["lamp"] * n_single + ["fan"] * n_single)
    steps: list[Step] = []
    truth = []
    for i, kind in enumerate(kinds):
        start = 2.5 + i * SPACING_S
        if kind == "two":
            p1 = (float(rng.uniform(-0.27, -0.13)), float(rng.uniform(-0.17, -0.03)))
            while True:
                p2 = (float(rng.uniform(-0.33, 0.33)), float(rng.uniform(-0.22, 0.22)))
                if 0.08 <= np.hypot(p2[0] - p1[0], p2[1] - p1[1]) <= 0.2:
                    break
            peak = float(rng.uniform(6, 10))
            steps += [
                Press(point=p1, peak_n=peak, hold_s=float(rng.uniform(0.3, 0.5)),
                      rise_n_per_s=40, release_n_per_s=80, start_s=start),
                Tap(point=p2, start_s=start + float(rng.uniform(0.25, 0.4))),
            ]  # fmt: skip
            truth.append(("two", start, p1, p2))
        else:
            x0 = -0.2 if kind == "lamp" else 0.2
            p = (x0 + float(rng.uniform(-0.07, 0.07)), float(rng.uniform(-0.17, -0.03)))
            steps.append(Tap(point=p, start_s=start))
            truth.append((kind, start, p, None))
    return Scene(steps, seed=int(rng.integers(1 << 30)), tail_s=1.5), truth


def _recognise(desk, layout, scene: Scene):
    rec = simulate(desk, scene)
    engine = GestureEngine(layout)
    estimator = ContactEstimator(desk)
    estimator.use_second_finger(engine.needs_second_finger)  # as the runtime does
    engine = GestureEngine(layout, position_delay_s=estimator.position_delay_s)
    contacts = estimator.push(rec.t, rec.wrench)
    return engine.feed(contacts) + engine.flush(float(contacts.t[-1]))


@pytest.fixture(scope="module")
def outcome(paper_desk, tmp_path_factory):
    path = tmp_path_factory.mktemp("two") / "layout.yaml"
    path.write_text(LAYOUT, encoding="utf-8")
    layout = load_layout(path)
    scene, truth = _scene(np.random.default_rng(3), n_two=16, n_single=8)
    return _recognise(paper_desk, layout, scene), truth


def test_a_layout_binding_it_turns_the_second_finger_on(paper_desk, write_layout):
    two = load_layout(write_layout(LAYOUT))
    plain = load_layout(write_layout(LAYOUT.replace("two_finger_tap", "double_tap")))
    assert GestureEngine(two).needs_second_finger
    assert not GestureEngine(plain).needs_second_finger
    assert paper_desk.estimation.second_finger is False


def test_two_finger_taps_fire_once_and_plain_taps_stay_taps(outcome):
    events, truth = outcome
    right = 0
    errors = []
    for kind, start, p, p2 in truth:
        got = [e for e in events if start <= e.t < start + SPACING_S]
        names = [(e.gesture, e.region) for e in got]
        if kind == "two":
            if names == [("two_finger_tap", "lamp")]:
                right += 1
                e = got[0]
                assert np.hypot(e.x - p[0], e.y - p[1]) < 0.015  # at the first finger
                if "x2" in e.extra:
                    errors.append(np.hypot(e.extra["x2"] - p2[0], e.extra["y2"] - p2[1]))
            else:
                assert ("tap", "fan") not in names
        else:
            assert names == [("tap", kind)], (kind, names)  # never a two-finger tap
    n_two = sum(k == "two" for k, *_ in truth)
    print(
        f"[two_finger_tap] {right}/{n_two} two-finger taps; second finger "
        f"placed in {len(errors)}, median {1e3 * np.median(errors):.0f} mm off"
    )
    assert right >= 0.8 * n_two
    assert len(errors) >= right // 2 and np.median(errors) < 0.03
