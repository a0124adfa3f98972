"""The methods compared on the paper's experiment, simulated with the paper's noise.

Judged on samples chosen from the truth (hapticdesk.bench.accuracy), pooled over four
sessions (seeds: each a different draw of the human and of the sensors' drift), as the paper
pools its subjects. Two settings:
- the paper's: the zero is taken once at the start and never followed (paper §2), where the
  force-based point diverges at release and the switched method helps (paper Fig. 12, 14);
- ours (the default): the zero follows sensor drift whenever the desk is idle.
"""

from dataclasses import replace

import numpy as np
import pytest

from hapticdesk.bench.accuracy import find_presses, measure_accuracy
from hapticdesk.estimator import ContactEstimator
from hapticdesk.sim import load_scene, simulate

SCENE = "examples/scenes/paper-experiment.yaml"


SEEDS = (10, 11, 12, 13)


@pytest.fixture(scope="module")
def sessions(paper_desk):
    from pathlib import Path

    scene = load_scene(Path(__file__).parents[2] / SCENE)
    return [simulate(paper_desk, scene, seed=seed) for seed in SEEDS]


def run(desk, rec, method, **settings):
    est = ContactEstimator(desk, method=method, settings=replace(desk.estimation, **settings))
    return est.push(rec.t, rec.wrench)


def test_switched_beats_force_at_release_with_the_papers_tare(paper_desk, sessions):
    paper = {"drift_settle_s": 0.0}  # the paper's tare: once, at the start
    release = {"force": [], "switched": []}
    for rec in sessions:
        for method, errors in release.items():
            acc = measure_accuracy(run(paper_desk, rec, method, **paper), rec.extra)
            assert acc.presses == 27 and acc.missed == 0
            assert acc.release.coverage > 0.99
            errors.append(acc.release.errors_m)
    p95 = {m: np.percentile(np.concatenate(e), 95) for m, e in release.items()}
    assert p95["switched"] < 0.8 * p95["force"], p95


@pytest.mark.parametrize("follow_drift", [True, False])
def test_fused_is_no_worse_than_switched_anywhere_and_better_at_touch(
    paper_desk, sessions, follow_drift
):
    settings = {} if follow_drift else {"drift_settle_s": 0.0}
    # per phase (touch, hold, release): errors on the samples both methods locate, and counts
    common: dict[int, dict[str, list]] = {c: {"switched": [], "fused": []} for c in (1, 2, 3)}
    located = {c: {"switched": 0, "fused": 0} for c in (1, 2, 3)}
    for rec in sessions:
        truth = rec.extra
        blocks = {m: run(paper_desk, rec, m, **settings) for m in ("switched", "fused")}
        phase = np.zeros(len(rec.t), int)
        for p in find_presses(truth["true_fn"]):
            phase[p.start : p.half_up], phase[p.half_up : p.half_down] = 1, 2
            phase[p.half_down : p.stop] = 3
        for code in (1, 2, 3):
            both = blocks["switched"].located & blocks["fused"].located & (phase == code)
            for m, b in blocks.items():
                err = np.hypot(b.x - truth["true_x"], b.y - truth["true_y"])
                common[code][m].append(err[both])
                located[code][m] += int((b.located & (phase == code)).sum())
    for code in (1, 2, 3):
        p95 = {m: np.percentile(np.concatenate(e), 95) for m, e in common[code].items()}
        assert p95["fused"] <= p95["switched"], (code, p95)
        if code == 1:
            assert p95["fused"] < 0.9 * p95["switched"], p95  # better at touch
        if follow_drift:  # and it reports as much of every phase: with the sway compensated
            # (the default for `fused`) its correction's noise leaves 2 of 17,420 release
            # samples over `max_sigma_m` that `switched` reports; a tenth of a per cent fewer
            # in any phase fails
            assert located[code]["fused"] >= 0.999 * located[code]["switched"], (code, located)
