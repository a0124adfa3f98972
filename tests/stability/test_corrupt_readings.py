"""A corrupt reading: one sample of one channel far off, or a few in a row, then back (an
HX711's odd garbage word, a bit error on a serial line). It made a tap nobody made (+50 N on
one channel of the idle paper desk: a press, then a tap). Now a reading that jumps from a
calm wrench is held while it stays away, up to settings.JUMP_HOLD_S (3 samples at 1.2 kHz,
1 at 80 Hz); the next is taken whatever it is, so a real change lands that late."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from hapticdesk.estimator import ContactEstimator, estimate
from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.profile_reader import load_profile
from hapticdesk.files.recording import Recording
from hapticdesk.gestures.layout_reader import load_layout
from hapticdesk.sim import Press, Scene, Tap, simulate

from .test_stability import SWIPES_AND_HOLDS, _pushed_in, _tap_hold_tap, finite, gestures_of

PROFILES = Path(__file__).resolve().parents[2] / "profiles"
WANT = [("tap", None), ("long_press", None), ("long_press", "end"), ("tap", None)]


def corrupted(rec: Recording, at: list[int], channel: int, by: float) -> Recording:
    """``rec`` with one channel's reading off by ``by`` at each sample of ``at``."""
    wrench = rec.wrench.copy()
    wrench.reshape(len(wrench), -1)[at, channel] += by
    return replace(rec, wrench=wrench)


def gestures(desk: DeskProfile, contacts, tmp_path) -> list[tuple[str, str | None, float]]:
    (tmp_path / "layout.yaml").write_text(SWIPES_AND_HOLDS.replace("kitamura2017", desk.name))
    layout = load_layout(tmp_path / "layout.yaml")
    delay = ContactEstimator(desk).position_delay_s
    return [(e.gesture, e.phase, e.t) for e in gestures_of(layout, contacts, delay)]


@pytest.mark.parametrize("by", [50.0, 100.0, -100.0, 400.0])
def test_a_corrupt_reading_makes_no_gesture(paper_desk, tmp_path, by):
    rec = _tap_hold_tap(paper_desk)
    fs = paper_desk.sample_rate_hz
    clean = estimate(paper_desk, rec)
    want = gestures(paper_desk, clean, tmp_path)
    assert [w[:2] for w in want] == WANT
    inc = clean.in_contact
    idle = int(2.5 * fs)  # in the quiet before the long press
    pressed = int(np.flatnonzero(inc[int(3.0 * fs) :])[0]) + int(3.5 * fs)  # in the long press
    assert not inc[idle - 10 : idle + 10].any() and inc[pressed - 10 : pressed + 10].all()
    for channel in (2, 9, 17):  # the first sensor's F_z, the second's F_y, the third's M_z
        bad = corrupted(rec, [idle, pressed], channel, by)
        for size in (len(rec.t), 1, 7):
            block = _pushed_in(paper_desk, bad.t, bad.wrench, size)
            assert finite(block)
            assert gestures(paper_desk, block, tmp_path) == want
            np.testing.assert_array_equal(block.in_contact, clean.in_contact)
            # the held sample is estimated as the one before it; the rest as without it
            far = np.abs(block.force_n - clean.force_n) > 1e-6
            assert not far[: idle - 1].any()


def test_corrupt_readings_are_told_at_the_first_and_tenth(paper_desk):
    rec = _tap_hold_tap(paper_desk)
    fs = paper_desk.sample_rate_hz
    quiet = [int(2.3 * fs) + 7 * j for j in range(12)]
    est = ContactEstimator(paper_desk)
    bad = corrupted(rec, quiet, 2, 80.0)
    est.push(bad.t, bad.wrench)
    told = [n for n in est.notices if n.kind == "jump"]
    assert [round(n.t * fs) for n in told] == [
        round(rec.t[quiet[0]] * fs),
        round(rec.t[quiet[9]] * fs),
    ]
    assert "80" in told[0].message and "(1 such so far)" in told[0].message


