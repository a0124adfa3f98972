"""Objects put down on a button bound to ``long_press`` (issue 15 item 5): the estimator says a
load is *resting* while it is as still as an object and its verdict is pending, and a hold
waits for that verdict. Before, a cup on the button fired the long press every time (0.8 s
hold, before the cup was judged an object)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from hapticdesk.estimator import ContactEstimator
from hapticdesk.estimator.inertia import accelerometer_readings
from hapticdesk.files.profile_reader import load_profile
from hapticdesk.gestures.engine import GestureEngine
from hapticdesk.gestures.layout_reader import load_layout
from hapticdesk.sim import Scene, simulate
from hapticdesk.sim.actions import Idle, LiftObject, LongPress, PutObject

BUTTON = (0.02, -0.01)
LAYOUT = """\
desk: kitamura2017
units: cm
regions:
  b: {rect: [-10, -10, 10, 10]}
bindings:
  - {gesture: long_press, region: b, do: log}
"""


@pytest.fixture(scope="module")
def desk():
    return load_profile("kitamura2017")


@pytest.fixture(scope="module")
def layout(desk, tmp_path_factory):
    path = tmp_path_factory.mktemp("layout") / "button.yaml"
    path.write_text(LAYOUT)
    return load_layout(path, profile=desk)


def _holds(desk, layout, scene: Scene):
    """The long-press tier events of a run, and the estimator's contacts."""
    rec = simulate(desk, scene)
    est = ContactEstimator(desk)
    contacts = est.push(rec.t, rec.wrench, accelerometer_readings(desk, rec.extra))
    engine = GestureEngine(layout, position_delay_s=est.position_delay_s)
    events = engine.feed(contacts) + engine.flush(float(contacts.t[-1]))
    return [e for e in events if e.gesture == "long_press" and e.phase is None], contacts


@pytest.mark.parametrize("mass_kg", [0.3, 1.5])
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_an_object_put_on_a_button_holds_nothing(desk, layout, mass_kg, seed):
    put = PutObject(name="cup", mass_kg=mass_kg, point=BUTTON, start_s=3.0)
    fired, contacts = _holds(desk, layout, Scene([put, Idle(duration_s=3.0)], seed=seed))
    assert fired == []
    assert contacts.resting.any()  # it was resting before it joined the zero
    assert not contacts.in_contact[contacts.t > 3.3 + 1.5].any()


@pytest.mark.parametrize(
    ("desk_name", "seeds"),
    [("unseen-four", (2, 3)), ("unseen-six", (2,)), ("panel-accel", (5,)), ("unseen-wide", (2,))],
)
def test_a_cup_whose_landing_rings_on_holds_nothing(desk_name, seeds, tmp_path):
    """Desks the resting was not tuned on (scripts/objects_eval.py): on these seeds a 0.3 kg
    cup's 0.2 s means strayed 1.05-1.46 times the allowed wander for a window or two while
    its landing rang out. The resting flag dropped on that window and the due long press
    fired; now the flag, once up, holds until the means stray 1.6 times it, and the cup is
    absorbed (at once or after ``settle_s``) with nothing fired. On the wide desk (seed 2) a
    window spread 1.43 times an object's limit as the ring went on, its mean where the cup
    rested, and the flag dropped for it: a light load keeps resting through one such window
    a run (still_objects.OBJECT_SPIKE)."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "scripts"))
    import objects_eval

    desk = objects_eval.desks(tmp_path)[desk_name]
    path = tmp_path / "button.yaml"
    path.write_text(objects_eval.LONG_PRESS_LAYOUT.format(desk=desk.name))
    button = load_layout(path, profile=desk)
    for seed in seeds:
        put = PutObject(name="cup", mass_kg=0.3, point=BUTTON, start_s=3.0)
        fired, contacts = _holds(desk, button, Scene([put, Idle(duration_s=3.0)], seed=seed))
        assert fired == [], (desk_name, seed)
        assert contacts.resting.any()
        assert not contacts.in_contact[-100:].any()  # absorbed in the end


def _finger_holds(desk, layout) -> dict[float, list[int]]:
    """Forty long presses at 8 N and at 2.6 N: the seeds whose press did not fire once, within
    its tier's time (0.25 s late at most for the firm one, 1 s for the light one)."""
    lost: dict[float, list[int]] = {8.0: [], 2.6: []}
    for seed in range(1, 41):
        for force_n, latest_s in ((8.0, 0.25), (2.6, 1.0)):
            press = LongPress(point=BUTTON, peak_n=force_n, hold_s=2.0, start_s=3.0)
            fired, contacts = _holds(desk, layout, Scene([press], tail_s=0.5, seed=seed))
            down = float(contacts.t[np.argmax(contacts.in_contact)])
            if len(fired) != 1 or not 0.8 - 1e-9 <= fired[0].t - down <= 0.8 + latest_s:
                lost[force_n].append(seed)
    return lost


