"""What reading a board costs: a serial board's lines decoded into samples, per 10 ms read,
beside the estimator on the same samples (the reference, in the same run: the machine is
shared and noisy).

    python scripts/serial_decode_bench.py [--seconds 20] [--repeat 5]

Four load cells at 1 kHz and at 2 kHz (ADS1256-like offsets, checksums on), and the paper's
four six-axis sensors at 1.2 kHz (24 channels); the lines come in reads of 10 ms, as the
``serial:`` source hands them on. Prints the best of ``--repeat`` runs: µs per read for the
decoder and for the estimator, and the share of one core the decoder takes at that rate.
"""

from __future__ import annotations

import argparse
import logging
import tempfile
import time
from pathlib import Path

import numpy as np

from hapticdesk.boards.decoder import BoardDecoder
from hapticdesk.boards.hello import BoardHello, with_checksum
from hapticdesk.boards.settings import serial_settings
from hapticdesk.estimator import ContactEstimator
from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.profile_reader import builtin_profile_path, load_profile

CELLS = """\
name: cells
sample_rate_hz: {rate}
sensors:
  - {{name: fl, kind: load_cell, position: [-0.34, -0.22, 0.0]}}
  - {{name: fr, kind: load_cell, position: [0.34, -0.22, 0.0]}}
  - {{name: bl, kind: load_cell, position: [-0.34, 0.22, 0.0]}}
  - {{name: br, kind: load_cell, position: [0.34, 0.22, 0.0]}}
surfaces:
  - {{name: top, origin: [0, 0, 0.733], normal: [0, 0, 1],
     polygon: [[-0.375, -0.25], [0.375, -0.25], [0.375, 0.25], [-0.375, 0.25]]}}
"""


def board_bytes(desk: DeskProfile, seconds: float) -> tuple[bytes, int]:
    """A board's hello and ``seconds`` of sample lines for ``desk``, with checksums."""
    names = tuple(desk.channel_names())
    rate = desk.sample_rate_hz
    step = 1e6 / rate / len(names)
    hello = BoardHello(
        rate, names, offsets_us=tuple(round(i * step) for i in range(len(names))),
        checksum_required=True,
    )  # fmt: skip
    n = int(seconds * rate)
    rng = np.random.default_rng(0)
    counts = np.rint(rng.normal(6e5, 200, (n, len(names)))).astype(np.int64)  # 30 N ± 0.01
    lines = [with_checksum(hello.text())]
    lines += [with_checksum(f"{i}," + ",".join(map(str, row))) for i, row in enumerate(counts)]
    return ("\n".join(lines) + "\n").encode(), n


def reads(data: bytes, n_lines: int, lines_per_read: int) -> list[bytes]:
    """``data`` cut where a read of ``lines_per_read`` lines would end (10 ms of lines)."""
    ends = (np.flatnonzero(np.frombuffer(data, np.uint8) == 10) + 1)[::lines_per_read].tolist()
    cuts = [0, *ends[1:], len(data)]
    return [data[a:b] for a, b in zip(cuts[:-1], cuts[1:], strict=True)]


def best(run, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        run()
        times.append(time.perf_counter() - start)
    return min(times)


def bench(name: str, desk: DeskProfile, seconds: float, repeat: int) -> None:
    data, n = board_bytes(desk, seconds)
    per_read = round(desk.sample_rate_hz * 0.01)
    chunks = reads(data, n, per_read)
    settings = serial_settings(desk, "/dev/null?scale=5e-5&zero=0")
    blocks = []

    def decode() -> None:
        blocks.clear()
        decoder = BoardDecoder(desk, settings)
        blocks.extend(decoder.push([(0.0, chunk)]) for chunk in chunks)

    def estimate() -> None:
        estimator = ContactEstimator(desk)
        for block in blocks:
            if len(block.t):
                estimator.push(block.t, block.channels)

    decode_s = best(decode, repeat)
    estimate_s = best(estimate, repeat)
    n_reads = len(chunks)
    decoder_us, estimator_us = decode_s / n_reads * 1e6, estimate_s / n_reads * 1e6
    print(
        f"{name:34s} {per_read:3d} lines/read: decoder {decoder_us:6.0f} µs/read "
        f"({decode_s / seconds * 100:4.1f} % of a core), estimator {estimator_us:6.0f} "
        f"µs/read; {sum(len(b.t) for b in blocks)} of {n} samples"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    logging.getLogger("hapticdesk").setLevel(logging.ERROR)  # (the tare's notices)
    folder = Path(tempfile.mkdtemp())
    for rate in (1000, 2000):
        path = folder / f"cells-{rate}.yaml"
        path.write_text(CELLS.format(rate=rate))
        bench(f"four load cells at {rate} Hz", load_profile(path), args.seconds, args.repeat)
    paper = builtin_profile_path("kitamura2017")
    assert paper is not None
    bench("four six-axis sensors at 1200 Hz", load_profile(paper), args.seconds, args.repeat)


if __name__ == "__main__":
    main()
