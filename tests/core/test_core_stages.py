"""The estimator's stages, one compiled pass per sample (estimator/kernel.py): each stage does
what it says, and one pass equals any split into blocks (STYLE.md 8) — for the outputs, the
notices and every stage's state."""

from __future__ import annotations

from dataclasses import fields

import numpy as np
import pytest
from scipy.signal import sosfilt, sosfilt_zi

from hapticdesk.estimator import ContactEstimator, kernel_sums
from hapticdesk.estimator import kernel_slots as slots
from hapticdesk.estimator.contacts import (
    BAD_SAMPLE,
    FLAG_GAP,
    FLAG_NAN,
    FLAG_SATURATED,
    FLAG_STUCK,
    FLAG_TIME_BACK,
    ContactBlock,
)
from hapticdesk.files.profile import METHODS
from hapticdesk.files.profile_reader import load_profile
from hapticdesk.sim import Press, Scene, SimEffects, simulate

SPLITS = ("one", "ones", "sevens", "random")


def _bounds(n: int, split: str, seed: int = 3) -> list[int]:
    """Block boundaries for a split of n samples."""
    if split == "one":
        return [0, n]
    if split == "ones":
        return list(range(n + 1))
    if split == "sevens":
        return [*range(0, n, 7), n]
    cuts = np.sort(np.random.default_rng(seed).choice(np.arange(1, n), 40, replace=False))
    return [0, *cuts.tolist(), n]


def _pushed(est: ContactEstimator, t, w, bounds: list[int]) -> ContactBlock:
    """The blocks of a split, each copied as it comes (a block holds until the next push)."""
    return ContactBlock.concat(
        [est.push(t[a:b], w[a:b]).copy() for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
    )


def _assert_same(got: ContactBlock, want: ContactBlock) -> None:
    for f in fields(ContactBlock):
        a, b = getattr(got, f.name), getattr(want, f.name)
        if b.dtype.kind == "f":
            np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9, err_msg=f.name)
        else:
            np.testing.assert_array_equal(a, b, err_msg=f.name)


@pytest.fixture(scope="module")
def desk():
    return load_profile("kitamura2017")


