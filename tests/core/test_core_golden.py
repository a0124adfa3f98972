"""The golden test: the estimator's outputs stay what they were when the file was recorded.

``tests/core/data/golden_contacts.npz`` holds every field of the contacts of every method on
short paper, shelf and day scenes and on desks with one and three accelerometers
(``python scripts/golden_contacts.py --write ... --short``).
A change that means to alter the outputs records the file anew, in its own commit, and says
why; a refactor must leave it equal to 1e-9, in batch and in 1- and 7-sample pushes.
"""

from __future__ import annotations

import importlib.util
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
    problems = golden.check_golden(now, stored)
    # pushes of 1 and 7 samples must give what the batch gave
    for key, values in now.items():
        if "/batch/" in key:
            continue
        batch_key = key.replace("/1/", "/batch/").replace("/7/", "/batch/")
        problems += golden.check_golden({key: values}, {key: stored[batch_key]})
    assert problems == []


def test_the_check_sees_a_change(golden):
    stored = {"a/force/batch/x": np.array([0.1, 0.2]), "a/force/batch/phase": np.array([1, 2])}
    assert golden.check_golden(dict(stored), stored) == []
    moved = {
        "a/force/batch/x": np.array([0.1, 0.2 + 1e-8]),
        "a/force/batch/phase": stored["a/force/batch/phase"],
    }
    assert golden.check_golden(moved, stored) == ["a/force/batch/x: differs by up to 1e-08"]
