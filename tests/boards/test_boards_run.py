"""`hapticdesk run --source serial:PTY` for a minute at 1 kHz (issue 28, what it must show):
a writer thread prints a simulated load-cell desk's samples on a pseudo-terminal as a board
would — with garbled lines, a reboot and a stretch of lost lines in the middle of a tap — and
the run must give every sample through, name and count the garbled lines, survive the
reset, and invent no gesture across the gap.
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass

import numpy as np
import pytest

from hapticdesk.boards.hello import BoardHello

from .board_stream import (
    SCALE,
    ZERO,
    PtyBoard,
    cells_desk,
    counts,
    hello_line,
    sample_lines,
    simulated_cells,
)

RATE = 1000
POINTS = [(-15, 10), (15, 10), (-15, -10), (15, -10)]  # cm, one in each quadrant
REGIONS = {"tl": (-15, 10), "tr": (15, 10), "bl": (-15, -10), "br": (15, -10)}
LAYOUT = """\
desk: cells-1k
units: cm
regions:
  tl: {rect: [-37, 0, 0, 25]}
  tr: {rect: [0, 0, 37, 25]}
  bl: {rect: [-37, -25, 0, 0]}
  br: {rect: [0, -25, 37, 0]}
bindings:
  - {gesture: tap, region: tl, do: {log: {}}}
  - {gesture: tap, region: tr, do: {log: {}}}
  - {gesture: tap, region: bl, do: {log: {}}}
  - {gesture: tap, region: br, do: {log: {}}}
