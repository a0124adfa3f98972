"""`hapticdesk run --source replay:LOG` on damaged CAN logs (issue 11 items 7 and 14).

A run must say what the CAN decoder saw (frames seen, samples decoded, frames rejected by
reason) as `contacts` does, fail when nothing decodes, and read past a junk line.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from hapticdesk.canbus.config_reader import can_config
from hapticdesk.canbus.frame_encoder import FrameEncoder
from hapticdesk.canbus.logs.writer import write_frames
from hapticdesk.cli import main

T0 = 1_700_000_000.0
N = 1200  # one second at 1.2 kHz
LAYOUT = """\
desk: kitamura2017
units: cm
regions:
  lamp: {rect: [-10, -10, 10, 10]}
bindings:
  - gesture: tap
    region: lamp
    do: {log: {}}
"""


@pytest.fixture
def log_lines(tmp_path, can_desk, make_samples) -> list[str]:
    """A candump -l log of one second of the shipped DBC desk, as lines."""
    t, wrench = make_samples(N, 4, seed=2)
    frames = FrameEncoder(can_config(can_desk), can_desk).encode(T0 + t, wrench)
    path = tmp_path / "whole.log"
    write_frames(path, [frames], channel="can0")
    return path.read_text().splitlines()


def replay(tmp_path, lines: list[str], capsys) -> tuple[int, str]:
    (tmp_path / "layout.yaml").write_text(LAYOUT)
    path = tmp_path / "desk.log"
    path.write_text("\n".join(lines) + "\n")
    code = main(["run", "--layout", str(tmp_path / "layout.yaml"), "--desk", "kitamura2017-can",
                 "--source", f"replay:{path}", "--speed", "0"])  # fmt: skip
    return code, capsys.readouterr().err


def test_run_reports_what_the_can_decoder_saw(tmp_path, log_lines, capsys):
    code, err = replay(tmp_path, log_lines, capsys)
    assert code == 0
    assert f"the source ended: {N} samples" in err
    assert f"CAN log desk.log: {8 * N} frames, {N} samples" in err


def test_run_reports_frames_of_the_wrong_length(tmp_path, log_lines, capsys):
    rng = np.random.default_rng(0)
    hit = rng.choice(len(log_lines), len(log_lines) // 50, replace=False)  # 2 % of frames
    for i in hit:  # one byte short
        stamp, channel, frame, *rest = log_lines[i].split()
        log_lines[i] = " ".join([stamp, channel, frame[:-2], *rest])
    code, err = replay(tmp_path, log_lines, capsys)
    assert code == 0
    assert f"CAN log desk.log: {8 * N} frames, {N} samples" in err
    line = next(x for x in err.splitlines() if "dropped frames of the wrong length" in x)
    assert sum(int(n) for n in re.findall(r"0x[0-9A-F]{3}: (\d+)", line)) == len(hit)
    # a sample that lost a frame holds that sensor's values from the sample before (issue
    # 30, item 6: they had been NaN, and enough of them refuse the tare for the whole run)
    assert "samples (" in err and "%) lacked a frame; its values were held" in err


def test_run_fails_when_no_frame_decodes(tmp_path, log_lines, capsys):
    moved = [x.replace(" can0 1", " can0 4", 1) for x in log_lines]  # other identifiers
    code, err = replay(tmp_path, moved, capsys)
    assert code == 1
    assert "error: " in err and "no samples of desk `kitamura2017-can` in this log" in err
    assert f"ignored {8 * N} frames of other traffic" in err


def test_a_junk_line_in_a_candump_l_log_is_skipped_with_its_line(
    tmp_path, log_lines, capsys, caplog
):
    log_lines.insert(4000, "this is not a frame")  # file line 4001
    log_lines.insert(6000, "(1700000000.5) can0 12#ABC")  # an odd number of hex digits
    code, err = replay(tmp_path, log_lines, capsys)
    assert code == 0
    assert "2 line(s) are not CAN frames and were skipped" in caplog.text
    assert "desk.log:4001" in caplog.text and "desk.log:6001" in caplog.text
    assert f"the source ended: {N} samples (1.00 s of sensor time)" in err
