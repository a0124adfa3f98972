"""The human model: force shapes and rates, tremor, rolling, friction, tracing speed."""

from __future__ import annotations

import numpy as np
import pytest

from hapticdesk.sim import Drag, HumanModel, LongPress, Press, Ramp, Stroke, Swipe, Tap, shape_path
from hapticdesk.sim.actions import TouchStep
from hapticdesk.sim.touch_track import Touch, touch_track

FS = 1200.0
STILL = HumanModel(tremor=0.0, wander=0.0, roll_m=0.0, aim_sd_m=0.0, tangential=0.0)


def track(action: TouchStep, seed: int = 0, human: HumanModel | None = None) -> Touch:
    rng = np.random.default_rng(seed)
    touch = touch_track(action, 1.0, FS, rng, human or HumanModel())
    assert len(touch.fn) == pytest.approx(touch.duration_s * FS, abs=2)
    return touch


def rate_at(fn: np.ndarray, level: float, rising: bool) -> float:
    """|dF/dt| where the force first (rising) or last (falling) crosses ``level``."""
    d = np.gradient(fn) * FS
    i = np.flatnonzero(fn >= level)
    return float(abs(d[i[0] if rising else i[-1]]))


def test_press_rises_at_the_given_rate_and_releases_faster() -> None:
    touch = track(
        Press((0.0, 0.0), peak_n=20.0, hold_s=1.0, rise_n_per_s=45.0, release_n_per_s=90.0),
        human=STILL,
    )
    fn = touch.fn
    assert fn[0] == 0.0 and fn[-1] == pytest.approx(0.0, abs=0.1)
    assert fn.max() == pytest.approx(20.0, abs=1e-6)
    # a quarter sine: the rate at 2 N is 45·√(1 − (2/20)²)
    assert rate_at(fn, 2.0, True) == pytest.approx(45.0 * np.sqrt(0.99), rel=0.01)
    assert rate_at(fn, 2.0, False) == pytest.approx(90.0 * np.sqrt(0.99), rel=0.01)
    held = np.count_nonzero(fn >= 20.0 - 1e-9) / FS
    assert held == pytest.approx(1.0, abs=0.01)


def test_presses_vary_like_the_papers_subjects() -> None:
    rises, releases, peaks = [], [], []
    for seed in range(200):
        fn = track(Press((0.0, 0.0)), seed).fn
        rises.append(rate_at(fn, 2.0, True))
        releases.append(rate_at(fn, 2.0, False))
        peaks.append(fn.max())
    rises_a, releases_a = np.array(rises), np.array(releases)
    assert np.mean(rises_a) == pytest.approx(45.0, rel=0.1)  # paper: −45 N/s at touch
    faster = np.mean(releases_a > rises_a)
    assert 0.7 < faster < 0.9  # paper: faster at release in 63 of 81 presses (78 %)
    assert 15.0 * 0.9 < min(peaks) and max(peaks) < 25.0 * 1.15  # 15–25 N with tremor


def test_tremor_is_in_the_physiological_band() -> None:
    human = HumanModel(wander=0.0, tremor=0.02)
    fn = track(Press((0.0, 0.0), peak_n=20.0, hold_s=4.0), 3, human).fn
    hold = fn[fn > 19.0]
    hold = hold - hold.mean()
    spectrum = np.abs(np.fft.rfft(hold * np.hanning(len(hold))))
    freq = np.fft.rfftfreq(len(hold), 1.0 / FS)
    assert 8.0 <= freq[np.argmax(spectrum)] <= 12.0
    assert np.std(hold) == pytest.approx(0.02 * 20.0, rel=0.35)


def test_taps_are_light_and_short() -> None:
    for seed in range(50):
        touch = track(Tap((0.0, 0.0)), seed)
        assert 2.0 * 0.9 < touch.fn.max() < 5.0 * 1.1
        assert 0.08 - 0.002 <= len(touch.fn) / FS <= 0.16 + 0.002


def test_long_press_holds_longer() -> None:
    def hold(action: Press, seed: int) -> float:
        fn = track(action, seed, STILL).fn
        return float(np.count_nonzero(fn >= fn.max() - 1e-9) / FS)

    short = [hold(Press((0.0, 0.0)), s) for s in range(30)]
    long = [hold(LongPress((0.0, 0.0)), s) for s in range(30)]
    assert 0.6 - 0.01 <= min(short) and max(short) <= 1.5 + 0.01
    assert 2.0 - 0.01 <= min(long) and max(long) <= 3.0 + 0.01


def test_finger_rolls_about_a_millimetre_and_pushes_slightly_sideways() -> None:
    human = HumanModel(aim_sd_m=0.0)
    for seed in range(20):
        touch = track(Press((0.1, 0.05), peak_n=20.0), seed, human)
        shift = np.linalg.norm(touch.uv - touch.uv[0], axis=1).max()
        assert 0.0005 * 0.99 <= shift <= 0.0015 * 1.01
        ratio = np.linalg.norm(touch.tangential, axis=1)[1:] / touch.fn[1:]
        assert np.ptp(ratio[touch.fn[1:] > 1.0]) < 1e-9  # constant direction and share
        assert ratio.max() <= 0.08
    still = track(Press((0.1, 0.05)), 0, STILL)
    assert np.all(still.uv == still.uv[0]) and not still.tangential.any()


