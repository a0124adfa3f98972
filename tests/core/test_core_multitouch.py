"""A second finger on the simulated desk: found from the change of wrench when it lands."""

from __future__ import annotations

import numpy as np

from hapticdesk.estimator import ContactEstimator
from hapticdesk.estimator.contacts import FLAG_MULTI
from hapticdesk.estimator.multitouch import mark_second_touches
from hapticdesk.files.profile import load_profile
from hapticdesk.sim import Scene, simulate
from hapticdesk.sim.actions import Press, Step, Tap

PAIRS = [  # first finger (a press, held from ≈0.45 s on), second finger, its delay (s)
    ((-0.2, 0.0), (0.0, 0.1), 0.6),
    ((0.1, -0.1), (0.25, 0.05), 0.7),
    ((0.3, 0.15), (0.1, 0.15), 0.8),
    ((-0.3, -0.15), (-0.25, 0.1), 0.65),
    ((0.0, 0.0), (-0.1, -0.15), 0.9),
    ((0.2, 0.2), (0.2, -0.05), 0.75),
]
SPACING_S = 4.0


def test_second_fingers_are_found_and_located_single_touches_are_not_flagged():
    desk = load_profile("kitamura2017")
    steps: list[Step] = []
    starts = []
    for i, (p1, p2, delay) in enumerate(PAIRS):
        start = 2.0 + i * SPACING_S
        starts.append(start)
        steps += [Press(point=p1, hold_s=1.5, start_s=start), Tap(point=p2, start_s=start + delay)]
    singles = []
    for i, (p1, _, _) in enumerate(PAIRS):
        start = 2.0 + (len(PAIRS) + i) * SPACING_S
        singles.append(start)
        single: Step = Press(point=p1, start_s=start) if i % 2 else Tap(point=p1, start_s=start)
        steps.append(single)
    rec = simulate(desk, Scene(steps, seed=4, tail_s=2.0))
    t = rec.t
    block = ContactEstimator(desk).push(rec.t, rec.wrench)
    found = mark_second_touches(desk, t, rec.wrench, block)
    flagged = (block.flags & FLAG_MULTI) != 0
    assert np.array_equal(flagged, found.multi)
    assert not (flagged & ~block.in_contact).any()
    errors = []
    for start, (_, p2, _) in zip(starts, PAIRS, strict=True):
        hit = found.multi & (t >= start) & (t < start + SPACING_S)
        if hit.any():
            i = np.flatnonzero(hit)[0]
            errors.append(np.hypot(found.x2[i] - p2[0], found.y2[i] - p2[1]))
    print(
        f"[multitouch] {len(errors)}/{len(PAIRS)} found, second finger errors (mm): "
        f"{np.round(np.array(errors) * 1e3, 1)}"
    )
    assert len(errors) >= len(PAIRS) - 1
    assert np.median(errors) < 0.05  # rough: the first finger's own change mixes in
    for start in singles:
        assert not found.multi[(t >= start) & (t < start + SPACING_S)].any()
