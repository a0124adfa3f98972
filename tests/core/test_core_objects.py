"""Objects on the simulated desk: a cup put down joins the zero within a second, a lift
restores the zero at once, and presses right after land where they land without the cup."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from hapticdesk.estimator import ContactEstimator
from hapticdesk.estimator import kernel_slots as slots
from hapticdesk.files.profile_reader import load_profile
from hapticdesk.sim import Scene, simulate
from hapticdesk.sim.actions import Idle, LiftObject, Press, PutObject

CUP = (-0.2, 0.1)
BUTTON = (0.1, -0.1)
PUT_S, LIFT_S = 3.0, 8.0  # the cup goes down (over 0.3 s) and comes up at these times
PRESS_AFTER_PUT_S = PUT_S + 1.5
PRESS_AFTER_LIFT_S = LIFT_S + 5.0


def cup_scene(with_cup: bool, seed: int) -> Scene:
    """Two 15 N presses on the same button, 1.5 s after the cup is put down and 5 s after it
    is lifted; without the cup the same presses (the same human draws) on an empty desk."""
    cup = [PutObject(name="cup", mass_kg=0.3, point=CUP, start_s=PUT_S)] if with_cup else []
    lift = [LiftObject(name="cup", start_s=LIFT_S)] if with_cup else [Idle(duration_s=0.0)]
    steps = [
        *cup,
        Press(point=BUTTON, peak_n=15.0, hold_s=1.0, start_s=PRESS_AFTER_PUT_S),
        *lift,
        Press(point=BUTTON, peak_n=15.0, hold_s=1.0, start_s=PRESS_AFTER_LIFT_S),
    ]
    return Scene(steps, tail_s=1.0, seed=seed)


def press_errors(rec, block, starts: tuple[float, ...]) -> list[float]:
    """The median location error (m) of each press (the 3 s after each start)."""
    t, truth = rec.t, rec.extra
    err = np.hypot(block.x - truth["true_x"], block.y - truth["true_y"])
    errors = []
    for start in starts:
        near = block.located & (t > start) & (t < start + 3.0) & (truth["true_fn"] > 0)
        assert near.sum() > 300
        errors.append(float(np.median(err[near])))
    return errors


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_cup_is_absorbed_within_a_second_and_a_lift_restores_the_zero(seed):
    desk = load_profile("kitamura2017")
    rec = simulate(desk, cup_scene(True, seed))
    empty = simulate(desk, cup_scene(False, seed))
    est = ContactEstimator(desk)
    block = est.push(rec.t, rec.wrench)
    plain = ContactEstimator(desk).push(empty.t, empty.wrench)
    t = rec.t
    kinds = [n.kind for n in est.notices]
    assert kinds == ["tare", "absorbed", "lifted"], est.notices
    # the cup is no touch beyond 1 s after it came down (it takes 0.3 s to put down)
    assert not block.in_contact[(t > PUT_S + 0.3 + 1.0) & (t < PRESS_AFTER_PUT_S)].any()
    assert not block.in_contact[(t > LIFT_S) & (t < PRESS_AFTER_LIFT_S)].any()
    starts = (PRESS_AFTER_PUT_S, PRESS_AFTER_LIFT_S)
    with_cup, without = press_errors(rec, block, starts), press_errors(empty, plain, starts)
    absorbed, lifted = est.notices[1].t - (PUT_S + 0.3), est.notices[2].t - (LIFT_S + 0.3)
    print(
        f"[objects] seed {seed}: absorbed {absorbed:.2f} s after the cup came down, zero "
        f"restored {lifted:.2f} s after it came up; press errors (mm) with the cup "
        f"{np.round(np.array(with_cup) * 1e3, 2)}, without {np.round(np.array(without) * 1e3, 2)}"
    )
    assert max(abs(a - b) for a, b in zip(with_cup, without, strict=True)) < 2e-3


def test_after_the_tare_only_an_objects_verdict_leaves_the_kernel():
    """Issue 29: no window's end is judged in Python once tared (it cost 60–120 µs of a push
    there): the kernel judges the still run, the drift, the yardsticks, the object rule and
    the lift itself, and leaves Python only the cup's absorption and lift, to be told, on
    the very samples where the batch decided them."""
    desk = load_profile("kitamura2017")
    rec = simulate(desk, cup_scene(True, 1))
    batch = ContactEstimator(desk)
    batch.push(rec.t, rec.wrench)
    est = ContactEstimator(desk)
    handled: list[tuple[float, int]] = []
    handle = est._handle

    def noting(events, *args):
        handled.append((est.state.sf[slots.S_WIN_T_END], events))
        handle(events, *args)

    est._handle = noting
    for i in range(len(rec.t)):
        est.push(rec.t[i : i + 1], rec.wrench[i : i + 1])
    tared_t = est.notices[0].t
    zero_events = slots.EV_WINDOW | slots.EV_ABSORBED | slots.EV_LIFTED
    after = [(t, events & zero_events) for t, events in handled if events & zero_events]
    after = [(t, events) for t, events in after if t > tared_t]
    assert [events for _, events in after] == [slots.EV_ABSORBED, slots.EV_LIFTED]
    assert [n.kind for n in est.notices] == [n.kind for n in batch.notices]
    assert [t for t, _ in after] == [n.t for n in batch.notices[1:]]
    np.testing.assert_array_equal(est.zero, batch.zero)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_light_finger_held_still_stays_a_touch(seed):
    # a 4 N press held 3 s: a finger wanders and trembles; it is not taken for an object
    desk = load_profile("kitamura2017")
    scene = Scene([Press(point=BUTTON, peak_n=4.0, hold_s=3.0, start_s=3.0)], seed=seed)
    rec = simulate(desk, scene)
    est = ContactEstimator(desk)
    block = est.push(rec.t, rec.wrench)
    assert [n.kind for n in est.notices] == ["tare"]
    touching = rec.extra["true_fn"] > 3.0
    assert block.in_contact[touching].mean() > 0.99


@pytest.mark.parametrize("desk_name", ["unseen-wide", "unseen-six"])
def test_objects_are_absorbed_on_desks_it_was_not_tuned_on(desk_name, tmp_path):
    """A 1.2 m desk on five turned, upside-down legs reporting the load, and a six-sensor
    desk at 1 kHz: a 1.5 kg and a 3 kg object (at two seeds) join the zero within 1 s of
    being down, the press 1.2 s after lands within 2 mm of the same press on the empty desk,
    and the lift restores the zero within 0.6 s. Before, with the tare's median window spread
    as the one yardstick, the 3 kg object on the wide desk was never absorbed (the press
    0.43 m off). (The tall 500 Hz desk swaying at 4.5 Hz is harder: scripts/objects_eval.py.)"""
    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "scripts"))
    import objects_eval

    desk = objects_eval.desks(tmp_path)[desk_name]
    for seed in (1, 2):
        delays, lifts, worse = objects_eval.objects(desk, seed)
        heavy = [i for i, m in enumerate(objects_eval.MASSES_KG) if m >= 1.5]
        assert all(delays[i] <= 1.0 for i in heavy), (seed, delays)
        assert all(worse[i] <= 2e-3 for i in heavy), (seed, worse)
        assert all(lifts[i] <= 0.6 for i in heavy), (seed, lifts)


@pytest.mark.parametrize("seed", [0, 1])
def test_a_cup_on_a_desk_quieter_than_its_steps_rests_and_is_absorbed(seed):
    """Sensors whose noise stays under their resolution step read the idle desk as still as
    constant: the idle desk's yardsticks are then its steps' (still_objects.STEP_SPREAD_SHARE).
    A 0.3 kg cup rests before a 0.8 s long press is due and is absorbed within a second of
    being down, where without a yardstick it waited for ``settle_s`` (5 s) and the long press
    fired; a finger's press on the same desk is no object."""
    from hapticdesk.sim import SensorParameters

    desk = load_profile("kitamura2017")
    quiet = SensorParameters(noise_amplitude_n=0.2)
    put = PutObject(name="cup", mass_kg=0.3, point=CUP, start_s=PUT_S)
    rec = simulate(desk, Scene([put, Idle(duration_s=3.0)], seed=seed), sensors=quiet)
    est = ContactEstimator(desk)
    block = est.push(rec.t, rec.wrench)
    assert est.state.sf[slots.S_QUIET_SPREAD] < 1e-4  # (the idle readings sat still)
    down = float(block.t[np.argmax(block.in_contact)])
    absorbed = [n.t for n in est.notices if n.kind == "absorbed"]
    assert absorbed and absorbed[0] - down < 1.5
    due = block.in_contact & (block.t >= down + 0.8)
    assert block.resting[due].all()
    press = Press(point=BUTTON, peak_n=15.0, hold_s=1.0, start_s=PUT_S)
    rec = simulate(desk, Scene([press], seed=seed), sensors=quiet)
    est = ContactEstimator(desk)
    est.push(rec.t, rec.wrench)
    assert not [n for n in est.notices if n.kind == "absorbed"]


def test_objects_on_a_noisy_load_cell_desk_hold_no_long_press(tmp_path):
    """A 1.3 m desk on eight 100 kg load cells read by HX711s at 50 Hz
    (``objects_eval.loadcell_desks``): its idle windows spread 0.2 N at the median, past
    ``still_n`` (0.15 N), so before a window with a cup on it was seldom still, the cup
    never rested, and on these four seeds a 1.5 kg one fired a 0.8 s long press four times,
    a 0.5 kg one three.
    Now the still limit is 2.5 times the idle desk's own spread there
    (yardsticks.STILL_NOISE_FACTOR): no object fires, and a finger's 8 N and 15 N long
    presses still do (an object's verdict waits two windows more there: without that the
    8 N finger of seed 1 was taken for an object, still_objects.NOISY_EXTRA_WINDOWS)."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "scripts"))
    import objects_eval

    desk = objects_eval.loadcell_desks()["cells8-50hz-1"]
    delays, fired_by = objects_eval.long_presses(desk, tmp_path, range(1, 5))
    assert not any(fired_by[0.5] + fired_by[1.5]), fired_by
    assert all(np.isfinite(delays[8.0] + delays[15.0])), delays
