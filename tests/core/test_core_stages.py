"""Each stage of the estimator on its own: one pass equals any split into blocks (STYLE.md 8),
and each stage's single-sample twin equals its block path."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from hapticdesk.estimator.candidates import CandidateStage, Covariances, unpacked_at
from hapticdesk.estimator.contacts import FLAG_GAP, FLAG_STUCK, FLAG_TIME_BACK, ContactBlock
from hapticdesk.estimator.detector import TouchDetector, slope_along
from hapticdesk.estimator.filter_bank import FilterBank
from hapticdesk.estimator.methods import emit_one, select, select_one
from hapticdesk.estimator.notices import Notice
from hapticdesk.estimator.samples import BAD_SAMPLE, SampleStage
from hapticdesk.estimator.settings import EstimatorSettings
from hapticdesk.estimator.zero import ZeroStage, subtract_zero
from hapticdesk.files.profile import METHODS
from hapticdesk.files.profile_reader import load_profile
from hapticdesk.sim import Press, Scene, SimEffects, simulate

SPLITS = ("one", "ones", "sevens", "random")


def _bounds(k: int, split: str) -> list[int]:
    """Block boundaries for a split of k samples."""
    if split == "one":
        return [0, k]
    if split == "ones":
        return list(range(k + 1))
    if split == "sevens":
        return [*range(0, k, 7), k]
    cuts = np.sort(np.random.default_rng(3).choice(np.arange(1, k), 40, replace=False))
    return [0, *cuts.tolist(), k]


def _in_blocks(k: int, split: str, step: Callable[[slice], list[np.ndarray]]) -> list[np.ndarray]:
    """Run ``step`` on each block of a split; its outputs joined along the last axis."""
    bounds = _bounds(k, split)
    parts = [step(slice(a, b)) for a, b in zip(bounds[:-1], bounds[1:], strict=True) if b > a]
    return [np.concatenate(p, axis=-1) for p in zip(*parts, strict=True)]


def _assert_same(got: list[np.ndarray], want: list[np.ndarray]) -> None:
    for g, w in zip(got, want, strict=True):
        if w.dtype.kind in "fc":
            np.testing.assert_allclose(g, w, rtol=1e-9, atol=1e-9)
        else:
            np.testing.assert_array_equal(g, w)


@pytest.fixture(scope="module")
def desk():
    return load_profile("kitamura2017")


@pytest.fixture(scope="module")
def bad_input(noisy_presses):
    """The noisy presses with a time step back, a gap and a stuck input (50 repeats of a
    sample, then 10 of another 0.3 s later: one spell; 10 more just after it ended: another)
    added to their NaN burst."""
    t, w = noisy_presses
    t, w = t.copy(), w.copy()
    w[7000:7050] = w[6999]
    w[7400:7410] = w[7399]
    w[8660:8670] = w[8659]
    t[5000] = t[4999] - 0.001  # time goes back once
    t[6000:] += 0.2  # a gap longer than max_gap_s
    return t, w


def _settings(desk, method: str = "fused") -> EstimatorSettings:
    from dataclasses import replace

    return EstimatorSettings.of(desk, replace(desk.estimation, method=method), trace=False)


@pytest.fixture(scope="module")
def upstream(desk, bad_input):
    """Every stage's input, from one pass of the stages before it."""
    s = _settings(desk)
    t, w = bad_input
    samples = SampleStage(s, [])
    flags, raw = samples.process(t, w)
    lp, det, diff, slope, release = FilterBank(s, []).process(t, raw, flags, True)
    zero = ZeroStage(s, [])
    segments = zero.process(t, lp.real, raw, flags)
    assert zero.state.noise is not None
    fast, age, tared, _ = subtract_zero(t, det, lp.copy(), segments, s.det_full)
    return {
        "t": t,
        "flags": flags,
        "raw": raw,
        "lp": lp,
        "det": det,
        "diff": diff,
        "slope": slope,
        "release": release,
        "fast": fast,
        "age": age,
        "tared": tared,
        "covs": Covariances.of(s, zero.state.noise),
    }