def test_ramp_climbs_steadily() -> None:
    touch = track(Ramp((0.0, 0.0), from_n=3.0, to_n=25.0, duration_s=2.0), 0, STILL)
    fn = touch.fn
    middle = fn[(fn > 5.0) & (np.arange(len(fn)) < np.argmax(fn))]
    slope = np.diff(middle) * FS
    assert np.allclose(slope, 22.0 / 2.0, rtol=1e-6)
    assert fn.max() == pytest.approx(25.0, abs=1e-3)


def speeds(touch: Touch) -> np.ndarray:
    return np.linalg.norm(np.gradient(touch.uv, 1.0 / FS, axis=0), axis=1)


def test_strokes_are_traced_at_the_papers_speed() -> None:
    path = shape_path("line", (0.0, 0.0), 0.1)
    mean_speeds = []
    for seed in range(60):
        touch = track(Stroke(path), seed)
        moving = speeds(touch) > 1e-4
        travelled = np.sum(np.linalg.norm(np.diff(touch.uv, axis=0), axis=1))
        mean_speeds.append(travelled / (np.count_nonzero(moving) / FS))
    assert np.mean(mean_speeds) == pytest.approx(0.0337, rel=0.08)  # 3.37 ± 0.64 cm/s
    assert np.std(mean_speeds) == pytest.approx(0.0064, rel=0.35)


def test_stroke_follows_its_path_and_stops_at_corners() -> None:
    path = shape_path("triangle", (0.0, 0.0), 0.1)
    touch = track(Stroke(path, speed=0.05), 0, STILL)
    np.testing.assert_allclose(touch.uv[0], path[0], atol=1e-12)
    np.testing.assert_allclose(touch.uv[-1], path[-1], atol=1e-12)
    v = speeds(touch)
    for corner in path[1:-1]:
        nearest = np.argmin(np.linalg.norm(touch.uv - corner, axis=1))
        assert np.linalg.norm(touch.uv[nearest] - corner) < 1e-4
        assert v[nearest] < 0.002  # the finger slows to a stop at each corner
    assert v.max() > 0.05


def test_friction_drags_along_the_motion() -> None:
    human = HumanModel(friction=0.6, aim_sd_m=0.0)
    touch = track(Drag([(-0.1, 0.0), (0.1, 0.0)], force_n=10.0, speed=0.1), 0, human)
    v = np.gradient(touch.uv, 1.0 / FS, axis=0)
    fast = np.linalg.norm(v, axis=1) > 0.05
    assert np.count_nonzero(fast) > 100
    t = touch.tangential[fast]
    assert np.all(t[:, 0] > 0)  # along +x, with the finger's motion
    np.testing.assert_allclose(np.linalg.norm(t, axis=1), 0.6 * touch.fn[fast], rtol=0.01)


def test_swipe_lifts_off_while_moving() -> None:
    touch = track(Swipe((-0.1, 0.0), (0.1, 0.0)), 0)
    v = speeds(touch)
    in_contact = touch.fn > 0.5
    last = np.flatnonzero(in_contact)[-1]
    assert v[last] > 0.02
    assert len(touch.fn) / FS < 1.5


def test_same_generator_state_gives_the_same_touch() -> None:
    a = track(Stroke(shape_path("circle", (0, 0), 0.1)), 11)
    b = track(Stroke(shape_path("circle", (0, 0), 0.1)), 11)
    c = track(Stroke(shape_path("circle", (0, 0), 0.1)), 12)
    np.testing.assert_array_equal(a.fn, b.fn)
    np.testing.assert_array_equal(a.uv, b.uv)
    assert not np.array_equal(a.fn, c.fn)


def test_human_model_refuses_nonsense() -> None:
    with pytest.raises(ValueError, match="peak_n"):
        HumanModel(peak_n=(25.0, 15.0))
    with pytest.raises(ValueError, match="friction"):
        HumanModel(friction=-0.1)


def test_stroke_with_logged_times_follows_them() -> None:
    # 1 cm in 1 s, then 5 cm in 0.1 s: a real stroke's timing, not the mean tracing speed
    path = [(0.0, 0.0), (0.01, 0.0), (0.06, 0.0)]
    touch = track(Stroke(path, times=(0.0, 1.0, 1.1)), 0, STILL)
    np.testing.assert_allclose(touch.uv[-1], path[-1], atol=1e-12)
    moving = np.flatnonzero(np.linalg.norm(np.diff(touch.uv, axis=0), axis=1) > 0)
    assert (moving[-1] - moving[0] + 1) / FS == pytest.approx(1.1, abs=2 / FS)
    at = moving[0] + int(1.05 * FS)  # halfway through the quick part
    assert touch.uv[at, 0] == pytest.approx(0.035, abs=0.001)
    slow = speeds(touch)[moving[0] + 10 : moving[0] + int(0.9 * FS)]
    assert slow == pytest.approx(0.01, rel=0.02)
    for bad in [(0.0, 1.0), (0.0, 1.0, 0.5), (0.1, 1.0, 2.0), (0.0, float("nan"), 1.0)]:
        with pytest.raises(ValueError, match="Stroke.times"):
            Stroke(path, times=bad)