@pytest.fixture(scope="module")
def bad_input(noisy_presses):
    """The noisy presses with a time step back, a gap, a saturated sample and a stuck input
    (50 repeats of a sample, then 10 of another 0.3 s later: one spell; 10 more just after
    it ended: another) added to their NaN burst."""
    t, w = noisy_presses
    t, w = t.copy(), w.copy()
    w[7000:7050] = w[6999]
    w[7400:7410] = w[7399]
    w[8660:8670] = w[8659]
    w[2500, 1, 2] = 1e3  # beyond the sensor's rated 300 N
    t[5000] = t[4999] - 0.001  # time goes back once
    t[6000:] += 0.2  # a gap longer than max_gap_s
    return t, w


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("split", SPLITS)
def test_any_split_gives_the_outputs_notices_and_state_of_one_pass(desk, bad_input, method, split):
    t, w = bad_input
    whole = ContactEstimator(desk, method=method)
    want = whole.push(t, w).copy()
    assert want.located.any() and (want.flags & BAD_SAMPLE).any()
    est = ContactEstimator(desk, method=method)
    _assert_same(_pushed(est, t, w, _bounds(len(t), split)), want)
    assert est.notices == whole.notices
    # every stage's state: the filters, the rings, the zero, the window, the detector
    np.testing.assert_allclose(est.state.sf, whole.state.sf, rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(
        est.state.si[: slots.J_EVENT_AT], whole.state.si[: slots.J_EVENT_AT]
    )


def test_the_sample_stage_flags_bad_samples_and_says_so(desk, bad_input):
    t, w = bad_input
    est = ContactEstimator(desk)
    flags = est.push(t, w).flags.copy()
    np.testing.assert_array_equal(np.flatnonzero(flags & FLAG_NAN), range(3000, 3010))
    np.testing.assert_array_equal(np.flatnonzero(flags & FLAG_SATURATED), [2500])
    np.testing.assert_array_equal(np.flatnonzero(flags & FLAG_TIME_BACK), [5000])
    # the first STUCK_RUN − 1 repeats pass as samples, the rest are a stuck input
    np.testing.assert_array_equal(
        np.flatnonzero(flags & FLAG_STUCK),
        [*range(7004, 7050), *range(7404, 7410), *range(8664, 8670)],
    )
    # the gap (the stuck spells are shorter than max_gap_s: no gap after them)
    np.testing.assert_array_equal(np.flatnonzero(flags & FLAG_GAP), [6000])
    # a notice when time first goes back (at the latest time before it), when a spell
    # sticks, and when it has been live for a second (1200 samples)
    told = [(n.kind, n.t) for n in est.notices if n.kind in ("time_back", "stuck", "live")]
    assert told == [
        ("time_back", t[4999]),
        ("stuck", t[7004]),
        ("live", t[7410 + 1199]),
        ("stuck", t[8664]),
    ]
    live = next(n for n in est.notices if n.kind == "live")
    assert f"to {t[7409]:.3f} s" in live.message


def test_a_noise_free_input_is_not_taken_for_a_stuck_one(desk):
    # a noise-free sensor (the simulator's ideal mode) repeats a steady load bit for bit:
    # three exact repeats in the input's first 0.2 s turn the stuck check off
    rec = simulate(desk, Scene([Press((0.1, 0.1))]), seed=1, effects=SimEffects.ideal())
    est = ContactEstimator(desk)
    flags = est.push(rec.t, rec.wrench).flags.copy()
    assert est.state.si[slots.J_STUCK_CHECK] == 0 and not (flags & BAD_SAMPLE).any()
    assert [n.kind for n in est.notices] == ["tare"]
    # while the same input, noisy at first, is checked
    noisy = rec.wrench.copy()
    noisy[:300] += np.random.default_rng(0).normal(0, 0.1, noisy[:300].shape)
    est = ContactEstimator(desk)
    flags = est.push(rec.t, noisy).flags.copy()
    assert (flags & FLAG_STUCK).any() and "stuck" in [n.kind for n in est.notices]


def test_the_filters_are_scipys_sosfilt_to_rounding(desk, noisy_presses):
    """The kernel's second-order sections run scipy's recursion: after a stretch of good
    samples its low-pass and fast states are sosfilt's, started in steady state alike."""
    t, w = noisy_presses
    n = 2900  # (before the NaN burst)
    est = ContactEstimator(desk)
    est.push(t[:n], w[:n])
    raw = w[:n].reshape(n, -1) @ desk.wrench_map().T  # (n, 6): paper eqs. (1)–(4)
    s = est.stage_settings
    sf, pi = est.state.sf, est.params.pi
    for sos, at in ((s.lp_sos, slots.I_SO_LP_ZI), (s.det_sos, slots.I_SO_DET_ZI)):
        zi = sosfilt_zi(sos)[:, :, None] * raw[0]
        _, zf = sosfilt(sos, raw, axis=0, zi=zi)
        kernel_zi = sf[pi[at] : pi[at] + 6 * len(sos) * 2].reshape(len(sos), 2, 6)
        lanes = 6 if at == slots.I_SO_LP_ZI else 3  # (the fast path's moments: fused alone)
        np.testing.assert_allclose(kernel_zi[..., :lanes], zf[..., :lanes], rtol=1e-9, atol=1e-9)


def test_window_means_are_numpys_to_the_bit():
    rng = np.random.default_rng(0)
    for n in (5, 8, 24, 120, 240, 600, 1201):
        a = rng.normal(100.0, 1.0, n) * rng.choice([1.0, 1e-8, 1e8], n)
        assert kernel_sums.pairwise_sum(a, 0, n, 1) == np.sum(a)
        strided = np.repeat(a, 3)
        assert kernel_sums.pairwise_sum(strided, 1, n, 3) == np.sum(a)


def test_the_zero_follows_drift_and_the_detector_switches(desk, bad_input):
    t, w = bad_input
    est = ContactEstimator(desk)
    block = est.push(t, w)
    assert 0.2 < block.in_contact.mean() < 0.8  # both states, several switches
    assert np.count_nonzero(np.diff(block.in_contact.astype(int)) == 1) >= 2
    # the zero was set more than once (tare, then the idle desk's drift followed)
    assert est.zeroing.state.zero_version > 1


@pytest.mark.parametrize("method", METHODS)
def test_single_sample_pushes_leave_the_loop_only_at_a_window_end(desk, noisy_presses, method):
    # issue 15 item 7 and issue 29: no slow path once tared; the one event a single sample
    # raises on the plain input is a zero window's end, 5 times a second at most (a window
    # that is not still, in contact, the kernel judges itself)
    t, w = noisy_presses
    est = ContactEstimator(desk, method=method)
    est.push(t[:3100], w[:3100])  # tared, and after the NaN burst
    assert est.tared
    handled: list[int] = []
    real_handle = est._handle
    est._handle = lambda events, *a: handled.append(events) or real_handle(events, *a)  # type: ignore[method-assign]
    window = est.stage_settings.window
    for i in range(3100, 3100 + 3 * window):
        est.push(t[i : i + 1], w[i : i + 1])
    assert set(handled) <= {slots.EV_WINDOW} and len(handled) <= 3
    # the windows of a press held (not still) never leave the loop
    est.push(t[3100 + 3 * window : 3600], w[3100 + 3 * window : 3600])
    handled.clear()
    pressing = ContactEstimator(desk, method=method)
    pressing.push(t[:2400], w[:2400])
    pressing._handle = lambda events, *a: handled.append(events)  # type: ignore[method-assign]
    inside = [pressing.push(t[i : i + 1], w[i : i + 1]).in_contact[0] for i in range(2400, 2880)]
    assert all(inside) and handled == []