@pytest.mark.parametrize("split", SPLITS)
def test_the_sample_stage_is_chunk_invariant(desk, bad_input, split):
    t, w = bad_input
    s = _settings(desk)
    told: list[Notice] = []
    whole = SampleStage(s, told)
    want = list(whole.process(t, w))
    assert (want[0] & FLAG_TIME_BACK).any() and (want[0] & FLAG_GAP).any()
    # the first STUCK_RUN − 1 repeats pass as samples, the rest are a stuck input
    np.testing.assert_array_equal(
        np.flatnonzero(want[0] & FLAG_STUCK),
        [*range(7004, 7050), *range(7404, 7410), *range(8664, 8670)],
    )
    assert (want[0] & BAD_SAMPLE).sum() > 10 and np.isfinite(want[1]).all()
    # a notice when time first goes back (at the latest time before it), when a spell
    # sticks, and when it has been live for a second (1200 samples)
    assert [(n.kind, n.t) for n in told] == [
        ("time_back", t[4999]),
        ("stuck", t[7004]),
        ("live", t[7410 + 1199]),
        ("stuck", t[8664]),
    ]
    assert f"to {t[7409]:.3f} s" in told[2].message
    notices: list[Notice] = []
    stage = SampleStage(s, notices)
    _assert_same(_in_blocks(len(t), split, lambda b: list(stage.process(t[b], w[b]))), want)
    assert stage.state.last_t == whole.state.last_t
    assert notices == told


def test_a_noise_free_input_is_not_taken_for_a_stuck_one(desk):
    # a noise-free sensor (the simulator's ideal mode) repeats a steady load bit for bit:
    # three exact repeats in the input's first 0.2 s turn the stuck check off
    rec = simulate(desk, Scene([Press((0.1, 0.1))]), seed=1, effects=SimEffects.ideal())
    notices: list[Notice] = []
    stage = SampleStage(_settings(desk), notices)
    flags, _ = stage.process(rec.t, rec.wrench)
    assert stage.state.stuck_check is False and not flags.any() and not notices
    # while the same input, noisy at first, is checked
    noisy = rec.wrench.copy()
    noisy[:300] += np.random.default_rng(0).normal(0, 0.1, noisy[:300].shape)
    flags, _ = SampleStage(_settings(desk), notices).process(rec.t, noisy)
    assert (flags & FLAG_STUCK).any() and notices[0].kind == "stuck"


def test_the_sample_stage_one_sample_twin_equals_its_block_path(desk, noisy_presses):
    t, w = noisy_presses
    s = _settings(desk)
    block, single = SampleStage(s, []), SampleStage(s, [])
    _, want = block.process(t, w)
    # the twin takes nothing during the input's noise check (the block path decides it)
    assert single.process_one(float(t[0]), w[:1]) is None
    single.process(t[:1000], w[:1000])
    assert single.state.stuck_check
    got = [single.process_one(float(t[i]), w[i : i + 1]) for i in range(1000, 3000)]
    # (a matrix-vector product may round in another order than the matrix one)
    np.testing.assert_allclose(np.array(got).T, want[:, 1000:3000], rtol=1e-12, atol=1e-12)
    # a NaN sample is not the twin's: it leaves the state alone
    last_t = single.state.last_t
    assert single.process_one(last_t + 0.001, np.full((1, 4, 6), np.nan)) is None
    assert single.state.last_t == last_t
    # nor a repeat of the sample before (the block path counts the repeats)
    assert single.process_one(last_t + 0.0005, w[2999:3000]) is None
    assert single.state.last_t == last_t


@pytest.mark.parametrize("split", SPLITS)
def test_the_filter_bank_is_chunk_invariant(desk, upstream, split):
    s = _settings(desk)
    t, raw, flags = upstream["t"], upstream["raw"], upstream["flags"]
    notices: list[Notice] = []
    bank = FilterBank(s, notices)
    got = _in_blocks(len(t), split, lambda b: list(bank.process(t[b], raw[:, b], flags[b], True)))
    names = ("lp", "det", "diff", "slope", "release")
    _assert_same(got, [upstream[n] for n in names])
    assert [n.kind for n in notices] == ["gap"]


