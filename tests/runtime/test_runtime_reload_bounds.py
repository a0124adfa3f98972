"""Reloads: atomic with respect to touches, and bounded in what they keep (issue 30, items 3
and 4).

On b5a43bd an MQTT `reload`, SIGHUP or a save from the page during a 3 s hold made a second
long press and three extra presses (the new engine saw the held finger as a new touch), and
every reload kept its replaced lanes for good: 751 reloads, +16 MB."""

from __future__ import annotations

import gc
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from hapticdesk.hookspecs import hookimpl
from hapticdesk.plugin_loading import load_registry
from hapticdesk.runtime.assembly import build_scene
from hapticdesk.runtime.dispatcher import MAX_RETIRED_LABELS
from hapticdesk.runtime.layout_reload import MAX_SWAP_WAIT_S
from hapticdesk.runtime.service import Runtime
from hapticdesk.runtime.source import Source, WrenchBlock

from .scripted import answer_into, rss_kb, scripted_run
from .taps import Tap, tap_recording

HOLD_LAYOUT = """\
desk: kitamura2017
units: cm
regions:
  lamp: {rect: [-35, -22, 35, 22]}
bindings:
  - {gesture: long_press, region: lamp, hold_s: 1.0, do: {log: {}}}
  - {gesture: press, region: lamp, do: {log: {}}}
  - {gesture: tap, region: lamp, do: {log: {}}}
"""


def _events(tmp_path: Path, paper_desk, taps: list[Tap], script: dict, seconds: float):
    path = tmp_path / "hold.yaml"
    path.write_text(HOLD_LAYOUT)
    answers: list[str] = []
    runtime, events = scripted_run(
        path,
        tap_recording(paper_desk, taps, seconds),
        {
            t: (lambda rt, c=c: rt.request(c).add_done_callback(answer_into(answers)))
            for t, c in script.items()
        },
        tmp_path / "events.jsonl",
    )
    return [(e["gesture"], e.get("phase"), e.get("level")) for e in events], answers, runtime


HOLD = [Tap(1.5, 0.0, 0.0, duration_s=3.0, peak_n=12.0), Tap(6.0, 0.05, 0.0)]


def test_a_reload_during_a_3_s_hold_fires_exactly_one_long_press(tmp_path, paper_desk):
    """Guards item 3: a reload in the middle of a 3 s hold changes nothing of what that
    touch fires (one long press, its presses once), says it waits for the touch, and the
    next touch is recognised by the reloaded layout (b5a43bd: a second long press and three
    extra presses)."""
    alone, _, _ = _events(tmp_path, paper_desk, HOLD, {}, 8.0)
    assert alone.count(("long_press", None, None)) == 1
    reloaded, answers, runtime = _events(tmp_path, paper_desk, HOLD, {3.0: "reload"}, 8.0)
    assert reloaded == alone
    [answer] = answers
    assert answer.endswith("it takes over when the touch in progress ends")
    assert runtime.reloads.waiting is None  # taken over once the hold ended


def test_a_reload_between_touches_takes_over_at_once(tmp_path, paper_desk):
    """Guards item 3's other side: with no touch in progress the new layout is used from the
    next block, as before."""
    _, answers, _ = _events(tmp_path, paper_desk, HOLD, {5.5: "reload"}, 8.0)
    assert not answers[0].endswith("ends")


def test_a_touch_held_past_the_wait_is_cancelled_never_released(tmp_path, paper_desk):
    """Guards item 3's bound: a touch held longer than MAX_SWAP_WAIT_S after the reload is
    cancelled (phase `cancel`; no tap, no release) and the new layout taken."""
    # a finger held 40 s, pressing harder and softer (a still load would be an object)
    long_hold = [
        Tap(1.5 + 0.6 * k, 0.0, 0.0, duration_s=1.0, peak_n=10.0 + 4.0 * (k % 2))
        for k in range(int((MAX_SWAP_WAIT_S + 10.0) / 0.6))
    ]
    events, _, runtime = _events(
        tmp_path, paper_desk, long_hold, {3.0: "reload"}, MAX_SWAP_WAIT_S + 15.0
    )
    long_presses = [e for e in events if e[0] == "long_press"]
    assert long_presses.count(("long_press", None, None)) == 1  # (none by the new layout)
    assert ("long_press", "cancel", None) in long_presses
    assert ("tap", None, None) not in events and ("long_press", "end", None) not in events
    assert runtime.reloads.waiting is None


class _Reloading(Source):
    """Quiet blocks; from block 20 on, a reload asked before each of ``count`` blocks."""

    def __init__(self, count: int) -> None:
        super().__init__(["fl", "fr", "bl", "br"], 1200.0)
        self.count = count
        self.runtime: Runtime | None = None
        self.rss_kb: dict[int, int] = {}
        self.k = 0

    def read_block(self) -> WrenchBlock | None:
        k = self.k
        if k >= self.count + 40:
            return None
        self.k += 1
        wrench = np.zeros((60, 4, 6))
        wrench[:, :, 2] = -33.6  # the desk's weight on its legs
        t = (k * 60 + np.arange(60)) / 1200.0
        if 20 <= k < self.count + 20:
            assert self.runtime is not None
            self.runtime.request("reload")
        if k in (70, self.count + 19):
            gc.collect()
            self.rss_kb[k] = rss_kb()
        return WrenchBlock(t, wrench)


def test_751_reloads_do_not_grow_memory(tmp_path):
    """Guards item 4: 751 reloads of a layout with templated actions keep the process's
    memory flat (700 of them after a warm-up: < 4 MB; b5a43bd +16 MB, every replaced lane
    kept) and keep no replaced lane once it finished, only its counts."""
    path = tmp_path / "l.yaml"
    path.write_text(
        "desk: kitamura2017\nunits: cm\nregions:\n  lamp: {rect: [-35, -22, 35, 22]}\n"
        "bindings:\n"
        '  - {gesture: tap, region: lamp, do: {log: {message: "{{ region }} {{ x }}"}}}\n'
        "  - {gesture: long_press, region: lamp, do: {log: {}}}\n"
    )
    source = _Reloading(751)
    plugin = SimpleNamespace(
        register_sources=hookimpl(lambda register: register("r", lambda a, p, **o: source))
    )
    registry = load_registry(entry_points=False, plugins=[("r", plugin)])
    scene = build_scene(path, "r:", registry, speed=0)
    runtime = source.runtime = Runtime(scene, drain_timeout_s=0.5)
    report = runtime.run(handle_signals=False)
    assert report.error is None
    first, last = source.rss_kb[70], source.rss_kb[751 + 19]
    assert last - first < 4_000, (first, last)
    assert len(scene.dispatcher.retired) == 0
    assert len(scene.dispatcher.retired_stats) <= MAX_RETIRED_LABELS
