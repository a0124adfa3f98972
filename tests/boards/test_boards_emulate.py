"""``hapticdesk emulate --serial``: a board on a pseudo-terminal, read by the ``serial:``
source as it reads a board: every sample, in the profile's counts or in newtons, the scene
from its start however late the reader opens the port."""

from __future__ import annotations

import re
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from hapticdesk.boards.emulator import PtyBoard, board_lines
from hapticdesk.plugin_loading import load_registry
from hapticdesk.runtime.source_spec import open_source
from hapticdesk.sim import load_scene, simulate

from .board_stream import SCALE, ZERO, cells_desk
from .test_boards_source import read_all

pytest.importorskip("serial")

SCENE = """\
name: taps
desk: cells-1k
units: cm
quiet_s: 1.5
tail_s: 0.3
timeline:
  - tap: {point: [-20, 12]}
  - press: {point: [25, -15], peak_n: 12}
"""


def _read(path: str, desk, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The first ``n`` samples the ``serial:`` source reads at ``path``: (t, values (n, C))."""
    source = open_source(f"serial:{path}", desk, load_registry(entry_points=False))
    blocks = read_all(source, n)
    t = np.concatenate([b.t for b in blocks])
    values = np.concatenate([b.wrench.reshape(len(b.t), -1) for b in blocks])
    return t, values


@pytest.mark.parametrize("scaled", [True, False], ids=["counts", "newtons"])
def test_the_serial_source_reads_every_emulated_sample(tmp_path, scaled):
    extra = f"serial: {{scale: {SCALE}, zero: {ZERO}}}\n" if scaled else ""
    desk = cells_desk(tmp_path, rate=200, extra=extra)
    (tmp_path / "taps.yaml").write_text(SCENE)
    rec = simulate(desk, load_scene(tmp_path / "taps.yaml"), seed=1)
    values = rec.wrench.reshape(len(rec), -1)
    hello, lines = board_lines(desk, values)
    assert "offsets_us=0,0,0,0" in hello and "checksum=xor" in hello
    board = PtyBoard(hello, lines, rec.t, speed=0.0)
    threading.Thread(target=board.run, daemon=True).start()
    time.sleep(0.3)  # (the board waits for the reader's `?`: nothing printed before it)
    assert board.printed == 0
    try:
        t, got = _read(board.path, desk, len(rec))
    finally:
        board.stop()
    assert len(t) == len(rec)
    np.testing.assert_allclose(np.diff(t), np.diff(rec.t), atol=1e-9)
    # a count is SCALE newtons; in newtons the board prints four decimals
    np.testing.assert_allclose(got, values, rtol=0, atol=SCALE if scaled else 5e-5)


def test_emulate_serial_says_its_port_and_a_reader_gets_the_scene(tmp_path):
    desk = cells_desk(tmp_path, rate=200, extra=f"serial: {{scale: {SCALE}, zero: {ZERO}}}\n")
    scene = tmp_path / "taps.yaml"
    scene.write_text(SCENE)
    rec = simulate(desk, load_scene(scene), seed=2)
    command = [sys.executable, "-m", "hapticdesk", "emulate", "--desk", str(desk.path)]
    command += ["--scene", str(scene), "--serial", "--speed", "0", "--seed", "2"]
    proc = subprocess.Popen(command, stderr=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stderr is not None
        said = proc.stderr.readline()
        port = re.search(r" on (/dev/\S+): read it with  hapticdesk run", said)
        assert port, said
        time.sleep(1.0)  # a reader that comes late still gets the scene from its start
        _, got = _read(port.group(1), desk, len(rec))
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            out, err = proc.communicate(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()  # (never left running past the test, whatever made it miss the signal)
            raise
    np.testing.assert_allclose(got, rec.wrench.reshape(len(rec), -1), rtol=0, atol=SCALE)
    assert f"printed {len(rec)} samples on {port.group(1)}" in out
    assert "Traceback" not in err
