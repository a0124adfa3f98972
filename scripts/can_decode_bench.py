"""Decoding throughput on one core: CAN frames of the four-sensor desk into samples.

    python scripts/can_decode_bench.py [--seconds 10] [--repeat 5]

A desk of four sensors at 1.2 kHz with two frames per sensor and sample sends 9,600
frames/s; the target is ten times that, 96,000 frames/s. Measured for the shipped DBC desk
(assembled by counter, with CANopen traffic mixed in), for four ATI boards (assembled by
polls), and for the path from python-can ``Message`` objects (what a live bus delivers),
which adds the conversion to arrays. Prints the best of ``--repeat`` runs, in frames/s.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from hapticdesk.canbus.assembler import FrameAssembler
from hapticdesk.canbus.config_reader import can_config
from hapticdesk.canbus.decoding import DeskDecoding, build_decoding
from hapticdesk.canbus.frame_encoder import FrameEncoder, encoder_for
from hapticdesk.canbus.frames import FrameArray
from hapticdesk.files.profile_reader import load_profile

TARGET = 96_000


def desk_samples(seconds: float, rate: float) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(0)
    n = int(seconds * rate)
    wrench = rng.normal(0.0, 2.0, (n, 4, 6))
    wrench[:, :, 2] += 34.0
    wrench[:, :, 3:] *= 0.02
    return np.arange(n) / rate, wrench


def with_canopen(frames: FrameArray, share: float) -> FrameArray:
    """Mix in CANopen traffic (SYNC, PDOs, heartbeats) as ``share`` of all frames."""
    rng = np.random.default_rng(1)
    n = int(len(frames) * share / (1 - share))
    ident = rng.choice([0x080, 0x181, 0x281, 0x701], n)
    other = FrameArray.build(
        np.sort(rng.uniform(frames.t[0], frames.t[-1], n)), ident, [bytes(4)] * n
    )
    both = FrameArray.concat([frames, other])
    return both.take(np.argsort(both.t, kind="stable"))


def best_rate(run, n_frames: int, repeat: int) -> float:
    best = float("inf")
    for _ in range(repeat):
        start = time.perf_counter()
        run()
        best = min(best, time.perf_counter() - start)
    return n_frames / best


def report(name: str, rate: float) -> None:
    verdict = "ok" if rate >= TARGET else "BELOW TARGET"
    print(f"  {name:<28} {rate:>12,.0f} frames/s  ({rate / TARGET:.1f}× the target, {verdict})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="desk time to decode")
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument(
        "--chunk", type=int, default=1200, help="frames per push (a live bus: ~100)"
    )
    args = parser.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})  # one core
    profile = load_profile("kitamura2017-can")
    t, wrench = desk_samples(args.seconds, profile.sample_rate_hz)
    dbc_config = can_config(profile)
    ati_config = encoder_for(profile, dbc_config, "ati")[1]
    ati_encoder = FrameEncoder(ati_config, profile)
    cases = {
        "DBC desk, by counter": (
            dbc_config,
            with_canopen(FrameEncoder(dbc_config, profile).encode(t, wrench), 0.1),
            None,
        ),
        "ATI boards, by polls": (
            ati_config,
            ati_encoder.encode(t, wrench, polls=True),
            ati_encoder.calibrations,
        ),
    }
    print(f"{len(t)} samples ({args.seconds:g} s of a 4-sensor desk at 1.2 kHz), one core")
    for name, (config, frames, calibrations) in cases.items():
        decoding = build_decoding(config, profile, calibrations)

        def decode(
            frames: FrameArray = frames,
            decoding: DeskDecoding = decoding,
            mode: str = config.assemble,
        ) -> None:
            asm = FrameAssembler(decoding, profile.sample_rate_hz, assemble=mode)
            for start in range(0, len(frames), args.chunk):
                asm.push(frames.take(slice(start, start + args.chunk)))
            asm.flush()
            assert asm.stats.samples == len(t)

        report(name, best_rate(decode, len(frames), args.repeat))
    # what a live bus hands over: python-can Messages, converted in chunks
    frames = cases["DBC desk, by counter"][1]
    messages = frames.to_messages()
    decoding = build_decoding(dbc_config, profile)

    def from_messages() -> None:
        asm = FrameAssembler(decoding, profile.sample_rate_hz, assemble="counter")
        for start in range(0, len(messages), args.chunk):
            asm.push(FrameArray.from_messages(messages[start : start + args.chunk]))
        asm.flush()

    rate = best_rate(from_messages, len(messages), args.repeat)
    report("DBC desk, from Messages", rate)


if __name__ == "__main__":
    main()
