"""`estimation.zeroed`: readings that come zeroed (a force plate's ZERO frames) are never
tared, and a still load never joins the zero."""

from __future__ import annotations

import numpy as np
import pytest

from hapticdesk.errors import ConfigError
from hapticdesk.estimator import ContactEstimator
from hapticdesk.files.profile import DeskProfile, EstimationSettings, SensorSpec, Surface
from hapticdesk.files.profile_reader import profile_from_mapping
from hapticdesk.files.yamlfile import load_marked_yaml

RATE = 1000.0


def plate(zeroed: bool) -> DeskProfile:
    """A 0.6 m × 0.4 m top on one six-axis sensor 5 cm below its centre."""
    top = Surface(
        "top",
        np.zeros(3),
        np.array([0.0, 0.0, 1.0]),
        np.array([1.0, 0.0, 0.0]),
        np.array([0.0, 1.0, 0.0]),
        np.array([[-0.3, -0.2], [0.3, -0.2], [0.3, 0.2], [-0.3, 0.2]]),
    )
    sensor = SensorSpec("plate1", np.array([0.0, 0.0, -0.05]), np.eye(3))
    settings = EstimationSettings(
        method="force", zeroed=zeroed, noise_force_n=0.3, noise_moment_nm=0.03
    )
    return DeskProfile("plate", RATE, (sensor,), (top,), settings)


def standing(seconds: float, at=(0.12, -0.07), load_n=700.0, seed=1):
    """A person standing still from the first sample on: the sensor's reaction wrench about
    its own origin (5 cm below the top), with noise."""
    k = int(seconds * RATE)
    t = np.arange(k) / RATE
    rng = np.random.default_rng(seed)
    f = np.array([0.0, 0.0, load_n])  # the support pushes up
    r = np.array([at[0], at[1], 0.05])  # the contact, from the sensor
    m = -np.cross(r, -f)  # the reaction balances the foot's moment about the sensor
    wrench = np.tile(np.concatenate([f, m]), (k, 1))
    wrench[:, :3] += rng.normal(0, 0.3, (k, 3))
    wrench[:, 3:] += rng.normal(0, 0.03, (k, 3))
    return t, wrench


def test_a_zeroed_plate_locates_a_person_standing_from_the_start_and_for_long():
    t, wrench = standing(20.0)
    block = ContactEstimator(plate(zeroed=True)).push(t, wrench)
    assert block.located[50:].all()  # (the filters settle in a few ms)
    assert np.allclose(block.x[50:], 0.12, atol=0.002)
    assert np.allclose(block.y[50:], -0.07, atol=0.002)


def test_without_it_the_load_from_the_start_is_tared_away():
    t, wrench = standing(3.0)
    estimator = ContactEstimator(plate(zeroed=False))
    block = estimator.push(t, wrench)
    assert not block.in_contact[-1000:].any()  # what the zeroed setting is for


def test_zeroed_takes_no_tare_and_absorbs_no_still_load():
    t, wrench = standing(20.0)
    estimator = ContactEstimator(plate(zeroed=True))
    estimator.push(t, wrench)
    kinds = {n.kind for n in estimator.notices}
    assert not kinds & {"tare", "tare_refused", "absorbed", "drift"}
    assert estimator.zero is not None and not estimator.zero.any()


def test_zeroed_streams_as_it_batches():
    t, wrench = standing(2.0, seed=4)
    whole = ContactEstimator(plate(zeroed=True)).push(t, wrench)
    streamed = ContactEstimator(plate(zeroed=True))
    parts, start = [], 0
    rng = np.random.default_rng(0)
    while start < len(t):
        end = min(len(t), start + int(rng.integers(1, 40)))
        # (push returns a view, valid till the next push)
        parts.append(streamed.push(t[start:end], wrench[start:end]).copy())
        start = end
    x = np.concatenate([p.x for p in parts])
    assert np.array_equal(np.concatenate([p.located for p in parts]), whole.located)
    assert np.allclose(x[whole.located], whole.x[whole.located], atol=1e-9)


def test_a_profile_that_says_zeroed_must_give_the_noise(tmp_path):
    path = tmp_path / "plate.yaml"
    path.write_text(
        "name: p\nsample_rate_hz: 1000\nsensors: [{name: s, position: [0, 0, -0.05]}]\n"
        "estimation: {zeroed: true}\n"
    )
    with pytest.raises(ConfigError, match=r"plate.yaml:4:\d+: `zeroed: true`.*noise_force_n"):
        profile_from_mapping(load_marked_yaml(path), path)
    path.write_text(
        "name: p\nsample_rate_hz: 1000\nsensors: [{name: s, position: [0, 0, -0.05]}]\n"
        "estimation: {zeroed: true, noise_force_n: 0.3, noise_moment_nm: 0.02}\n"
    )
    assert profile_from_mapping(load_marked_yaml(path), path).estimation.zeroed
