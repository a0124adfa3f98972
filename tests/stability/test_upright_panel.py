"""Issue 15, item 4: a desk with an upright front panel (``kitamura2017-panel``), on the
simulator with its dynamics (the desk sways at 5.9 Hz) and the paper's noise.

A press on the panel, or a hand pushing the desk, is a horizontal force: it rings the sway,
and the ring is a force along the panel's normal. Measured figures: docs/stability.md,
"Upright panels and sideways pushes" (``python scripts/touch_release_eval.py``).
"""

from __future__ import annotations

import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from hapticdesk.bench.accuracy import find_presses
from hapticdesk.estimator import ContactEstimator, estimate
from hapticdesk.estimator import kernel_slots as slots
from hapticdesk.estimator.detector import upright_surfaces
from hapticdesk.files.profile_reader import load_profile
from hapticdesk.gestures.engine import GestureEngine
from hapticdesk.gestures.layout_reader import load_layout
from hapticdesk.sim import LongPress, Scene, Tap, simulate

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "scripts"))
import touch_release_eval as evaluation  # noqa: E402


def contact_starts(in_contact: np.ndarray) -> int:
    """How many contacts begin in ``in_contact``."""
    return int(np.count_nonzero(in_contact & ~np.concatenate([[False], in_contact[:-1]])))


def guard(est: ContactEstimator) -> np.ndarray:
    """The ring guard of each upright surface (N), from the estimator's state."""
    at, n = int(est.params.pi[slots.I_SO_GUARD]), int(est.params.pi[slots.I_N_UP])
    return est.state.sf[at : at + n].copy()


@pytest.fixture(scope="module")
def pushes():
    """The side and back pushes (5–30 N, slow and quick) simulated on the panel desk."""
    pushed = evaluation.panel_desk(with_push_faces=True)
    return simulate(pushed, evaluation.sideways_pushes(), seed=0)


@pytest.mark.parametrize("method", ["switched", "fused"])
def test_sideways_pushes_make_no_phantom_touch(pushes, method) -> None:
    """Before the ring guard: 24 contacts per seed from 12 pushes (the sway's swings towards
    the panel, 2–9 N); now none, on the block path and sample by sample."""
    panel = evaluation.panel_desk()
    assert pushes.extra["true_fn"].max() >= 29.0  # the pushes are there (30 N at most)
    block = ContactEstimator(panel, method=method).push(pushes.t, pushes.wrench)
    assert contact_starts(block.in_contact) == 0
    assert not block.located.any()


def test_sideways_pushes_make_no_phantom_touch_with_three_accelerometers() -> None:
    """The compensation removes the sway the pushes excite; it must not make a touch of
    what is left (the same pushes on the desk with three accelerometers, readings used)."""
    from hapticdesk.estimator.inertia import accelerometer_readings

    pushed = evaluation.panel_desk(with_push_faces=True, name="kitamura2017-panel-accel")
    rec = simulate(pushed, evaluation.sideways_pushes(), seed=1)
    desk = evaluation.panel_desk(name="kitamura2017-panel-accel")
    accel = accelerometer_readings(desk, rec.extra)
    assert accel is not None
    for method in ("switched", "fused"):
        block = ContactEstimator(desk, method=method).push(rec.t, rec.wrench, accel)
        assert contact_starts(block.in_contact) == 0
        assert not block.located.any()


def test_sample_by_sample_the_guard_holds_the_same(pushes) -> None:
    """The single-sample path keeps the same guard as the block path."""
    panel = evaluation.panel_desk()
    back = int(np.argmax(pushes.extra["true_fy"] < -4.0))  # the first push on the back
    part = slice(back - 1200, back + 6000)  # it and its ring
    t, w = pushes.t[: part.stop], pushes.wrench[: part.stop]
    whole = ContactEstimator(panel)
    block = whole.push(t, w)
    one = ContactEstimator(panel)
    one.push(t[: part.start], w[: part.start])
    singles = [
        one.push(t[k : k + 1], w[k : k + 1]).in_contact[0] for k in range(part.start, part.stop)
    ]
    assert np.array_equal(np.array(singles), block.in_contact[part])
    assert max(guard(whole)) > 0.5  # the guard is up, decaying
    assert np.allclose(guard(one), guard(whole), rtol=1e-9)