def test_the_filter_bank_one_sample_twin_equals_its_block_path(desk, upstream):
    s = _settings(desk)
    raw = upstream["raw"][:, :3000]
    block, single = FilterBank(s, []), FilterBank(s, [])
    want = block.process(upstream["t"][:3000], raw, np.zeros(3000, np.uint8), True)
    single.process(upstream["t"][:1], raw[:, :1], np.zeros(1, np.uint8), True)
    got = [single.process_one(raw[:, i]) for i in range(1, 3000)]
    for j in range(3):
        np.testing.assert_allclose(np.array([g[j] for g in got]).T, want[j][:, 1:], atol=1e-12)
    np.testing.assert_allclose(np.array([g[3] for g in got]).T, want[3][:, 1:], atol=1e-9)
    np.testing.assert_allclose(np.array([g[4] for g in got]).T, want[4][:, 1:], atol=1e-9)


def _zero_per_sample(segments, k: int) -> np.ndarray:
    """The zero segments (starts, zeros) as an (8, k) array: [F; M], set time, resting."""
    starts, zeros = segments
    out = np.empty((8, k))
    for a, b, j in zip(starts, [*starts[1:], k], range(len(starts)), strict=True):
        out[:, a:b] = zeros[:, j : j + 1]
    return out


@pytest.mark.parametrize("split", SPLITS)
def test_the_zero_stage_is_chunk_invariant(desk, upstream, split):
    s = _settings(desk)
    t, raw, flags, lp = upstream["t"], upstream["raw"], upstream["flags"], upstream["lp"].real
    whole_notices: list[Notice] = []
    want = _zero_per_sample(ZeroStage(s, whole_notices).process(t, lp, raw, flags), len(t))
    assert np.isnan(want[0, 0]) and not np.isnan(want[0, -1])  # the tare happened
    notices: list[Notice] = []
    stage = ZeroStage(s, notices)

    def step(b: slice) -> list[np.ndarray]:
        segments = stage.process(t[b], lp[:, b], raw[:, b], flags[b])
        return [_zero_per_sample(segments, b.stop - b.start)]

    got = _in_blocks(len(t), split, step)
    np.testing.assert_array_equal(np.isnan(got[0]), np.isnan(want))
    np.testing.assert_allclose(np.nan_to_num(got[0]), np.nan_to_num(want), atol=1e-9)
    assert [(n.t, n.kind) for n in notices] == [(n.t, n.kind) for n in whole_notices]
    assert "tare" in [n.kind for n in notices]


def test_the_zero_stage_one_sample_twin_judges_window_ends_as_its_block_path(desk, upstream):
    # after the tare, every sample goes through process_one, window ends included (no slow
    # path every 0.2 s): the zero it keeps equals the block path's, sample for sample
    s = _settings(desk)
    t, raw, lp = upstream["t"][:6000], upstream["raw"][:, :6000], upstream["lp"].real[:, :6000]
    flags = np.zeros(len(t), np.uint8)
    want = _zero_per_sample(ZeroStage(s, []).process(t, lp, raw, flags), len(t))
    single = ZeroStage(s, [])
    start = 3000  # well after the tare
    assert not np.isnan(want[0, start])
    single.process(t[:start], lp[:, :start], raw[:, :start], flags[:start])
    got = np.empty((8, len(t) - start))
    for i in range(start, len(t)):
        got[:, i - start] = single.state.column()  # the zero this sample is tared with
        single.process_one(float(t[i]), lp[:, i], raw[:, i])
    np.testing.assert_allclose(got, want[:, start:], atol=1e-12)
    assert len(np.unique(want[6, start:])) > 1  # the zero changed in between (drift followed)


@pytest.mark.parametrize("split", SPLITS)
def test_the_touch_detector_is_chunk_invariant(desk, upstream, split):
    s = _settings(desk)
    f_det = upstream["fast"].real
    mag = np.sqrt(np.einsum("ik,ik->k", f_det, f_det))
    tared = upstream["tared"]
    falling = slope_along(f_det, upstream["release"], mag)
    want = TouchDetector(s).process(f_det, mag, falling, tared)
    assert 0.2 < want.mean() < 0.8  # both states, several switches
    detector = TouchDetector(s)
    got = _in_blocks(
        len(mag), split, lambda b: [detector.process(f_det[:, b], mag[b], falling[b], tared[b])]
    )
    _assert_same(got, [want])


