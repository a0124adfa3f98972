"""How fast can the live ATI path poll a desk of NETCANOEM boards? (issue 11 item 19)

Emulated boards answer polls on a python-can bus; a live CAN source polls them at the
profile's rate for a few seconds, and each block read is estimated as ``hapticdesk run``
does (``--estimate METHOD``, the profile's by default; ``none`` to only read). Prints the
samples per second delivered, the share of samples with missing data (NaN), the decoder's
counts and the share of the time spent estimating (issue 29: the estimator's compiled
kernels release the GIL, so the poller and the emulator run meanwhile), and the share of
the samples due (one a period, from the first to the last) that never came.

    python scripts/ati_live_rate.py --rate 1200 --boards 4 --bus virtual
    python scripts/ati_live_rate.py --rate 1200 --boards 4 --bus virtual --estimate none
    python scripts/ati_live_rate.py --rate 1200 --boards 4 --bus udp_multicast

``virtual`` runs the emulator in this process (a thread: it shares the GIL with the poller
and the reader); ``udp_multicast`` runs ``hapticdesk emulate`` in its own process (python-can
needs ``pip install msgpack`` for it). The CPU per sample delivered is printed beside the
load average: on a shared host the rate follows the share of a core the process gets, the
CPU per sample does much less.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

LEGS = """name: ati-rate
sample_rate_hz: {rate}
sensors:
{sensors}
surfaces:
  - {{name: top, origin: [0, 0, 0.733], normal: [0, 0, 1],
     polygon: [[-0.375, -0.25], [0.375, -0.25], [0.375, 0.25], [-0.375, 0.25]]}}
can:
  silent_timeout_s: 0.5
  sensors:
{boards}
"""
POSITIONS = [(-0.34, -0.22), (0.34, -0.22), (-0.34, 0.22), (0.34, 0.22)]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rate", type=float, default=1200.0)
    parser.add_argument("--boards", type=int, default=4, choices=[3, 4])
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--bus", choices=["virtual", "udp_multicast"], default="virtual")
    parser.add_argument(
        "--estimate",
        choices=["profile", "none", "force", "diff", "switched", "fused"],
        default="profile",
        help="estimate each block read with this method (profile: the profile's; none: no)",
    )
    args = parser.parse_args()

    from hapticdesk.canbus.config_reader import can_config
    from hapticdesk.canbus.emulator import CanEmulator
    from hapticdesk.canbus.frame_encoder import FrameEncoder
    from hapticdesk.canbus.source import CanSource
    from hapticdesk.files.profile_reader import load_profile
    from hapticdesk.files.recording import Recording
    from hapticdesk.files.recording_io import write_recording

    names = ["fl", "fr", "bl", "br"][: args.boards]
    tmp = Path(tempfile.mkdtemp(prefix="ati-rate-"))
    profile_path = tmp / "ati-rate.yaml"
    profile_path.write_text(
        LEGS.format(
            rate=args.rate,
            sensors="\n".join(
                f"  - {{name: {n}, position: [{x}, {y}, 0.0]}}"
                for n, (x, y) in zip(names, POSITIONS, strict=False)
            ),
            boards="\n".join(
                f"    {n}: {{ati_netcanoem: {{base: 0x2{i}}}}}" for i, n in enumerate(names)
            ),
        )
    )
    profile = load_profile(str(profile_path))
    k = int(args.rate * 5)
    rng = np.random.default_rng(0)
    t = np.arange(k) / args.rate
    wrench = rng.normal(0, 0.05, (k, len(names), 6))
    wrench[:, :, 2] += 34.0
    wrench[:, :, 3:] *= 0.02

    channel = f"ati-rate-{time.time_ns()}" if args.bus == "virtual" else "239.74.163.2"
    emulator_thread = None
    process = None
    if args.bus == "virtual":
        import can

        bus = can.Bus(interface="virtual", channel=channel, receive_own_messages=False)
        emulator = CanEmulator(
            FrameEncoder(can_config(profile), profile), t, wrench, bus, loop=True
        )
        emulator_thread = emulator.start()
    else:
        recording = tmp / "rec.npz"
        write_recording(recording, Recording(t, wrench, names))
        process = subprocess.Popen(
            [sys.executable, "-m", "hapticdesk", "emulate", "--desk", str(profile_path),
             "--recording", str(recording), "--bus", f"udp_multicast:{channel}", "--loop"]
        )  # fmt: skip
        time.sleep(1.5)  # its interpreter and imports
    estimator = None
    if args.estimate != "none":
        from hapticdesk.estimator import ContactEstimator

        # (built, its kernels compiled or loaded, before the clock starts)
        method = None if args.estimate == "profile" else args.estimate
        estimator = ContactEstimator(profile, method=method)
    source = CanSource(f"can:{args.bus}:{channel}", profile, calibration_timeout_s=2.0)
    got = []
    times = []
    estimating = 0.0
    start = time.monotonic()
    cpu_start = time.process_time()  # every thread of this process: poller, reader, emulator
    try:
        for block in source.blocks():
            got.append(block.wrench)
            times.append(block.t)
            if estimator is not None:
                began = time.perf_counter()
                estimator.push(block.t, block.wrench, block.accel)
                estimating += time.perf_counter() - began
            if time.monotonic() - start > args.seconds:
                break
    finally:
        source.close()
        if emulator_thread is not None:
            emulator.stop()
            emulator_thread.join(2)
            bus.shutdown()
        if process is not None:
            process.terminate()
            process.wait(5)
    wall = time.monotonic() - start
    cpu = time.process_time() - cpu_start
    w = np.concatenate(got) if got else np.zeros((0, len(names), 6))
    nan = np.isnan(w).any(axis=(1, 2))
    print(
        f"{args.boards} board(s) polled at {args.rate:g} Hz over {args.bus} for {wall:.1f} s: "
        f"{len(w)} samples ({len(w) / wall:.0f}/s), {nan.mean() * 100 if len(w) else 0:.2f} % "
        "with missing data; "
        + (
            "not estimated"
            if estimator is None
            else f"estimated ({estimator.method}) in {estimating:.2f} s ({estimating / wall:.1%})"
        )
    )
    print(
        f"  CPU of this process {cpu:.2f} s ({cpu / wall:.0%} of one core), "
        f"{1e6 * cpu / max(len(w), 1):.0f} µs per sample delivered"
        + (" (the emulator's included)" if args.bus == "virtual" else "")
        + f"; load average {Path('/proc/loadavg').read_text().split()[0]}"
        if Path("/proc/loadavg").exists()
        else ""
    )
    if len(w) > 1:
        # the samples due from the first to the last (the poller's clock, one a period), and
        # the share of them that never came: rounds not polled in time, the missing samples
        t = np.concatenate(times)
        due = int(round((t[-1] - t[0]) * args.rate)) + 1
        print(
            f"  {len(w)} of {due} samples due from the first to the last delivered: "
            f"{100 * max(due - len(w), 0) / due:.2f} % missing"
        )
    for line in source.stats.summary():
        print("  " + line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
