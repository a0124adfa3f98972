"""The ``serial:`` source on a pseudo-terminal fed by a writer thread (a board on a line):
opened through the plugin registry like any source, a wrong board refused before the run,
garbled and lost lines counted, a reset survived, a port that is gone said plainly."""

from __future__ import annotations

import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from hapticdesk.boards.hello import BoardHello
from hapticdesk.errors import ConfigError
from hapticdesk.plugin_loading import load_registry
from hapticdesk.runtime.source_spec import open_source

from .board_stream import SCALE, ZERO, PtyBoard, cells_desk, counts, hello_line, sample_lines

CHANNELS = ("fl_fz", "fr_fz", "bl_fz", "br_fz")
HELLO = BoardHello(1000, CHANNELS, offsets_us=(0, 250, 500, 750), checksum_required=True)


@pytest.fixture
def desk(tmp_path):
    return cells_desk(tmp_path, extra=f"serial: {{scale: {SCALE}, zero: {ZERO}}}\n")


@pytest.fixture
def registry():
    return load_registry(entry_points=False)


@pytest.fixture
def boards():
    made: list[PtyBoard] = []

    def make(*args, **kwargs) -> PtyBoard:
        made.append(PtyBoard(*args, **kwargs).start())
        return made[-1]

    yield make
    for board in made:
        board.close()


def read_all(source, expected: int, timeout_s: float = 20.0):
    """Blocks until ``expected`` samples came (or the timeout); closes the source."""
    blocks, got = [], 0
    deadline = time.monotonic() + timeout_s
    try:
        while got < expected and time.monotonic() < deadline:
            block = source.read_block()
            if block is not None and len(block.t):
                blocks.append(block)
                got += len(block.t)
    finally:
        source.close()
    return blocks


def test_missing_pyserial_is_named_with_its_install_command(desk, registry, monkeypatch):
    monkeypatch.setitem(sys.modules, "serial", None)  # import serial -> ImportError
    with pytest.raises(ConfigError, match=r"pip install 'hapticdesk\[serial\]'"):
        open_source("serial:/dev/ttyUSB0", desk, registry)


def test_pyserial_and_the_boards_are_imported_only_for_the_serial_source():
    probe = (
        "import sys; from hapticdesk.plugin_loading import load_registry; "
        "from hapticdesk.files.profile_reader import load_profile; "
        "from hapticdesk.runtime.source_spec import open_source; "
        "r = load_registry(entry_points=False); "
        "open_source('sim:examples/scenes/buttons.yaml', load_profile('kitamura2017'), r).close(); "
        "print(sorted(m for m in ('serial', 'hapticdesk.boards') if m in sys.modules))"
    )
    root = Path(__file__).resolve().parents[2]
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, cwd=root,
                          timeout=120, check=True)  # fmt: skip
    assert done.stdout.strip() == "[]"


def test_a_port_that_cannot_be_opened(desk, registry, tmp_path):
    with pytest.raises(ConfigError, match=f"cannot open serial port {tmp_path}/nope"):
        open_source(f"serial:{tmp_path}/nope", desk, registry)


@pytest.mark.parametrize(
    ("channels", "needle"),
    [
        (
            ("fr_fz", "fl_fz", "bl_fz", "br_fz"),
            "the board sends the desk's channels in another order",
        ),
        (("a", "b", "c", "d"), "the board is not for desk `cells-1k`"),
    ],
)
def test_a_wrong_board_is_refused_before_the_run(desk, registry, boards, channels, needle):
    board = boards([], hello_line(BoardHello(1000, channels, offsets_us=(0, 0, 0, 0))))
    with pytest.raises(ConfigError, match=needle) as info:
        open_source(f"serial:{board.path}", desk, registry)
    assert f"{board.path} line 1" in str(info.value)
    assert "fl_fz,fr_fz,bl_fz,br_fz" in str(info.value)


def test_a_board_that_never_says_hello(desk, registry, boards):
    board = boards(sample_lines(np.arange(2000), counts(np.ones((2000, 4)))), "", rate=1000,
                   answer_hello=False, wait_for_ask=False)  # fmt: skip
    started = time.monotonic()
    with pytest.raises(
        ConfigError, match=r"no hello from the board within 0.5 s \(\d+ bytes"
    ) as info:
        open_source(f"serial:{board.path}?hello_timeout_s=0.5", desk, registry)
    assert time.monotonic() - started < 3
    assert "the last: '" in str(info.value) and board.asked >= 1


