"""What the browser UI costs the sensing loop: estimator + gestures per block, with 0 and 2
browsers connected, side by side in one run.

    python scripts/ui_cost.py [--phase-s 8] [--rounds 3] [--json]

A simulated desk (the paper's, 1.2 kHz) taps the buttons of examples/layouts/buttons.yaml in
real time (speed 1) while the UI server runs in its own thread. Phases alternate: no browser,
then two headless Chromium pages on the live view, `--rounds` times. Every estimator push and
gesture-engine feed on the sensing thread is timed; per phase the script prints the median,
p99 and max per block, the blocks that came late (the sensing thread behind the source's
pace), and how many contact frames each browser received per second.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CHROMIUM = "/usr/bin/chromium"
ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]


class Timed:
    """Wraps the estimator's ``push`` or the engine's ``feed``: time each call into the
    current phase's list."""

    def __init__(self, inner: Any, method: str, sink: dict[str, list[float]], phase: list[str]):
        self._inner, self._method, self._sink, self._phase = inner, method, sink, phase

    def __getattr__(self, name: str) -> Any:
        attr = getattr(self._inner, name)
        if name != self._method:
            return attr

        def timed(*args: Any) -> Any:
            t0 = time.perf_counter()
            out = attr(*args)
            self._sink.setdefault(self._phase[0], []).append(time.perf_counter() - t0)
            return out

        return timed


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--phase-s", type=float, default=8.0)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()

    from playwright.sync_api import sync_playwright

    from hapticdesk.plugin_loading import load_registry
    from hapticdesk.plugins.ui.server import UiServer
    from hapticdesk.runtime.assembly import build_scene
    from hapticdesk.runtime.lane import Lane
    from hapticdesk.runtime.service import Runtime

    total_s = 3 + 2 * args.rounds * args.phase_s + 5
    folder = Path(tempfile.mkdtemp(prefix="ui_cost"))
    scene_path = folder / "taps.yaml"
    points = [(-8, 8), (0, 0), (8, -8), (0, 8), (-8, -8)]
    n_taps = int(total_s / 0.6) + 5
    scene_path.write_text(
        "name: ui-cost\ndesk: kitamura2017\nunits: cm\nquiet_s: 2.0\ntimeline:\n"
        + "".join(
            f"  - tap: {{point: [{points[i % 5][0]}, {points[i % 5][1]}], wait_s: 0.3}}\n"
            for i in range(n_taps)
        )
    )
    layout = ROOT / "examples" / "layouts" / "buttons.yaml"
    registry = load_registry()
    scene = build_scene(layout, f"sim:{scene_path}", registry, speed=1.0, actions=False)
    server = UiServer(layout, registry, port=0, read_only=True)
    scene.dispatcher.add_sink(Lane("every event → ui", server.on_gesture))
    phase = ["warm-up"]
    estimator_s: dict[str, list[float]] = {}
    gestures_s: dict[str, list[float]] = {}
    scene.estimator = Timed(scene.estimator, "push", estimator_s, phase)
    scene.engine = Timed(scene.engine, "feed", gestures_s, phase)
    server.start()
    runtime = Runtime(scene, drain_timeout_s=0.5)
    server.attach(runtime)
    sensing = threading.Thread(target=runtime.run, kwargs={"handle_signals": False}, daemon=True)
    sensing.start()
    received: dict[str, list[float]] = {}
    published: dict[str, list[float]] = {}
    dropped: dict[str, list[int]] = {}
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        time.sleep(3.0)  # the tare
        for r in range(args.rounds):
            for label in ("0 browsers", "2 browsers"):
                pages = []
                contexts = []
                if label == "2 browsers":
                    for _ in range(2):
                        c = browser.new_context()
                        pg = c.new_page()
                        pg.goto(server.url)
                        pg.wait_for_selector("#region-b5")
                        contexts.append(c)
                        pages.append(pg)
                    time.sleep(0.5)
                counts0 = [pg.evaluate("window.hapticdeskStats.contacts") for pg in pages]
                published0, dropped0 = server.hub.contacts_published, server.hub.contacts_dropped
                phase[0] = label
                t0 = time.monotonic()
                time.sleep(args.phase_s)
                elapsed = time.monotonic() - t0
                phase[0] = "between"
                published.setdefault(label, []).append(
                    (server.hub.contacts_published - published0) / elapsed
                )
                dropped.setdefault(label, []).append(server.hub.contacts_dropped - dropped0)
                for pg, c0 in zip(pages, counts0, strict=True):
                    n = pg.evaluate("window.hapticdeskStats.contacts") - c0
                    received.setdefault(label, []).append(n / elapsed)
                for c in contexts:
                    c.close()
                print(f"round {r + 1}: {label} done", file=sys.stderr)
        browser.close()
    runtime.stop()
    sensing.join(10)
    server.close()

    results = {}
    for label in ("0 browsers", "2 browsers"):
        est = np.array(estimator_s.get(label, [])) * 1e6
        ges = np.array(gestures_s.get(label, [])) * 1e6
        both = est + ges[: len(est)] if len(ges) >= len(est) else est[: len(ges)] + ges
        results[label] = {
            "blocks": int(len(both)),
            "estimator_us_median": round(float(np.median(est)), 1),
            "gestures_us_median": round(float(np.median(ges)), 1),
            "per_block_us_median": round(float(np.median(both)), 1),
            "per_block_us_p99": round(float(np.percentile(both, 99)), 1),
            "per_block_us_max": round(float(both.max()), 1),
            "contact_frames_per_s_per_browser": round(statistics.mean(received[label]), 1)
            if received.get(label)
            else 0.0,
            "contact_frames_per_s_published": round(statistics.mean(published[label]), 1),
            "contact_frames_dropped": int(sum(dropped[label])),
        }
    if args.json:
        print(json.dumps(results))
    else:
        print(
            f"{'':<12} {'blocks':>7} {'est µs':>7} {'gest µs':>8} {'median':>7} {'p99':>7} "
            f"{'max':>8} {'frames/s':>9} {'published/s':>11} {'dropped':>7}"
        )
        for label, r in results.items():
            print(
                f"{label:<12} {r['blocks']:>7} {r['estimator_us_median']:>7} "
                f"{r['gestures_us_median']:>8} {r['per_block_us_median']:>7} "
                f"{r['per_block_us_p99']:>7} {r['per_block_us_max']:>8} "
                f"{r['contact_frames_per_s_per_browser']:>9} "
                f"{r['contact_frames_per_s_published']:>11} {r['contact_frames_dropped']:>7}"
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
