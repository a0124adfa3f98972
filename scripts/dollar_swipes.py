#!/usr/bin/env python3
"""Real people's strokes as swipes nobody made: the $1 logs (../shared/data/dollar1, 2,400
strokes by five people), each traced on a simulated desk at its logged speed, through a
layout with `stroke` and `swipe` both bound anywhere. A stroke that fires a swipe is a
gesture nobody made (the person drew a shape).

    python scripts/dollar_swipes.py [--desk PROFILE] [--every 10] [--data DIR]
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from hapticdesk.estimator import ContactEstimator, estimate
from hapticdesk.files.profile_reader import load_profile
from hapticdesk.gestures.engine import GestureEngine
from hapticdesk.gestures.layout_reader import load_layout
from hapticdesk.gestures.strokes.dollar_logs import read_logs
from hapticdesk.sim import Idle, Scene, Stroke, simulate

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "dollar1"
PER_SCENE = 20  # strokes simulated in one scene


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--desk", default="kitamura2017", help="desk profile: name or path")
    parser.add_argument("--every", type=int, default=10, help="take every Nth logged stroke")
    parser.add_argument("--data", default=str(DATA), help="the $1 logs' folder")
    args = parser.parse_args()
    desk = load_profile(args.desk)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "layout.yaml"
        path.write_text(
            f"desk: {desk.name}\nbindings:\n  - {{gesture: swipe, do: log}}\n"
            "  - {gesture: stroke, do: log}\n"
        )
        layout = load_layout(path, profile=desk)
    logs = list(read_logs(args.data))[:: args.every]
    speeds, swipes, shapes = [], 0, 0
    for first in range(0, len(logs), PER_SCENE):
        actions: list = []
        for stroke in logs[first : first + PER_SCENE]:
            points = stroke.points - stroke.points.mean(axis=0)
            length = float(np.hypot(*np.diff(points, axis=0).T).sum())
            duration = float(stroke.t[-1]) if stroke.t[-1] > 0 else 1.0
            speeds.append(float(np.clip(length / duration, 0.02, 1.5)))  # the person's speed
            path_m = tuple((float(x), float(y)) for x, y in points)
            actions += [Stroke(path=path_m, speed=speeds[-1]), Idle(duration_s=1.5)]
        rec = simulate(desk, Scene(actions=actions, seed=first), seed=first)
        contacts = estimate(desk, rec)
        engine = GestureEngine(layout, position_delay_s=ContactEstimator(desk).position_delay_s)
        events = engine.feed(contacts) + engine.flush(float(contacts.t[-1]))
        swipes += sum(e.gesture == "swipe" for e in events)
        shapes += sum(e.gesture == "stroke" and e.shape is not None for e in events)
    print(
        f"{desk.name}: {len(logs)} real strokes (speed median {np.median(speeds):.2f} m/s, "
        f"p90 {np.percentile(speeds, 90):.2f}); swipes fired {swipes}, shapes {shapes}"
    )


if __name__ == "__main__":
    main()