def test_a_finger_still_holds_the_button(desk, layout):
    """Without sway compensation, every long press fires: firm ones at their tier (now and
    then a window later: seed 33), light ones (2.6 N, as still as a cup at times) later by up
    to about a second while the estimator looks. Forty seeds: a finger that wandered a little
    in every window once stayed resting all along (seed 29), its long press never fired."""
    plain = desk.with_estimation(sway_compensation=False)
    assert _finger_holds(plain, layout) == {8.0: [], 2.6: []}


def test_a_finger_still_holds_the_button_on_the_compensated_desk(desk, layout):
    """As shipped (`fused` with the legs as the accelerometer) the compensation takes the
    desk's own ring out of a finger's force, so a light finger looks stiller: 2 of the 40
    2.6 N presses (seeds 17, 23) were taken for an object and did not fire. Every firm one
    fires; the light ones lose at most three."""
    assert desk.estimation.sway_compensation is None  # (auto: on for this `fused` desk)
    lost = _finger_holds(desk, layout)
    assert lost[8.0] == []
    assert len(lost[2.6]) <= 3, lost


def test_resting_is_the_same_streamed_one_sample_at_a_time(desk):
    scene = Scene([PutObject(name="cup", mass_kg=0.3, point=BUTTON, start_s=3.0)], seed=1)
    rec = simulate(desk, scene)
    batch = ContactEstimator(desk).push(rec.t, rec.wrench)
    assert batch.resting.any() and not (batch.resting & ~batch.in_contact).any()
    streamed = ContactEstimator(desk)
    one = [streamed.push(rec.t[i : i + 1], rec.wrench[i : i + 1]).copy() for i in range(len(rec.t))]
    np.testing.assert_array_equal(np.concatenate([b.resting for b in one]), batch.resting)


def test_resting_is_the_same_in_any_blocks(desk):
    """Pushed in random blocks (a cup put down and lifted, a light long press), resting and
    contact are what one push gives."""
    scene = Scene(
        [
            PutObject(name="cup", mass_kg=0.3, point=BUTTON, start_s=3.0),
            LiftObject(name="cup", start_s=5.0),
            LongPress(point=BUTTON, peak_n=2.6, hold_s=2.0, start_s=6.0),
        ],
        tail_s=0.5,
        seed=4,
    )
    rec = simulate(desk, scene)
    batch = ContactEstimator(desk).push(rec.t, rec.wrench)
    assert batch.resting.any()
    rng = np.random.default_rng(0)
    cuts = np.unique(rng.integers(1, len(rec.t), 400))
    est = ContactEstimator(desk)
    bounds = zip([0, *cuts], [*cuts, len(rec.t)], strict=True)
    parts = [est.push(rec.t[a:b], rec.wrench[a:b]).copy() for a, b in bounds]
    np.testing.assert_array_equal(np.concatenate([p.resting for p in parts]), batch.resting)
    np.testing.assert_array_equal(np.concatenate([p.in_contact for p in parts]), batch.in_contact)
