"""Fuzzing CAN frame assembly and CAN log reading (issue 11 item 21): any frames end in
samples (NaN where incomplete) and counts, any log in frames or a ConfigError naming the file;
never a traceback, and frames waiting for their sample stay bounded."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hapticdesk.canbus.assembler import FrameAssembler
from hapticdesk.canbus.config_reader import can_config
from hapticdesk.canbus.decoding import build_decoding
from hapticdesk.canbus.frame_encoder import FrameEncoder
from hapticdesk.canbus.frames import FrameArray
from hapticdesk.canbus.logs.formats import read_frames
from hapticdesk.errors import ConfigError

FUZZ = settings(
    max_examples=40,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
PUSHES = 20  # the same frames pushed again and again: what waits must not grow


@st.composite
def frame_lists(draw: st.DrawFn, idents: list[int]) -> tuple[list[float], list[int], list[bytes]]:
    """Frames of the desk's identifiers and others, any length, times in order, jumbled,
    equal or missing."""
    n = draw(st.integers(0, 60))
    ids = draw(st.lists(st.sampled_from(idents) | st.integers(0, 0x7FF), min_size=n, max_size=n))
    data = draw(st.lists(st.binary(max_size=8), min_size=n, max_size=n))
    style = draw(st.sampled_from(["ordered", "jumbled", "equal", "missing"]))
    steps = draw(st.lists(st.floats(0, 0.01), min_size=n, max_size=n))
    t = np.cumsum(steps).tolist()
    if style == "jumbled":
        t = draw(st.permutations(t))
    elif style == "equal":
        t = [0.0] * n
    elif style == "missing":
        t = [float("nan")] * n
    return t, ids, data


def desk_assembler(profile, calibrations=None) -> tuple[FrameAssembler, list[int]]:
    config = can_config(profile)
    if calibrations is None and config.ati_sensors:
        calibrations = FrameEncoder(config, profile).calibrations
    decoding = build_decoding(config, profile, calibrations)
    asm = FrameAssembler(
        decoding,
        profile.sample_rate_hz,
        assemble=config.assemble,
        frame_gap_s=config.frame_gap_s,
        silent_timeout_s=config.silent_timeout_s,
    )
    idents = sorted({k.ident & 0x7FF for k in decoding.kinds} | set(decoding.request_sensor))
    return asm, idents


def run_frames(asm: FrameAssembler, frames: FrameArray, splits: list[int]) -> None:
    n_sensors = len(asm.decoding.readings)
    out = []
    for _ in range(PUSHES):
        bounds = sorted({0, len(frames), *(s % (len(frames) + 1) for s in splits)})
        for a, b in zip(bounds[:-1], bounds[1:], strict=True):
            block = asm.push(frames.take(slice(a, b)))
            assert block.wrench.shape == (len(block.t), n_sensors, 6)
            out.append(block.t)
        # frames waiting for their sample: a few samples' worth, whatever was pushed before
        assert len(asm._pending.key) <= 2 * len(frames) + 64
    last = asm.flush()
    assert last.wrench.shape == (len(last.t), n_sensors, 6)
    assert len(asm._pending.key) == 0
    s = asm.stats
    assert s.frames == PUSHES * len(frames)
    assert (
        s.data_frames
        + s.requests
        + s.protocol
        + sum(s.foreign.values())
        + sum(s.wrong_length.values())
        + s.error_frames
        + s.remote_frames
        == s.frames
    )


@pytest.mark.parametrize("desk", ["dbc", "uncounted", "ati"])
@FUZZ
@given(data=st.data())
def test_any_frames_assemble_into_samples_and_counts(request, desk, data):
    profile = {
        "dbc": lambda: request.getfixturevalue("can_desk"),
        "uncounted": lambda: request.getfixturevalue("uncounted_desk"),
        "ati": lambda: request.getfixturevalue("ati_desk")[0],
    }[desk]()
    asm, idents = desk_assembler(profile)
    t, ids, payloads = data.draw(frame_lists(idents))
    frames = FrameArray.build(np.array(t, dtype=float), ids, payloads)
    splits = data.draw(st.lists(st.integers(0, 60), max_size=5))
    run_frames(asm, frames, splits)


def candump_line(t: float, ident: int, payload: bytes) -> str:
    return f"({t:.6f}) can0 {ident:03X}#{payload.hex().upper()}"


junk_lines = st.sampled_from(
    [
        "",
        "# a comment",
        "garbage",
        "(1.0) can0 12X#00",
        "(1.0) can0 123#ABC",
        "(x) can0 123#00",
        "(1.0) can0 123##1" + "00" * 64,
        "(1.0) can0 123#R",
        "(1.0) can0 20000080#0000000000000000",
        "\x00\xff",
        "(1.0)  can0  123   [2]  00 11",
    ]
) | st.text(max_size=30)


@FUZZ
@given(
    lines=st.lists(
        st.builds(candump_line, st.floats(0, 1e9), st.integers(0, 0x7FF), st.binary(max_size=8))
        | junk_lines,
        max_size=40,
    ),
    suffix=st.sampled_from([".log", ".txt", ".candump"]),
)
def test_any_candump_text_is_frames_or_a_clear_error(tmp_path, lines, suffix):
    path = tmp_path / f"fuzz{suffix}"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8", errors="surrogateescape")
    try:
        chunks = list(read_frames(path, chunk_frames=7))
    except ConfigError as err:
        assert str(err).startswith(str(path)), str(err)
        return
    total = sum(len(c) for c in chunks)
    assert 0 < total <= len(lines)