def test_the_touch_detector_one_sample_twin_equals_its_block_path(desk, upstream):
    s = _settings(desk)
    at = np.flatnonzero(upstream["tared"])
    f_det = upstream["fast"].real[:, at]
    mag = np.sqrt(np.einsum("ik,ik->k", f_det, f_det))
    slope, release = upstream["slope"][:, at], upstream["release"][:, at]
    want = TouchDetector(s).process(f_det, mag, slope_along(f_det, release, mag), None)
    single = TouchDetector(s)
    got = [
        single.process_one(f_det[:, i].tolist(), slope[:, i].tolist(), release[:, i].tolist())
        for i in range(len(at))
    ]
    np.testing.assert_array_equal([g[0] for g in got], want)
    np.testing.assert_allclose([g[1] for g in got], mag, rtol=1e-12)
    np.testing.assert_allclose([g[2] for g in got], slope_along(f_det, slope, mag), atol=1e-9)


def _located(desk, upstream, method: str, idx: np.ndarray) -> ContactBlock:
    """The candidate and method stages over the samples ``idx``, in one block."""
    s = _settings(desk, method)
    stage = CandidateStage(s)
    stage.covs = upstream["covs"]
    fast = upstream["fast"]
    f_det = fast.real
    mag = np.sqrt(np.einsum("ik,ik->k", f_det, f_det))[idx]
    inv = 1.0 / np.where(mag > 0, mag, 1.0)
    cands = stage.process(
        unpacked_at(_tared_lp(upstream), idx),
        np.take(upstream["diff"], idx, axis=1),
        unpacked_at(fast, idx),
        f_det[:, idx],
        inv,
        mag,
        upstream["age"][idx] ** 2,
    )
    block = ContactBlock.blank(upstream["t"][idx])
    select(block, np.arange(len(idx)), cands, s)
    return block


def _tared_lp(upstream) -> np.ndarray:
    """The low-passed wrench with the zero taken off (as the estimator tares it)."""
    fast_zero = upstream["det"] - upstream["fast"]  # the zero, packed, per sample
    return upstream["lp"] - fast_zero


def _contact_samples(upstream) -> np.ndarray:
    f_det = upstream["fast"].real
    mag = np.sqrt(np.einsum("ik,ik->k", f_det, f_det))
    good = upstream["tared"] & ((upstream["flags"] & BAD_SAMPLE) == 0)
    return np.flatnonzero(good & (mag > 1.0))


FIELDS = ("located", "surface", "x", "y", "z", "sigma_m", "source")


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("split", ("ones", "sevens", "random"))
def test_the_candidate_and_method_stages_are_chunk_invariant(desk, upstream, method, split):
    idx = _contact_samples(upstream)
    whole = _located(desk, upstream, method, idx)
    assert whole.located.mean() > 0.1  # (`diff` locates only while the force changes)
    if split == "ones":
        idx = idx[::5]  # (the stages keep no state: a fifth is enough)
        whole = whole.take(np.arange(0, len(whole.t), 5))

    def step(b: slice) -> list[np.ndarray]:
        part = _located(desk, upstream, method, idx[b])
        return [getattr(part, f) for f in FIELDS]

    _assert_same(_in_blocks(len(idx), split, step), [getattr(whole, f) for f in FIELDS])


@pytest.mark.parametrize("method", METHODS)
def test_the_candidate_and_method_stages_one_sample_twins_equal_their_block_paths(
    desk, upstream, method
):
    s = _settings(desk, method)
    idx = _contact_samples(upstream)[::3]
    whole = _located(desk, upstream, method, idx)
    stage = CandidateStage(s)
    stage.covs = upstream["covs"]
    wrench = unpacked_at(_tared_lp(upstream), idx)
    diff = unpacked_at(upstream["diff"], idx)
    fast = unpacked_at(upstream["fast"], idx)
    got = ContactBlock.blank(upstream["t"][idx])
    for i in range(len(idx)):
        mag = float(np.linalg.norm(fast[:3, i]))
        inv = 1.0 / mag if mag > 0 else 1.0
        cf, cd, cq, f_mag, motion = stage.process_one(
            wrench[:, i].tolist(), diff[:, i].tolist(), fast[:, i].tolist(), inv,
            float(upstream["age"][idx[i]]),
        )  # fmt: skip
        chosen, source = select_one(cf, cd, cq, f_mag, motion, s)
        if chosen is not None:
            one = got.take(slice(i, i + 1))
            emit_one(one, chosen, source, s.frames)
    assert whole.located.sum() > 100
    _assert_same([getattr(got, f) for f in FIELDS], [getattr(whole, f) for f in FIELDS])