@pytest.mark.parametrize("run", [2, 3])
def test_corrupt_readings_in_a_row_make_no_gesture(paper_desk, tmp_path, run):
    # held for one sample only, two readings in a row +50 or +100 N off made a tap nobody
    # made (15 and 22 samples in contact); a run up to settings.JUMP_HOLD_S (3 samples at
    # 1.2 kHz) is held whole, and told once with its length
    rec = _tap_hold_tap(paper_desk)
    clean = estimate(paper_desk, rec)
    idle = int(2.5 * paper_desk.sample_rate_hz)
    for by in (50.0, 100.0, -100.0):
        bad = corrupted(rec, list(range(idle, idle + run)), 2, by)
        for size in (len(rec.t), 1, 7):
            block = _pushed_in(paper_desk, bad.t, bad.wrench, size)
            np.testing.assert_array_equal(block.in_contact, clean.in_contact)
            assert [g[:2] for g in gestures(paper_desk, block, tmp_path)] == WANT
    est = ContactEstimator(paper_desk)
    est.push(bad.t, bad.wrench)
    told = [n.message for n in est.notices if n.kind == "jump"]
    assert len(told) == 1 and f"for {run} samples and came back" in told[0]


def test_a_real_step_lands_after_the_hold(paper_desk):
    # a load put down at once (a step of 30 N that stays) is no corrupt reading: its first
    # samples are held (estimated as without the step) for JUMP_HOLD_S (3 at 1.2 kHz), the
    # rest taken, found in contact
    fs = paper_desk.sample_rate_hz
    hold = ContactEstimator(paper_desk).stage_settings.jump_hold_n
    assert hold == 3
    rec = simulate(paper_desk, Scene(actions=[Tap(point=(0.1, 0.05), peak_n=5.0)]), seed=3)
    at, n = int(2.5 * fs), len(rec.t)
    clean = estimate(paper_desk, rec)
    block = estimate(paper_desk, corrupted(rec, list(range(at, n)), 2, 30.0))
    later = estimate(paper_desk, corrupted(rec, list(range(at + 1, n)), 2, 30.0))
    # (held: the clean run's force; taken: +0.17 N and more)
    held = slice(at, at + hold)
    np.testing.assert_allclose(block.force_n[held], clean.force_n[held], atol=0.01)
    assert block.force_n[at + hold] > clean.force_n[at + hold] + 0.1
    assert block.in_contact[at : at + int(0.02 * fs)].any()
    # the same step a sample later is held alike: what follows is the same, a sample apart
    np.testing.assert_allclose(block.force_n[at + 1 : -1], later.force_n[at + 2 :], atol=0.05)
    np.testing.assert_array_equal(block.in_contact[at:-1], later.in_contact[at + 1 :])


@pytest.mark.parametrize("profile", ["kitamura2017-loadcells-80hz", "balance-board"])
def test_load_cells_at_80_hz_lose_no_tap_and_make_none(profile, tmp_path):
    # at 80 Hz a finger's press rises past the jump in one sample: its first sample is held,
    # the press is not lost, and a one-sample +50 N reading between taps makes no tap
    desk = load_profile(profile)
    middle = desk.surfaces[0].origin[:2]
    scene = Scene(
        actions=[
            Tap(point=(middle[0] + 0.05, middle[1]), peak_n=5.0),
            Press(point=(middle[0] - 0.05, middle[1]), hold_s=1.5),
            Tap(point=(middle[0], middle[1] + 0.03), peak_n=5.0),
        ]
    )
    rec = simulate(desk, scene, seed=3)
    clean = estimate(desk, rec)
    want = gestures(desk, clean, tmp_path)
    assert [w[:2] for w in want] == WANT
    fs = desk.sample_rate_hz
    idle = int(np.flatnonzero(clean.in_contact)[0] - 0.3 * fs)
    assert not clean.in_contact[idle - 3 : idle + 3].any()
    bad = corrupted(rec, [idle], 0, 50.0)
    assert gestures(desk, estimate(desk, bad), tmp_path) == want


def test_hold_jumps_off_takes_every_reading(paper_desk, tmp_path):
    # `estimation: {hold_jumps: false}` holds nothing: the corrupt reading's tap is back
    rec = _tap_hold_tap(paper_desk)
    bad = corrupted(rec, [int(2.5 * paper_desk.sample_rate_hz)], 2, 100.0)
    off = paper_desk.with_estimation(hold_jumps=False)
    got = [g[:2] for g in gestures(off, estimate(off, bad), tmp_path)]
    assert got == [WANT[0], ("tap", None), *WANT[1:]]
    # ... and a profile says so in its YAML
    text = (PROFILES / "kitamura2017.yaml").read_text()
    assert "\nestimation:\n" in text
    (tmp_path / "desk.yaml").write_text(
        text.replace("\nestimation:\n", "\nestimation:\n  hold_jumps: false\n", 1)
    )
    assert load_profile(tmp_path / "desk.yaml").estimation.hold_jumps is False
    assert paper_desk.estimation.hold_jumps is True