"""


def scene(seconds: float) -> str:
    taps = int((seconds - 3.5) / 1.9)
    lines = [f"  - tap: {{point: [{POINTS[i % 4][0]}, {POINTS[i % 4][1]}], wait_s: 1.7}}"
             for i in range(taps)]  # fmt: skip
    return (
        "name: serial-run\ndesk: kitamura2017\nunits: cm\nquiet_s: 2.0\ntail_s: 1.0\n"
        "human: {tap_peak_n: [4, 6]}\ntimeline:\n" + "\n".join(lines) + "\n"
    )


@dataclass
class Plan:
    """What the board prints and what the run must report."""

    lines: list[str | bytes]
    pauses: dict[int, float]
    samples: int  # sample lines that must come through
    garbled: int
    lost: int  # missing from the sequence: the garbled lines and the cut
    taps: list[str]  # the region of each tap a person made, in order
    cut_tap: int  # the tap whose middle is lost: it must not fire


def plan(tmp_path, seconds: float, seed: int = 11) -> Plan:
    cells = simulated_cells(tmp_path, scene(seconds), rate=RATE, oversample=4, seed=seed)
    n = len(cells.t)
    readings = counts(cells.fz[:, np.arange(4), np.arange(4)])  # bridges read 250 µs apart
    touching = cells.truth["true_fn"] > 0
    downs = np.flatnonzero(touching[1:] & ~touching[:-1]) + 1
    ups = np.flatnonzero(~touching[1:] & touching[:-1]) + 1
    taps = [next(r for r, p in REGIONS.items() if p == POINTS[i % 4]) for i in range(len(downs))]
    # a reboot half-way, between two taps; the sequence starts again from 0
    reset_at = int(downs[len(downs) // 2] - 0.6 * RATE)
    stamps = np.where(np.arange(n) < reset_at, np.arange(n), np.arange(n) - reset_at)
    lines: list[str | bytes] = list(sample_lines(stamps, readings))
    # 70 ms lost from the middle of a later tap: it went down before the gap, up after it
    long_enough = [k for k in range(3 * len(downs) // 4, len(downs)) if ups[k] - downs[k] > 110]
    cut_tap = long_enough[0]
    cut = np.arange(downs[cut_tap] + 20, downs[cut_tap] + 90)
    rng = np.random.default_rng(seed)
    hits = rng.choice(np.setdiff1d(np.arange(n), np.concatenate([cut, [reset_at]])), n // 300,
                      replace=False)  # fmt: skip
    for i in hits:  # one character changed: the checksum no longer matches
        text = str(lines[i])
        at = int(rng.integers(0, len(text) - 3))
        lines[i] = text[:at] + ("7" if text[at] != "7" else "3") + text[at + 1 :]
    for i in cut:
        lines[i] = b""
    hello = BoardHello(RATE, ("fl_fz", "fr_fz", "bl_fz", "br_fz"), offsets_us=(0, 250, 500, 750),
                       checksum_required=True, board="ads1256-test")  # fmt: skip
    lines.insert(reset_at, hello_line(hello))
    return Plan(
        lines=[hello_line(hello), *lines],  # (what a board that answers `?` prints first)
        pauses={reset_at + 1: 0.5},
        samples=n - len(hits) - len(cut),
        garbled=len(hits),
        lost=len(hits) + len(cut),
        taps=taps,
        cut_tap=cut_tap,
    )


def run_on_pty(tmp_path, seconds: float):
    p = plan(tmp_path, seconds)
    desk = cells_desk(tmp_path, rate=RATE, extra=f"serial: {{scale: {SCALE}, zero: {ZERO}}}\n")
    layout = tmp_path / "layout.yaml"
    layout.write_text(LAYOUT)
    events = tmp_path / "events.jsonl"
    board = PtyBoard(p.lines[1:], p.lines[0], rate=RATE, pauses=p.pauses).start()
    started = time.monotonic()
    proc = subprocess.Popen(
        [sys.executable, "-m", "hapticdesk", "run", "--layout", str(layout), "--desk",
         str(desk.path), "--source", f"serial:{board.path}", "--events", str(events),
         "--json", "--status"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=dict(os.environ),
    )  # fmt: skip
    err: list[bytes] = []
    reader = threading.Thread(target=lambda: err.extend(iter(lambda: proc.stderr.read(256), b"")))
    reader.start()
    try:
        # when the board has printed everything and the run's clock stands still, stop it
        last_t, still_since = -1.0, time.monotonic()
        while proc.poll() is None and time.monotonic() - started < seconds + 60:
            time.sleep(0.2)
            shown = re.findall(rb"t +([0-9.]+) s", b"".join(err[-40:]))
            t = float(shown[-1]) if shown else -1.0
            if t != last_t:
                last_t, still_since = t, time.monotonic()
            elif board.done.is_set() and time.monotonic() - still_since > 1.5:
                proc.send_signal(signal.SIGINT)
                break
        out, _ = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
        board.close()
        reader.join(5)
    wall = time.monotonic() - started
    stderr = b"".join(err).decode(errors="replace")
    report = json.loads(out.decode().strip().splitlines()[-1])
    fired = [json.loads(x) for x in events.read_text().splitlines()] if events.exists() else []
    return p, report, fired, stderr, wall


@pytest.mark.slow
def test_a_minute_at_1khz_on_a_pty(tmp_path):
    p, report, fired, stderr, wall = run_on_pty(tmp_path, 65.0)
    notes = "\n".join(report["notes"])
    printed = sum(1 for x in p.lines if x and not str(x).startswith("@"))
    print(
        f"\nboard: {printed} sample lines printed ({p.garbled} garbled, {p.lost - p.garbled} "
        f"more never sent: the cut), a reboot, {len(p.taps)} taps; run: {report['samples']} "
        f"samples ({report['sample_time_s']:.1f} s of sensor time) in {wall:.1f} s wall, "
        f"gestures {report['gestures']}\n" + notes
    )
    assert report["error"] is None and report["stopped_by"] == "SIGINT", stderr[-2000:]
    # every sample through: all the board sent but the garbled lines and the cut
    assert report["samples"] == p.samples
    assert f"{p.samples} samples given out" in notes
    # garbled lines named (on the run's log) and counted (in its summary)
    assert f"{p.garbled} garbled lines dropped (checksum does not match {p.garbled})" in notes
    assert len(re.findall(r"line \d+: garbled, checksum does not match", stderr)) >= min(
        10, p.garbled
    )
    assert f"{p.lost} samples lost in" in notes
    # the reboot survived: counted, and the taps after it still recognised
    assert "1 board resets" in notes and "the board said hello again: it restarted" in stderr
    # no gesture invented across the gap: the cut tap fires nothing, every other one once,
    # in its own quadrant, and nothing else fires
    taps = [e for e in fired if e["gesture"] == "tap"]
    expected = [r for i, r in enumerate(p.taps) if i != p.cut_tap]
    assert [e["region"] for e in taps] == expected, (len(taps), len(expected))
    assert len(fired) == len(taps)


def test_record_keeps_what_a_board_prints(tmp_path):
    """`hapticdesk record --source serial:PTY -o rec.csv`: every sample the board printed is
    in the recording, in newtons, its garbled lines dropped and said; the recording replays."""
    from hapticdesk.files.recording_io import read_recording

    n, rate = 1500, 500
    rng = np.random.default_rng(3)
    newtons = 40.0 + rng.normal(0, 2.0, (n, 4))
    lines: list[str | bytes] = list(sample_lines(np.arange(n), counts(newtons)))
    lines[700] = str(lines[700]).replace(",", ";", 1)  # one garbled line
    hello = BoardHello(rate, ("fl_fz", "fr_fz", "bl_fz", "br_fz"), offsets_us=(0, 0, 0, 0),
                       checksum_required=True,
                       board="ads1256-test")  # fmt: skip
    desk = cells_desk(tmp_path, rate=rate, extra=f"serial: {{scale: {SCALE}, zero: {ZERO}}}\n")
    board = PtyBoard(lines, hello_line(hello), rate=rate).start()
    out = tmp_path / "rec.csv"
    try:
        done = subprocess.run(
            [sys.executable, "-m", "hapticdesk", "record", "--source", f"serial:{board.path}",
             "--desk", str(desk.path), "-o", str(out), "--seconds", f"{n / rate + 2.5}"],
            capture_output=True, text=True, timeout=60,
        )  # fmt: skip
    finally:
        board.close()
    assert done.returncode == 0, done.stdout + done.stderr
    assert "Traceback" not in done.stderr
    assert f"wrote {out}: {n - 1} samples" in done.stdout
    assert "1 garbled lines dropped" in done.stdout
    rec = read_recording(out, desk.sensor_names, channel_names=desk.channel_names())
    kept = np.delete(np.arange(n), 700)
    assert len(rec) == n - 1
    np.testing.assert_allclose(rec.t - rec.t[0], kept / rate, atol=1e-6)
    np.testing.assert_allclose(rec.channels, (counts(newtons)[kept] - ZERO) * SCALE, atol=1e-9)
