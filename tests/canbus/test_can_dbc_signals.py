"""Vectorised signal extraction equals cantools' own decode and encode, bit for bit."""

from __future__ import annotations

from pathlib import Path

import cantools
import numpy as np
import pytest

from hapticdesk.canbus.config_reader import can_config
from hapticdesk.canbus.dbc_signals import (
    SignalLayout,
    frame_words,
    message_layouts,
    words_to_frames,
)
from hapticdesk.canbus.decoding import build_decoding
from hapticdesk.canbus.frames import EXTENDED, FrameArray

# every layout case: Intel and Motorola, signed and unsigned, odd starts and lengths crossing
# bytes, scale and offset, IEEE floats, an extended id and a short frame
TEST_DBC = """VERSION ""

NS_ :

BS_:

BU_: A B

BO_ 100 MIXED: 8 A
 SG_ U5 : 3|5@1+ (1,0) [0|31] "" B
 SG_ S12 : 8|12@1- (0.5,-3) [-1027|1020.5] "" B
 SG_ MU10 : 31|10@0+ (1,0) [0|1023] "" B
 SG_ MS16 : 37|16@0- (0.01,2) [-325|330] "" B
 SG_ MS7 : 53|7@0- (1,0) [-64|63] "" B
 SG_ BIT : 56|1@1+ (1,0) [0|1] "" B

BO_ 101 FLOATS: 8 A
 SG_ F32 : 0|32@1- (1,0) [0|0] "" B
 SG_ MF32 : 39|32@0- (2,1) [0|0] "" B

BO_ 102 DOUBLE: 8 A
 SG_ F64 : 0|64@1- (1,0) [0|0] "" B

BO_ 2566914048 EXT: 8 A
 SG_ U64 : 0|64@1+ (1,0) [0|0] "" B

BO_ 103 SHORT: 5 A
 SG_ MS13 : 13|13@0- (0.25,0) [0|0] "" B
 SG_ U11 : 24|11@1+ (1,0) [0|2047] "" B

SIG_VALTYPE_ 101 F32 : 1;
SIG_VALTYPE_ 101 MF32 : 1;
SIG_VALTYPE_ 102 F64 : 2;
"""


@pytest.fixture(scope="module")
def db(tmp_path_factory: pytest.TempPathFactory):
    path = tmp_path_factory.mktemp("dbc") / "test.dbc"
    path.write_text(TEST_DBC)
    return cantools.database.load_file(str(path), strict=True)


def frames(n: int, length: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    data = rng.integers(0, 256, (n, 8), dtype=np.uint8)
    data[0], data[1], data[2] = 0, 255, 0x55  # all clear, all set, alternating
    data[:, length:] = 0
    return data


@pytest.mark.parametrize("name", ["MIXED", "FLOATS", "DOUBLE", "EXT", "SHORT"])
def test_decode_equals_cantools(db, name):
    message = db.get_message_by_name(name)
    data = frames(400, message.length, seed=len(name))
    layouts = message_layouts(db, name)
    words = frame_words(data)
    for signal, layout in layouts.items():
        ours = layout.decode(words)
        theirs = [
            float(message.decode(row[: message.length].tobytes(), decode_choices=False)[signal])
            for row in data
        ]
        # random bits include NaN and infinite floats: those must agree too
        np.testing.assert_allclose(
            ours, theirs, rtol=1e-12, atol=1e-12, equal_nan=True, err_msg=signal
        )


@pytest.mark.parametrize("name", ["MIXED", "SHORT"])
def test_encode_equals_cantools(db, name):
    message = db.get_message_by_name(name)
    data = frames(300, message.length, seed=7 + len(name))
    layouts = message_layouts(db, name)
    words = frame_words(data)
    physical = {s: layouts[s].decode(words) for s in layouts}
    little = np.zeros(len(data), dtype=np.uint64)
    big = np.zeros(len(data), dtype=np.uint64)
    for s, layout in layouts.items():
        bits = layout.encode(physical[s])
        if layout.big_endian:
            big |= bits
        else:
            little |= bits
    ours = words_to_frames(little, big)
    for i in range(len(data)):
        values = {s: physical[s][i] for s in layouts}
        theirs = message.encode(values, strict=False)
        assert ours[i, : message.length].tobytes() == theirs, values
    # and back: the encoded frames decode to the values they were made from
    back = frame_words(ours)
    for s, layout in layouts.items():
        np.testing.assert_array_equal(layout.decode(back), physical[s])


def test_layout_positions(db):
    layouts = message_layouts(db, "MIXED")
    assert (layouts["U5"].shift, layouts["U5"].big_endian) == (3, False)
    # Motorola start 31 = bit 7 of byte 3, the MSB; 10 bits run into byte 4
    assert layouts["MU10"].big_endian and layouts["MU10"].shift == 64 - 24 - 10
    assert (
        SignalLayout.from_cantools(
            db.get_message_by_name("FLOATS"), db.get_message_by_name("FLOATS").signals[0]
        ).float_bits
        == 32
    )


def test_shipped_dbc_desk_decodes_like_cantools(can_desk, dbc_frames):
    config = can_config(can_desk)
    decoding = build_decoding(config, can_desk)
    rng = np.random.default_rng(3)
    n = 200
    ids = [k.ident for k in decoding.kinds]
    data = rng.integers(0, 256, (n * len(ids), 8), dtype=np.uint8)
    arr = FrameArray.build(np.zeros(len(data)), np.repeat(ids, n), [bytes(d) for d in data])
    codes = decoding.classify(arr)
    assert (codes == np.repeat(np.arange(len(ids)), n)).all()
    for k, kind in enumerate(decoding.kinds):
        sel = codes == k
        ours = kind.decode(arr.data[sel])
        message = config.database.get_message_by_frame_id(kind.ident)
        names = [s.name for s in message.signals if s.name not in ("Seq",)]
        for i, row in enumerate(arr.data[sel][:50]):
            theirs = message.decode(row.tobytes(), decode_choices=False)
            np.testing.assert_allclose(ours[i], [theirs[s] for s in names], rtol=0, atol=1e-12)


@pytest.mark.parametrize("fmt", ["kcd", "sym"])
def test_other_database_formats_decode_the_same(can_desk, profile_text, dbc_frames, fmt):
    """KCD and SYM (through cantools) give the same samples as the DBC."""
    db = can_config(can_desk).database
    text_path = Path(str(can_desk.path))
    converted = db.as_kcd_string() if fmt == "kcd" else db.as_sym_string()
    original = text_path.read_text()
    profile = profile_text(original.replace("kitamura2017.dbc", f"desk.{fmt}"), "desk.yaml")
    (Path(str(profile.path)).parent / f"desk.{fmt}").write_text(converted)
    profile = profile_text(original.replace("kitamura2017.dbc", f"desk.{fmt}"), "desk.yaml")
    config = can_config(profile)
    assert config.database_path is not None and config.database_path.suffix == f".{fmt}"
    t, wrench, arr = dbc_frames(120)
    ours = build_decoding(config, profile)
    dbc = build_decoding(can_config(can_desk), can_desk)
    for mine, theirs in zip(ours.kinds, dbc.kinds, strict=True):
        assert mine.ident == theirs.ident
        sel = arr.ident == mine.ident
        np.testing.assert_array_equal(mine.decode(arr.data[sel]), theirs.decode(arr.data[sel]))
    assert not (arr.ident & EXTENDED).any()
