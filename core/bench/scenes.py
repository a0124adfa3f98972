"""The scenes the benchmark runs, built in code so ``hapticdesk bench`` works from any install.

They are the same as examples/scenes/paper-experiment.yaml and kita.yaml.
"""

from __future__ import annotations

import numpy as np

from hapticdesk.sim import Action, Idle, Press, Scene, Stroke, Swipe, Tap, text_paths

# paper §5.1, Fig. 6: nine points 0.3 m by 0.2 m apart around the centre, three presses each
PAPER_POINTS = [(x, y) for y in (0.2, 0.0, -0.2) for x in (-0.3, 0.0, 0.3)]


def paper_experiment() -> Scene:
    """Nine points, three presses each (27 presses, about 90 s)."""
    actions: list[Action] = [
        Press(point=p, label=f"p{i + 1}") for i, p in enumerate(PAPER_POINTS) for _ in range(3)
    ]
    return Scene(actions=actions, quiet_s=2.0, name="paper-experiment")


def kita() -> Scene:
    """北 traced on the top board, 30 cm tall (paper Fig. 15)."""
    actions: list[Action] = []
    for i, path in enumerate(text_paths("北", center=(0.0, 0.0), size=0.3)):
        actions.append(
            Stroke(path=tuple(map(tuple, path)), label=f"kita-{i + 1}", wait_s=0.6 if i else None)
        )
    return Scene(actions=actions, quiet_s=2.0, name="kita")


def desk_day(minutes: float = 10.0, seed: int = 0) -> Scene:
    """Ordinary use: a touch every 5–15 s (taps, presses, swipes) on an otherwise idle desk,
    about a tenth of the time in contact — the load a desk in a living room sees."""
    rng = np.random.default_rng(seed)
    actions: list[Action] = []
    elapsed = 0.0
    while elapsed < minutes * 60:
        pause = float(rng.uniform(5.0, 15.0))
        actions.append(Idle(duration_s=pause))
        x, y = float(rng.uniform(-0.3, 0.3)), float(rng.uniform(-0.2, 0.2))
        kind = rng.integers(3)
        if kind == 0:
            actions.append(Tap(point=(x, y)))
        elif kind == 1:
            actions.append(Press(point=(x, y)))
        else:
            actions.append(Swipe(from_point=(x, y), to_point=(-x * 0.5, y)))
        elapsed += pause + 1.5
    return Scene(actions=actions, quiet_s=2.0, name="desk-day")
