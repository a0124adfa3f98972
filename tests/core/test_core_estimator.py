"""The contact estimator: exactness, chunk invariance, tare, objects, bad samples, extremes."""

import re
from dataclasses import fields, replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hapticdesk.estimator import ContactEstimator
from hapticdesk.estimator.contacts import (
    FLAG_GAP,
    FLAG_NAMES,
    FLAG_NAN,
    FLAG_SATURATED,
    FLAG_STUCK,
    FLAG_TIME_BACK,
    ContactBlock,
    contact_events,
)
from hapticdesk.files.profile import METHODS
from hapticdesk.files.profile_reader import load_profile

# the page that states the contact samples' flags (the README points there)
CONTACTS_DOC = Path(__file__).resolve().parents[2] / "docs" / "contacts.md"
POINTS = [(0.2, 0.1, 0.733), (-0.3, -0.2, 0.733), (0.0, 0.0, 0.733)]


@pytest.fixture(autouse=True)
def _helpers(statics):
    global PUSH, PRESS, READINGS
    PUSH, PRESS, READINGS = statics


def all_finite(block: ContactBlock) -> bool:
    return all(
        np.isfinite(getattr(block, f.name)).all()
        for f in fields(block)
        if getattr(block, f.name).dtype.kind == "f"
    )