def test_samples_through_a_pty_with_garbled_lost_and_a_reset(desk, registry, boards):
    n = 3000
    rng = np.random.default_rng(3)
    values = counts(rng.normal(80, 3, (n, 4)))
    reset_at = 2000  # the board reboots: a pause, its hello, and the sequence from 0
    stamps = np.where(np.arange(n) < reset_at, np.arange(n), np.arange(n) - reset_at)
    lines: list[str | bytes] = list(sample_lines(stamps, values))
    garbled = [400, 401, 1500, 2600]
    for i in garbled:
        lines[i] = lines[i].replace(",", ";", 1)  # a byte hit on the line
    lost = [700, 701, 702]
    for i in lost:
        lines[i] = b""  # never arrives
    first, second = lines[:reset_at], [hello_line(HELLO), *lines[reset_at:]]
    board = boards(first + second, hello_line(HELLO), rate=1000, pauses={reset_at: 0.3})
    source = open_source(f"serial:{board.path}", desk, registry)
    expected = n - len(garbled) - len(lost)
    blocks = read_all(source, expected)
    got = np.concatenate([b.wrench for b in blocks])
    t = np.concatenate([b.t for b in blocks])
    stats = source.decoder.stats
    assert len(got) == expected and stats.samples == expected
    assert stats.garbled_lines == len(garbled) and stats.lost == len(garbled) + len(lost)
    assert stats.resets == 1 and stats.gaps == 1
    # every sample that came is the one the board sent, in order
    sent = np.delete((values - ZERO) * SCALE, garbled + lost, axis=0)
    np.testing.assert_allclose(got[:, 0], sent[:, 0], atol=1e-9)  # channel 0: offset 0
    assert (np.diff(t) > 0).all()
    k = reset_at - sum(i < reset_at for i in garbled + lost)  # the first after the reboot
    reboot = t[k] - t[k - 1]
    assert 0.25 < reboot < 2.0  # the reboot's real time, measured by the host
    summary = "\n".join(source.summary())
    assert f"serial {board.path}: " in summary and "4 garbled lines dropped" in summary
    assert "7 samples lost in 4 sequence gaps" in summary and "1 board resets" in summary
    named = [x.message for x in stats.notices if x.kind == "garbled"]
    # named by their line on the port: after the hello, less the lost ones, the second hello
    numbers = [i + 2 - sum(j < i for j in lost) + (i >= reset_at) for i in garbled]
    assert [m.split(": ")[0] for m in named] == [f"{board.path} line {k}" for k in numbers]


def test_a_port_that_is_gone_for_good_ends_with_a_clear_error(desk, registry, boards):
    n = 300
    board = boards(
        sample_lines(np.arange(n), counts(np.ones((n, 4)))), hello_line(HELLO), rate=1000
    )
    source = open_source(f"serial:{board.path}?reconnect_timeout_s=0.3", desk, registry)
    got = sum(len(b.t) for b in read_all_until_done(source, board, n))
    assert got == n
    board.close()  # unplugged
    started = time.monotonic()
    with pytest.raises(
        ConfigError, match="the serial port was lost .* did not come back within 0.3 s"
    ):
        for _ in source.blocks():
            pass
    assert time.monotonic() - started < 5
    source.close()
    assert any(
        "failed" in x.message and "reopening" in x.message for x in source.decoder.stats.notices
    )


def read_all_until_done(source, board, n):
    blocks, got = [], 0
    deadline = time.monotonic() + 10
    while got < n and time.monotonic() < deadline:
        block = source.read_block()
        if block is not None and len(block.t):
            blocks.append(block)
            got += len(block.t)
    return blocks


class NetworkBoard:
    """A board on the network (an ESP32 serving its lines over TCP, pyserial's socket://):
    each connection waits for the host's `?`, says hello and sends its share of lines, then
    the first one drops (Wi-Fi lost) and the next one serves the rest."""

    def __init__(self, shares: list[list[str]]) -> None:
        self.server = socket.create_server(("127.0.0.1", 0))
        self.port = self.server.getsockname()[1]
        self.shares = shares
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        self.server.settimeout(10)
        for i, share in enumerate(self.shares):
            conn, _ = self.server.accept()
            with conn:
                conn.settimeout(5)
                while b"?" not in conn.recv(64):
                    pass
                conn.sendall(("\n".join([hello_line(HELLO), *share]) + "\n").encode())
                last = i == len(self.shares) - 1
                self.stop.wait(10 if last else 0.3)  # then the link drops (the last stays)

    def close(self) -> None:
        self.stop.set()
        self.server.close()
        self.thread.join(5)


def test_a_board_on_the_network_that_drops_is_reconnected(desk, registry):
    values = counts(np.full((1000, 4), 80.0))
    lines = sample_lines(np.arange(1000), values)
    board = NetworkBoard([lines[:500], lines[700:]])  # 200 sent while the link was down
    source = open_source(f"serial:socket://127.0.0.1:{board.port}", desk, registry)
    try:
        blocks = read_all(source, 800, timeout_s=20)
    finally:
        board.close()
    t = np.concatenate([b.t for b in blocks])
    stats = source.decoder.stats
    assert len(t) == 800 and stats.reconnects == 1 and stats.resets == 0
    # a new epoch after the time the link was away, never bridged
    away = t[500] - t[499]
    assert away > desk.estimation.max_gap_s and (np.diff(t) > 0).all()
    told = [n.message for n in stats.notices if n.kind in ("port", "resume")]
    assert any("failed" in m for m in told) and any("is back" in m for m in told)
    assert any("the port was opened again" in m for m in told)


@pytest.mark.parametrize("scale", ["", "?scale=2e-5"])
def test_the_summary_says_when_no_scale_made_the_values_newtons(tmp_path, registry, boards, scale):
    """A board's raw counts taken as newtons never let the desk tare ("not quiet"): the run's
    summary says that no `scale` was given, and says nothing when one was."""
    board = boards(sample_lines(np.arange(50), counts(np.ones((50, 4)))), hello_line(HELLO),
                   rate=1000)  # fmt: skip
    source = open_source(f"serial:{board.path}{scale}", cells_desk(tmp_path), registry)
    read_all(source, 50)
    said = "\n".join(source.summary())
    assert ("no `scale` given" in said) is (not scale), said
    assert "taken as newtons" in said or scale
