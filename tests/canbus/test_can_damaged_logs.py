"""A damaged CAN log is not silently nothing (issue 30, item 6).

On b5a43bd a candump log of the buttons scene (11 taps) with 5 % of its lines junk, or 0.5 %
of its frames dated a second early, gave a tare refused for the whole run, 0 of 11 taps and
exit 0: the junk lost a frame in a third of the samples (their channels NaN, skipped by the
estimator, so no quiet second of whole samples for the tare), and each early frame read as
a wrap of the counter (1.6 million samples "lost"). Now the good frames are used — a lost
frame's channels hold their last value for up to two samples, an early frame's time moves no
clock — and the summary counts what was skipped, held and out of time."""

from __future__ import annotations

import random
import re
from pathlib import Path

import numpy as np
import pytest

from hapticdesk.canbus.assembler import FrameAssembler
from hapticdesk.canbus.config_reader import can_config
from hapticdesk.canbus.decoding import build_decoding
from hapticdesk.canbus.frame_encoder import FrameEncoder
from hapticdesk.cli import main

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


@pytest.fixture(scope="module")
def buttons_log(tmp_path_factory: pytest.TempPathFactory) -> list[str]:
    """The buttons scene (11 taps) on the CAN desk, as candump -l lines."""
    path = tmp_path_factory.mktemp("can") / "buttons.log"
    code = main(
        ["record", "--source", f"sim:{EXAMPLES / 'scenes' / 'buttons.yaml'}", "--desk",
         "kitamura2017-can", "-o", str(path), "--seed", "1"]
    )  # fmt: skip
    assert code == 0
    return path.read_text().splitlines()


def _run(tmp_path: Path, lines: list[str], capsys: pytest.CaptureFixture) -> tuple[int, str]:
    path = tmp_path / "damaged.log"
    path.write_text("\n".join(lines) + "\n")
    code = main(
        ["run", "--layout", str(EXAMPLES / "layouts" / "buttons.yaml"), "--desk",
         "kitamura2017-can", "--source", f"replay:{path}", "--speed", "0"]
    )  # fmt: skip
    return code, capsys.readouterr().err


def _taps(err: str) -> int:
    found = re.search(r"; (\d+) gestures", err)
    assert found, err
    return int(found.group(1))


def test_a_log_with_5_percent_junk_lines_still_gives_its_taps(tmp_path, buttons_log, capsys):
    """Guards item 6 (junk): 5 % of the lines replaced by junk: the taps are found (b5a43bd:
    0 of 11) and the summary counts the skipped lines and the samples whose values were
    held."""
    rng = random.Random(0)
    damaged = [
        f"junk line {i}" if rng.random() < 0.05 else line for i, line in enumerate(buttons_log)
    ]
    junk = sum(line.startswith("junk") for line in damaged)
    code, err = _run(tmp_path, damaged, capsys)
    assert code == 0
    assert _taps(err) >= 10
    assert f"CAN log damaged.log: {junk} line(s) are not CAN frames and were skipped" in err
    held = re.findall(r"sensor \w+: (\d+) samples \(([\d.]+) %\) lacked a frame; its values", err)
    assert len(held) == 4 and all(8.0 < float(share) < 12.0 for _, share in held)
    assert "never tared" not in err


def test_a_log_with_frames_dated_early_still_gives_its_taps(tmp_path, buttons_log, capsys):
    """Guards item 6 (time-reversed frames): 0.5 % of the frames dated a second early: their
    counters place them, the taps are found (b5a43bd: 6 of 11, 1,384 s of "sensor time"),
    and the summary counts them."""
    rng = random.Random(1)
    damaged = []
    early = 0
    for line in buttons_log:
        if rng.random() < 0.005:
            stamp, rest = line.split(")", 1)
            line = f"({float(stamp[1:]) - 1.0:.6f}){rest}"
            early += 1
        damaged.append(line)
    code, err = _run(tmp_path, damaged, capsys)
    assert code == 0
    assert _taps(err) == 11
    assert "(26.70 s of sensor time)" in err
    assert f"CAN log damaged.log: {early} frames came with a time before an earlier" in err
    assert "samples lost" not in err


def test_a_run_that_never_tares_says_so(tmp_path, buttons_log, capsys):
    """Guards item 6 ("not silently nothing"): a log whose sensor `fl` never sends gives no
    sample the tare can use; the run says it was never tared instead of ending quietly with
    0 gestures (b5a43bd: said nothing)."""
    without_fl = [line for line in buttons_log if not re.search(r" 1[01][01]#", line)]
    code, err = _run(tmp_path, without_fl, capsys)
    assert _taps(err) == 0
    assert "the desk was never tared in 26.7 s of samples: no gesture could be recognised" in err


def test_holding_a_lost_frame_does_not_depend_on_how_the_frames_are_split(can_desk):
    """The assembler's contract (any split gives the same samples) holds with the hold: a
    third of the samples missing a frame, pushed whole, one frame at a time and in random
    pieces."""
    config = can_config(can_desk)
    rng = np.random.default_rng(3)
    n = 400
    t = np.arange(n) / 1200.0
    wrench = rng.normal(0, 5, (n, 4, 6))
    frames = FrameEncoder(config, can_desk).encode(1_700_000_000.0 + t, wrench)
    keep = rng.random(len(frames)) > 0.05
    keep[:8] = True
    frames = frames.take(keep)

    def assemble(splits: list[int]) -> tuple[np.ndarray, np.ndarray]:
        assembler = FrameAssembler(
            build_decoding(config, can_desk, {}), 1200.0, assemble=config.assemble,
            hold_samples=2,
        )  # fmt: skip
        ts, ws = [], []
        for a, b in zip([0, *splits], [*splits, len(frames)], strict=True):
            block = assembler.push(frames.take(np.arange(a, b)))
            ts.append(block.t)
            ws.append(block.wrench)
        block = assembler.flush()
        return np.concatenate([*ts, block.t]), np.concatenate([*ws, block.wrench])

    whole_t, whole_w = assemble([])
    assert np.isnan(whole_w).any(axis=(1, 2)).mean() < 0.02  # most lost frames were held
    for splits in (list(range(1, len(frames))), sorted(rng.choice(len(frames), 40, False))):
        t2, w2 = assemble([int(s) for s in splits])
        np.testing.assert_array_equal(t2, whole_t)
        np.testing.assert_array_equal(w2, whole_w)