def split_push(est: ContactEstimator, t, w, cuts) -> ContactBlock:
    """The blocks of pushes cut at ``cuts``, each copied as it comes (a block holds until the
    estimator's next push)."""
    bounds = [0, *sorted(cuts), len(t)]
    return ContactBlock.concat(
        [est.push(t[a:b], w[a:b]).copy() for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
    )


@pytest.mark.parametrize("method", METHODS)
def test_noise_free_presses_are_located_exactly(paper_desk, press_recording, method):
    t, w, _ = press_recording(paper_desk, POINTS)
    est = ContactEstimator(paper_desk, method=method)
    block = est.push(t, w)
    assert [n.kind for n in est.notices] == ["tare"]
    for i, p in enumerate(POINTS):
        window = (t > 1.5 + 4 * i) & (t < 1.5 + 4 * (i + 1)) & block.located
        assert window.sum() > 100
        err = np.hypot(block.x[window] - p[0], block.y[window] - p[1])
        assert err.max() < 1e-9, (method, i, err.max())
        assert np.allclose(block.z[window], 0.733)
    events = contact_events(block)
    assert [e.kind for e in events].count("down") == 3
    assert [e.kind for e in events].count("up") == 3


@settings(max_examples=25, deadline=None)
@given(
    cuts=st.lists(st.integers(1, 8999), max_size=40, unique=True), method=st.sampled_from(METHODS)
)
def test_streaming_in_any_blocks_equals_batch(noisy_presses, cuts, method):
    desk = load_profile("kitamura2017")
    t, w = noisy_presses
    batch = ContactEstimator(desk, method=method).push(t, w)
    assert batch.located.sum() > 200 and (batch.flags & FLAG_NAN).sum() == 10
    stream = split_push(ContactEstimator(desk, method=method), t, w, cuts)
    for f in fields(ContactBlock):
        a, b = getattr(batch, f.name), getattr(stream, f.name)
        if a.dtype.kind == "f":
            np.testing.assert_allclose(b, a, rtol=1e-9, atol=1e-9, err_msg=f.name)
        else:
            np.testing.assert_array_equal(b, a, err_msg=f.name)


@pytest.mark.parametrize("method", METHODS)
def test_single_sample_pushes_equal_batch(noisy_presses, method):
    # a one-sample push goes through the kernel's one-sample entry: it must agree
    desk = load_profile("kitamura2017")
    t, w = noisy_presses
    batch = ContactEstimator(desk, method=method).push(t, w)
    stream = split_push(ContactEstimator(desk, method=method), t, w, range(1, len(t)))
    for f in fields(ContactBlock):
        a, b = getattr(batch, f.name), getattr(stream, f.name)
        if a.dtype.kind == "f":
            np.testing.assert_allclose(b, a, rtol=1e-9, atol=1e-9, err_msg=f.name)
        else:
            np.testing.assert_array_equal(b, a, err_msg=f.name)


@pytest.mark.parametrize("method", METHODS)
def test_a_stuck_input_streamed_in_1_and_7_sample_pushes_equals_batch(noisy_presses, method):
    # stuck for 0.7 s after the first press, live again 0.4 s before the light second one
    desk = load_profile("kitamura2017")
    t, w = noisy_presses
    w = w.copy()
    w[4090:4920] = w[4089]  # (across the range check's pieces of 4096 in a batch)
    est = ContactEstimator(desk, method=method)
    batch = est.push(t, w)
    stuck = (batch.flags & FLAG_STUCK) != 0
    assert stuck.sum() == 830 - 4 and not batch.located[stuck].any() and all_finite(batch)
    # the press after it found as without the stuck spell (to a sample: the filters
    # restarted when the input came back) and located as well (the zero is older)
    clean = ContactEstimator(desk, method=method).push(t, noisy_presses[1])
    assert np.count_nonzero(batch.in_contact != clean.in_contact) <= 2

    def error_m(block: ContactBlock) -> float:
        after = block.located & (t > 4.5)
        assert after.sum() > 100
        return float(np.hypot(np.median(block.x[after]) - 0.1, np.median(block.y[after]) + 0.15))

    assert abs(error_m(batch) - error_m(clean)) < 3e-3
    assert [n.kind for n in est.notices] == ["tare", "stuck", "gap", "live"]
    for size in (1, 7):
        streamed = ContactEstimator(desk, method=method)
        block = split_push(streamed, t, w, range(size, len(t), size))
        assert streamed.notices == est.notices
        for f in fields(ContactBlock):
            a, b = getattr(batch, f.name), getattr(block, f.name)
            if a.dtype.kind == "f":
                np.testing.assert_allclose(b, a, rtol=1e-9, atol=1e-9, err_msg=f.name)
            else:
                np.testing.assert_array_equal(b, a, err_msg=f.name)


def lean_then_press(desk, lean_until: float):
    """Someone leans on the desk (a wavering 30 N) until ``lean_until``, then lets go."""
    fs = desk.sample_rate_hz
    t = np.arange(int((lean_until + 6.0) * fs)) / fs
    lean = np.where(t < lean_until, 30 + 3 * np.sin(2 * np.pi * 1.3 * t), 0.0)
    f_o, m_o = PUSH(np.array([0.0, -0.2, 0.733]), np.outer(lean, [0, 0, -1.0]))
    press = PRESS(t, lean_until + 2.5)
    f2, m2 = PUSH(np.array([0.25, 0.1, 0.733]), np.outer(press, [0, 0, -1.0]))
    f_o = f_o + f2
    f_o[:, 2] += 134.4
    return t, READINGS(desk, f_o, m_o + m2)


def test_tare_is_refused_while_someone_leans_and_retried(paper_desk):
    t, w = lean_then_press(paper_desk, 3.0)
    est = ContactEstimator(paper_desk)
    block = est.push(t, w)
    # (the tare's notices: a press held this still may be taken for an object after it)
    kinds = [n.kind for n in est.notices if n.kind.startswith("tare")]
    assert kinds.count("tare_refused") >= 2 and kinds[-1] == "tare"
    tare_t = next(n.t for n in est.notices if n.kind == "tare")
    assert tare_t > 3.0  # not a silent bad zero taken while leaning
    assert not block.in_contact[t < tare_t].any()
    press = block.located & (t > 5.0)
    assert press.sum() > 500
    assert np.abs(block.x[press] - 0.25).max() < 1e-6


def test_an_object_put_down_becomes_part_of_the_zero(paper_desk):
    fs = paper_desk.sample_rate_hz
    settings_ = replace(paper_desk.estimation, settle_s=3.0)
    t = np.arange(int(14 * fs)) / fs
    mug = np.where(t > 2.0, 4.0, 0.0)  # a 4 N mug put down at t = 2 s, perfectly still
    f_o, m_o = PUSH(np.array([-0.3, 0.2, 0.733]), np.outer(mug, [0, 0, -1.0]))
    press = PRESS(t, 9.0)
    f2, m2 = PUSH(np.array([0.1, -0.1, 0.733]), np.outer(press, [0, 0, -1.0]))
    f_o = f_o + f2
    f_o[:, 2] += 134.4
    w = READINGS(paper_desk, f_o, m_o + m2)
    est = ContactEstimator(paper_desk, settings=settings_)
    block = est.push(t, w)
    absorbed = [n for n in est.notices if n.kind == "absorbed"]
    assert len(absorbed) == 1 and "4.0 N" in absorbed[0].message
    assert 5.0 < absorbed[0].t < 5.5
    # the mug was a touch until absorbed, then not; the later press is located exactly
    assert block.in_contact[(t > 2.5) & (t < 4.5)].all()
    assert not block.in_contact[(t > 5.6) & (t < 8.9)].any()
    later = block.located & (t > 9.0)
    assert later.sum() > 500 and np.abs(block.x[later] - 0.1).max() < 1e-6


@pytest.mark.parametrize("method", METHODS)
def test_nan_bursts_are_flagged_and_skipped(paper_desk, press_recording, method):
    t, w, _ = press_recording(paper_desk, POINTS[:1], noise=0.05)
    clean = ContactEstimator(paper_desk, method=method).push(t, w)
    bad = w.copy()
    burst = slice(int(2.5 * 1200), int(2.5 * 1200) + 24)  # 20 ms of NaN mid-press
    bad[burst, 1, :] = np.nan
    bad[int(2.0 * 1200), 0, 2] = np.inf
    block = ContactEstimator(paper_desk, method=method).push(t, bad)
    assert all_finite(block)
    assert (block.flags[burst] & FLAG_NAN).all()
    assert block.in_contact[burst].all()  # a burst is not a release
    assert not block.located[burst].any()
    after = slice(burst.stop + 600, burst.stop + 1200)
    np.testing.assert_allclose(block.x[after], clean.x[after], atol=2e-3)


def test_time_going_backwards_and_gaps(paper_desk, press_recording):
    t, w, _ = press_recording(paper_desk, POINTS[:1])
    t = t.copy()
    t[2000] = t[1990]  # a repeated (late) time stamp
    t[2700:] += 0.5  # the sensor stalled for half a second, mid-press
    est = ContactEstimator(paper_desk)
    block = est.push(t, w)
    assert block.flags[2000] & FLAG_TIME_BACK
    assert block.flags[2700] & FLAG_GAP
    assert any(n.kind == "gap" for n in est.notices)
    [back] = [n for n in est.notices if n.kind == "time_back"]  # the one is said once
    assert back.t == pytest.approx(t[1999]) and "(1 such so far)" in back.message
    assert all_finite(block)
    later = block.located & (t > t[2700])
    assert later.sum() > 300
    assert np.abs(block.x[later] - 0.2).max() < 1e-9


def test_a_recording_whose_time_runs_backwards_says_so_a_few_times(paper_desk):
    """Reversed time stamps had ended with no contact and only "tare refused" to say why; the
    estimator now says time went back, at its 1st, 10th, 100th… such sample, block by block."""
    fs = paper_desk.sample_rate_hz
    t = (np.arange(30_000) / fs)[::-1].copy()
    w = np.random.default_rng(0).normal(0, 0.05, (len(t), len(paper_desk.sensors), 6))
    est = ContactEstimator(paper_desk)
    for start in range(0, len(t), 7_000):
        est.push(t[start : start + 7_000], w[start : start + 7_000])
    said = [n.message for n in est.notices if n.kind == "time_back"]
    assert [m.split("(")[1].split(" such")[0] for m in said] == ["1", "10", "100", "1000", "10000"]
    assert said[0].startswith("time went back: a sample at t = ")


def test_forces_at_and_beyond_the_rated_range(paper_desk):
    fs = paper_desk.sample_rate_hz
    t = np.arange(int(4 * fs)) / fs
    mag = np.clip(200 * (t - 1.5), 0, 1200)  # up to 1200 N on one corner: beyond ±300 N
    f_o, m_o = PUSH(np.array([0.33, 0.21, 0.733]), np.outer(mag, [0, 0, -1.0]))
    f_o[:, 2] += 134.4
    w = READINGS(paper_desk, f_o, m_o)
    block = ContactEstimator(paper_desk).push(t, w)
    sat = (block.flags & FLAG_SATURATED) != 0
    assert sat.any() and all_finite(block)
    limits = paper_desk.saturation_limits()
    assert np.array_equal(sat, (np.abs(w) >= limits).any(axis=(1, 2)))
    ok = block.located & ~sat
    assert ok.sum() > 100 and np.abs(block.x[ok] - 0.33).max() < 1e-6


def test_10_khz_with_a_half_hertz_low_pass_stays_stable(tmp_path):
    text = (
        load_profile("kitamura2017")
        .path.read_text()
        .replace("sample_rate_hz: 1200", "sample_rate_hz: 10000")
        .replace("diff_lowpass_hz: 4.77", "diff_lowpass_hz: 0.5")
        .replace("force_lowpass_hz: 4.77", "force_lowpass_hz: 0.5")
    )
    path = tmp_path / "fast.yaml"
    path.write_text(text)
    desk = load_profile(path)
    fs = desk.sample_rate_hz
    t = np.arange(int(20 * fs)) / fs
    mag = PRESS(t, 3.0, hold=4.0)  # shorter than settle_s: not taken for an object
    f_o, m_o = PUSH(np.array([-0.1, 0.2, 0.733]), np.outer(mag, [0, 0, -1.0]))
    f_o[:, 2] += 134.4
    w = READINGS(desk, f_o, m_o) + np.random.default_rng(1).normal(0, 0.05, (len(t), 4, 6))
    for method in METHODS:
        block = ContactEstimator(desk, method=method).push(t, w)
        assert all_finite(block)
        # `diff` alone locates only while the force changes; the others through the hold
        window = (t > 3.0) & (t < 4.0) if method == "diff" else (t > 5.5) & (t < 7.5)
        located = block.located & window
        assert located.sum() > 2000, method
        assert np.abs(block.x[located] + 0.1).max() < 5e-3, method


def test_an_hour_streamed_in_blocks_keeps_memory_flat(paper_desk, press_recording):
    import tracemalloc

    t, w, _ = press_recording(paper_desk, POINTS, noise=0.05)
    est = ContactEstimator(paper_desk, method="fused")
    block_size = 600
    n_blocks = int(3600 * 1200 / block_size)
    # what the pushes allocate and keep: traced with their callers, so that a thread left
    # running by another test (it allocates too) is not counted as the estimator's growth
    tracemalloc.start(16)
    early = None
    located = 0
    for i in range(n_blocks):
        a = (i * block_size) % (len(t) - block_size)
        out = est.push(t[a : a + block_size] + i * block_size / 1200 - t[a], w[a : a + block_size])
        located += int(out.located.sum())
        if i == 50:
            early = tracemalloc.take_snapshot()
    late = tracemalloc.take_snapshot()
    tracemalloc.stop()
    assert early is not None
    pushed = [tracemalloc.Filter(True, __file__, all_frames=True)]
    kept = late.filter_traces(pushed).compare_to(early.filter_traces(pushed), "filename")
    assert n_blocks * block_size == 4_320_000
    assert located > 100_000
    assert sum(d.size_diff for d in kept) < 200_000  # bytes: no growth over an hour
    assert len(est.notices) < 20_000  # drift notices only; nothing per sample


def test_trace_keeps_both_candidates_and_changes_nothing(noisy_presses):
    from hapticdesk.estimator import CandidateTrace

    desk = load_profile("kitamura2017")
    t, w = noisy_presses
    plain = ContactEstimator(desk, method="switched").push(t, w)
    est = ContactEstimator(desk, method="switched", trace=True)
    traced = split_push(est, t, w, range(500, len(t), 500))
    for f in fields(ContactBlock):
        np.testing.assert_allclose(getattr(traced, f.name), getattr(plain, f.name), atol=1e-9)
    trace = CandidateTrace.concat(est.traces)
    good_contact = plain.in_contact & ((plain.flags & (FLAG_NAN | FLAG_SATURATED)) == 0)
    assert len(trace.t) == good_contact.sum()
    # where switched used a candidate, the trace holds that same point
    used = plain.located[good_contact]
    src = plain.source[good_contact]
    point = np.where(src == 1, trace.force_point, trace.diff_point)
    np.testing.assert_allclose(point[0, used], plain.x[good_contact][used])


def test_a_block_holds_until_the_next_push_and_a_copy_or_a_long_one_is_kept(
    noisy_presses, monkeypatch
):
    # push returns views of the estimator's own output columns (no per-sample arrays are
    # built): the next push writes over them. A push longer than KEPT_COLUMNS gets columns
    # of its own, so the block of a whole recording is the caller's to keep.
    from hapticdesk.estimator import contact_estimator

    desk = load_profile("kitamura2017")
    t, w = noisy_presses
    est = ContactEstimator(desk)
    first = est.push(t[:1000], w[:1000])
    kept = first.copy()
    np.testing.assert_array_equal(first.t, t[:1000])
    again = est.push(t[1000:2000], w[1000:2000])
    assert again is first  # the same view for a push of the same length
    np.testing.assert_array_equal(first.t, t[1000:2000])
    np.testing.assert_array_equal(kept.t, t[:1000])
    one = est.push(t[2000:2001], w[2000:2001])
    assert est.push(t[2001:2002], w[2001:2002]) is one  # the reused one-sample record
    monkeypatch.setattr(contact_estimator, "KEPT_COLUMNS", 997)
    whole = ContactEstimator(desk)
    long = whole.push(t, w)
    whole.push(t[:1000] + t[-1] + 1.0, w[:1000])
    np.testing.assert_array_equal(long.t, t)


def test_an_unrated_channel_cannot_overflow_the_sums(paper_desk, press_recording):
    # without a rating every finite reading is accepted, but one so large that the resultant
    # would overflow is flagged as saturated, not turned into infinity
    sensors = tuple(replace(s, force_range=None, moment_range=None) for s in paper_desk.sensors)
    desk = replace(paper_desk, sensors=sensors)
    assert desk.saturation_limits() is None
    t, w, _ = press_recording(desk, POINTS[:1])
    w = w.copy()
    w[2500, 1, 2] = 1e300
    w[2600:2610, 0, 4] = -1e308
    for k in (len(t), 1):
        est = ContactEstimator(desk, method="fused")
        block = split_push(est, t, w, range(k, len(t), k))
        sat = np.flatnonzero(block.flags & FLAG_SATURATED)
        assert sat.tolist() == [2500, *range(2600, 2610)]
        assert all_finite(block) and block.located.sum() > 100


def test_the_first_sample_is_never_a_gap(paper_desk):
    # however the first block ends, even with max_gap_s shorter than a sample period
    s = replace(paper_desk.estimation, max_gap_s=0.5 / paper_desk.sample_rate_hz)
    t = np.arange(10) / paper_desk.sample_rate_hz
    w = np.random.default_rng(0).normal(0, 0.01, (10, 4, 6))
    w[5, 0, 0] = np.nan  # the first block of five is clean, the whole is not
    whole = ContactEstimator(paper_desk, settings=s).push(t, w)
    est = ContactEstimator(paper_desk, settings=s)
    split = split_push(est, t, w, [5])
    assert not whole.flags[0] & FLAG_GAP
    np.testing.assert_array_equal(split.flags, whole.flags)


@pytest.mark.parametrize("method", METHODS)
def test_noise_free_single_sample_pushes_equal_batch(paper_desk, press_recording, method):
    # tiny variances (noise-free input, no drift): the 2×2 inversions must not clamp them
    # differently on the two paths
    s = replace(
        paper_desk.estimation, method=method, drift_force_n_per_min=0.0, drift_moment_nm_per_min=0.0
    )
    t, w, _ = press_recording(paper_desk, POINTS[:2])
    batch = ContactEstimator(paper_desk, settings=s).push(t, w)
    est = ContactEstimator(paper_desk, settings=s)
    single = split_push(est, t, w, range(1, len(t)))
    np.testing.assert_array_equal(single.located, batch.located)
    assert batch.located.sum() > 100
    np.testing.assert_allclose(single.sigma_m, batch.sigma_m, rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose(single.x, batch.x, rtol=0, atol=1e-9)


def test_the_flags_are_the_documented_ones():
    # a contract: flags may grow, never change (docs/contacts.md: "bits that only grow")
    text = " ".join(CONTACTS_DOC.read_text(encoding="utf-8").split())
    listed = text.split("bits that only grow:")[1].split("(")[0]
    documented = {int(bit): name for name, bit in re.findall(r"`(\w+)` (\d+)", listed)}
    assert documented == FLAG_NAMES


def test_the_notices_are_bounded_and_a_reader_keeps_its_place(paper_desk):
    """Issue 11 item 16: a day of gaps must not grow the notices for the whole run."""
    from hapticdesk.estimator.notices import NOTICES_KEPT

    rate = paper_desk.sample_rate_hz
    rng = np.random.default_rng(0)
    est = ContactEstimator(paper_desk)
    n_gaps, per_piece = NOTICES_KEPT + 500, 6
    seen = 0
    read: list[str] = []
    for i in range(n_gaps):
        # a few samples, then a 1 s gap before the next piece: one "gap" notice each time
        t = i * 2.0 + np.arange(per_piece) / rate
        w = rng.normal(0.0, 0.01, (per_piece, len(paper_desk.sensors), 6))
        est.push(t, w)
        if i % 97 == 0:  # a reader such as the browser's feed, polling now and then
            read += [n.kind for n in est.notices.since(seen)]
            seen = est.notices.total
    read += [n.kind for n in est.notices.since(seen)]
    assert len(est.notices) == NOTICES_KEPT
    assert est.notices.total == len(read) >= n_gaps - 1  # every one read once, none twice
    assert est.notices.dropped == est.notices.total - NOTICES_KEPT
    assert est.notices[-1].t > est.notices[0].t