def test_the_guard_is_the_same_for_any_split_into_blocks(pushes) -> None:
    """The ring guard is state carried from block to block: one pass equals any split."""
    panel = evaluation.panel_desk()
    n = int(40.0 * 1200)  # side and back pushes and their ring
    t, w = pushes.t[:n], pushes.wrench[:n]
    whole = ContactEstimator(panel)
    expected = whole.push(t, w).in_contact
    rng = np.random.default_rng(7)
    cuts = np.sort(rng.choice(np.arange(1, n), size=40, replace=False))
    split = ContactEstimator(panel)
    parts = [
        split.push(t[a:b], w[a:b]).in_contact.copy()
        for a, b in zip([0, *cuts], [*cuts, n], strict=True)
    ]
    assert np.array_equal(np.concatenate(parts), expected)
    assert np.allclose(guard(split), guard(whole), rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("seed", [0, 1])
def test_presses_on_the_panel_touch_down_once_each(seed) -> None:
    """The guard does not hold back a press: every press and every tap of 3.5 N or more on
    the panel is one contact, and no contact is more (before the guard the ring after each
    one made 82–96 more per 36). Light taps (2–3.1 N) within a second of another touch can
    be lost in the ring of its release: 4 of 72 here."""
    panel = evaluation.panel_desk()
    scene = evaluation.presses_and_taps(evaluation.PANEL_POINTS, "panel", surface="front")
    rec = simulate(panel, scene, seed=seed)
    block = ContactEstimator(panel).push(rec.t, rec.wrench)
    presses = find_presses(rec.extra["true_fn"])
    felt = [bool(block.in_contact[p.start : p.stop + 60].any()) for p in presses]
    assert all(f for f, p in zip(felt, presses, strict=True) if p.peak_n >= 3.5)
    assert sum(felt) >= len(presses) - 3
    assert contact_starts(block.in_contact) == sum(felt)


def test_the_top_of_a_desk_without_a_panel_is_not_guarded() -> None:
    """No upright surface, no guard: the paper desk's detector is unchanged."""
    assert (
        upright_surfaces(ContactEstimator(load_profile("kitamura2017")).stage_settings.normals)
        == []
    )
    assert upright_surfaces(ContactEstimator(evaluation.panel_desk()).stage_settings.normals) == [1]


@pytest.fixture(scope="module")
def panel_layout(tmp_path_factory):
    path = tmp_path_factory.mktemp("panel") / "layout.yaml"
    path.write_text(
        textwrap.dedent(
            """
            desk: kitamura2017-panel
            regions:
              left: {rect: [-0.35, -0.08, -0.15, 0.08], surface: front}
              mid: {rect: [-0.1, -0.08, 0.1, 0.08], surface: front}
              right: {rect: [0.15, -0.08, 0.35, 0.08], surface: front}
            bindings:
              - {gesture: long_press, region: left, do: log}
              - {gesture: long_press, region: mid, do: log}
              - {gesture: long_press, region: right, do: log}
              - {gesture: tap, region: left, do: log}
              - {gesture: tap, region: mid, do: log}
              - {gesture: tap, region: right, do: log}
            """
        )
    )
    return load_layout(path)


def recognise(layout, scene: Scene, seed: int, desk_name: str = "kitamura2017-panel"):
    """Gestures from the simulated ``scene`` on the panel desk (``desk_name``: the same desk,
    ``kitamura2017-panel-accel`` with three accelerometers whose readings are used)."""
    desk = load_profile(desk_name)
    rec = simulate(desk, scene, seed=seed)
    contacts = estimate(desk, rec)
    engine = GestureEngine(layout, position_delay_s=ContactEstimator(desk).position_delay_s)
    return engine.feed(contacts) + engine.flush(float(contacts.t[-1]))


@pytest.mark.parametrize("seed", [0, 1])
def test_a_long_press_in_the_panels_middle_fires_and_nothing_else(panel_layout, seed) -> None:
    """End to end (scene → estimator → gestures): before the ring guard the same scene also
    fired 2–8 phantom taps in `mid` from the ring after each press."""
    scene = Scene(
        actions=[
            LongPress(point=(0.0, 0.0), surface="front", hold_s=2.5),
            LongPress(point=(0.0, 0.02), surface="front", hold_s=2.5, wait_s=1.5),
        ]
    )
    events = recognise(panel_layout, scene, seed)
    assert [(e.gesture, e.region) for e in events] == [("long_press", "mid")] * 4
    assert [e.phase for e in events][1::2] == ["end", "end"]


NO_ROTATION = pytest.mark.xfail(
    strict=True,
    reason="without accelerometers off the panel's middle the sway's yaw (10 Hz) puts the "
    "first points 1–4 cm off, so the hold is cancelled and taps miss their region",
)


@pytest.mark.parametrize(
    ("desk_name", "seed"),
    [
        pytest.param("kitamura2017-panel", 0, marks=NO_ROTATION),
        ("kitamura2017-panel-accel", 0),
        ("kitamura2017-panel-accel", 1),
    ],
)
def test_long_presses_and_taps_off_the_panels_middle_fire(panel_layout, desk_name, seed) -> None:
    """Issue 15 item 4: with three accelerometers (the desk's rotation measured and its
    inertial wrench removed) gestures anywhere on the panel fire, and nothing else."""
    scene = Scene(
        actions=[
            LongPress(point=(-0.25, 0.0), surface="front", hold_s=2.5),
            Tap(point=(0.25, 0.0), surface="front", peak_n=5.0, wait_s=2.0),
            LongPress(point=(0.28, -0.05), surface="front", hold_s=2.0, wait_s=1.5),
            Tap(point=(-0.28, 0.05), surface="front", peak_n=4.0, wait_s=2.0),
        ]
    )
    events = recognise(panel_layout, scene, seed, desk_name)
    assert [(e.gesture, e.region, e.phase) for e in events] == [
        ("long_press", "left", None),
        ("long_press", "left", "end"),
        ("tap", "right", None),
        ("long_press", "right", None),
        ("long_press", "right", "end"),
        ("tap", "left", None),
    ]
