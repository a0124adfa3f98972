"""The golden test: the estimator's outputs stay what they were when the file was recorded.

``tests/core/data/golden_contacts.npz`` holds every field of the contacts of every method, its
notices and the candidates it traces, on short scenes of every desk it is judged on
(scripts/golden_contacts.py lists them: the paper's desk, a shelf, ordinary use, the
accelerometer desks with their readings, lossy and missing, the upright panel, the unseen
desks, objects, a second finger, hostile input, ideal and quiet sensors), recorded from
main b5a43bd by ``python scripts/golden_contacts.py --write ... --short``. A push of 1 or 7
samples is recorded only where it differed from the batch there; where single samples have
a record, it judges every push size (``check_golden`` says why).
A change that means to alter the outputs records the file anew, in its own commit, and says
why; a refactor must leave it equal to 1e-9 (relative above 1), in batch and in 1- and
7-sample pushes.

Re-recorded since: ``sigma_m`` alone (76 arrays, every scene whose sensors round their
readings), from branch sigma: the located 1-σ now holds the zero's rounding offset
(estimator/resolution.py ``zero_rounding``, issue 33), added after the method has chosen and
weighed its candidates; positions, forces, located and every other field are as recorded.
Again ``sigma_m`` alone (58 arrays), from branch sigma: each channel's share of that offset
is what a press keeps of it (``moved_share``: a channel the press does not move keeps none).
Again ``sigma_m`` alone (68 arrays), from branch sigma: that share is the exact variance of
the change of the rounding's bias under the noise (quadratic in a small change), and the
noise is the likeliest for all quiet channels' rest changes (``zero_rounding_noise``).
Again ``sigma_m`` alone (55 arrays), from branch sigma2: the kernel reuses the floor's sums
over the channels while the tared wrench stays within 2 % of where they were made
(estimator/kernel_rounding.py) and reads each share off a table: σ within 9 % of the exact
per-sample floor on these scenes, 99 % of samples within 2.5 % (the most on ``fused``, whose
fast wrench moves the most between samples).
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
GOLDEN = Path(__file__).parent / "data" / "golden_contacts.npz"


def _golden_module():
    spec = importlib.util.spec_from_file_location(
        "golden_contacts", ROOT / "scripts" / "golden_contacts.py"
    )
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["golden_contacts"] = module  # (its dataclasses look their module up)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def golden():
    return _golden_module()


def test_outputs_equal_the_golden_file_in_batch_and_pushes(golden):
    now = golden.golden_outputs(short=True, pushes=True)
    with np.load(GOLDEN) as stored_file:
        stored = dict(stored_file)
    assert stored, "the golden file is empty"
    assert golden.check_golden(now, stored) == []


def test_the_check_sees_a_change(golden):
    stored = {"a/force/batch/x": np.array([0.1, 20.0]), "a/force/batch/phase": np.array([1, 2])}
    assert golden.check_golden(dict(stored), stored) == []
    moved = {
        "a/force/batch/x": np.array([0.1 + 2e-9, 20.0]),
        "a/force/batch/phase": stored["a/force/batch/phase"],
    }
    assert golden.check_golden(moved, stored) == ["a/force/batch/x: differs by up to 2e-09"]
    # relative above 1: 20 moved by 1e-8 is 5e-10 of it
    assert (
        golden.check_golden({**stored, "a/force/batch/x": np.array([0.1, 20 + 1e-8])}, stored) == []
    )
    # a push is judged against the batch's record unless single samples have their own, which
    # then judges every push size (the batch too)
    pushed = {"a/force/7/phase": np.array([1, 3])}
    assert golden.check_golden(pushed, stored) == [
        "a/force/batch/x: missing",
        "a/force/batch/phase: missing",
        "a/force/7/phase: 1 values differ",
    ]
    single = {**stored, "a/force/1/phase": np.array([1, 3])}
    assert golden.check_golden(pushed, single)[2:] == []
    assert golden.check_golden(stored, single) == ["a/force/batch/phase: 1 values differ"]
