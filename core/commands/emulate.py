"""``hapticdesk emulate --desk D --scene S (--bus INTERFACE:CHANNEL [--encoding dbc|ati] |
--serial)``.

Sends a simulated desk's sensor frames onto a CAN bus (python-can's virtual bus, a SocketCAN
vcan or real hardware), so the whole CAN path can be tried without sensors; or, with
``--serial``, prints its samples as a board on a serial line does, on a pseudo-terminal whose
path it says (:mod:`hapticdesk.boards.emulator`: ``run --source serial:PATH`` reads it).
``--recording`` sends a recorded CSV/NPZ instead of a scene. Database desks stream, paced by
sample time (``--speed 1``, the default; ``--speed 0`` as fast as possible); ATI boards answer
polls, one sample per poll, and their calibration requests, so the poller sets the pace.

python-can's ``virtual`` bus only reaches buses in the same process: to emulate for another
program use a SocketCAN ``vcan`` interface (``ip link add dev vcan0 type vcan``) or
``udp_multicast``.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import signal
import sys
import time
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

from hapticdesk.commands import bit_rate, seed_number
from hapticdesk.errors import ConfigError
from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.profile_reader import load_profile
from hapticdesk.files.recording import Recording
from hapticdesk.files.recording_io import read_recording
from hapticdesk.runtime.pacing import check_speed


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--desk", required=True, help="desk profile name or path")
    what = parser.add_mutually_exclusive_group(required=True)
    what.add_argument("--scene", help="scene YAML to simulate and send")
    what.add_argument("--recording", help="recording (.csv, .npz) to send instead of a scene")
    where = parser.add_mutually_exclusive_group(required=True)
    where.add_argument("--bus", help="INTERFACE:CHANNEL, e.g. socketcan:vcan0 or virtual:desk")
    where.add_argument(
        "--serial",
        action="store_true",
        help="a board on a serial line instead: a pseudo-terminal (its path is printed) "
        "printing the lines of docs/serial.md",
    )
    parser.add_argument(
        "--encoding",
        choices=("dbc", "ati"),
        help="frames as the profile's database signals or ATI NETCANOEM boards "
        "(default: as the profile's `can:` says)",
    )
    parser.add_argument(
        "--speed", type=float, default=1.0, help="1 real time (default), 0 as fast as possible"
    )
    parser.add_argument("--loop", action="store_true", help="start over at the end, until Ctrl-C")
    parser.add_argument("--bitrate", type=bit_rate, help="CAN bit rate")
    parser.add_argument("--seed", type=seed_number, help="simulation seed")
    parser.add_argument("--json", action="store_true", help="print a JSON summary")


class _BusAddress(NamedTuple):
    """``--bus INTERFACE:CHANNEL`` read."""

    interface: str
    channel: str


def run(args: argparse.Namespace) -> int:
    if args.serial:
        return _run_serial(args)
    import can  # (a missing python-can is named before any work)

    from hapticdesk.canbus.config_reader import can_config
    from hapticdesk.canbus.emulator import CanEmulator
    from hapticdesk.canbus.frame_encoder import encoder_for

    check_speed(args.speed)  # as `run` paces a replay
    address = _bus_address(args.bus)
    profile = load_profile(args.desk)
    config = can_config(profile) if profile.can is not None else None
    encoder, used = encoder_for(profile, config, args.encoding)
    rec = _samples(args, profile)
    if used is not config:
        bases = ", ".join(
            f"{n}: {{ati_netcanoem: {{base: 0x{s.base:02X}}}}}" for n, s in used.sensors.items()
        )
        print(
            f"emulating ATI boards; decode them with  can: {{sensors: {{{bases}}}}}",
            file=sys.stderr,
        )
    bus = _open_bus(can.Bus, address, args.bitrate)
    from hapticdesk.estimator.inertia import accelerometer_readings

    accel = accelerometer_readings(profile, rec.extra)  # None: the desk has no accelerometer
    emulator = CanEmulator(
        encoder, rec.t, rec.wrench, bus, speed=args.speed, loop=args.loop, accel=accel
    )
    start = time.perf_counter()
    try:
        with _stopped_by_signals(emulator.stop):
            until = "Ctrl-C stops" if args.loop else "to the end; Ctrl-C stops"
            print(
                f"sending desk {profile.name} on {args.bus} ({until})", file=sys.stderr, flush=True
            )
            emulator.run()
    finally:
        bus.shutdown()
    stats = emulator.stats
    summary = {
        "desk": profile.name,
        "bus": args.bus,
        "encoding": "ati" if used.ati_sensors else "dbc",
        "samples": stats.samples,
        "frames": stats.frames,
        "polls": stats.polls,
        "seconds": round(time.perf_counter() - start, 3),
    }
    if args.json:
        print(json.dumps(summary))
    else:
        print(
            f"sent {stats.frames} frames ({stats.samples} samples, {summary['encoding']}) "
            f"on {args.bus} in {summary['seconds']:.2f} s"
        )
    return 0


def _run_serial(args: argparse.Namespace) -> int:
    """``--serial``: the desk's samples printed on a pseudo-terminal until the end (or
    Ctrl-C; with ``--loop`` until Ctrl-C), the board then still answering its hello."""
    from hapticdesk.boards.emulator import PtyBoard, board_lines
    from hapticdesk.estimator.inertia import accelerometer_readings

    check_speed(args.speed)
    profile = load_profile(args.desk)
    rec = _samples(args, profile)
    values = rec.wrench.reshape(len(rec), -1)
    accel = accelerometer_readings(profile, rec.extra)
    if accel is not None:
        values = np.concatenate([values, accel], axis=1)
    hello, lines = board_lines(profile, values)
    board = PtyBoard(hello, lines, rec.t, speed=args.speed, loop=args.loop)
    print(
        f"a board of desk {profile.name} on {board.path}: read it with  hapticdesk run "
        f"--desk {args.desk} --source serial:{board.path}  (Ctrl-C stops)",
        file=sys.stderr,
        flush=True,
    )
    start = time.perf_counter()
    try:
        with _stopped_by_signals(board.halt):
            board.run()
    finally:
        board.stop()
    summary = {"desk": profile.name, "port": board.path, "samples": board.printed,
               "seconds": round(time.perf_counter() - start, 3)}  # fmt: skip
    print(json.dumps(summary) if args.json else f"printed {board.printed} samples on {board.path}")
    return 0


def _stopped_by_signals(stop: Callable[[], None]) -> contextlib.AbstractContextManager[None]:
    """``stop`` called on Ctrl-C or a kill (SIGINT, SIGTERM) while the block runs, so the
    emulator ends its run and its summary is printed. By handlers of its own: a process
    started in the background by a shell ignores Ctrl-C's KeyboardInterrupt. Off the
    handler (:mod:`hapticdesk.runtime.signal_handoff`: set in it, the stop Event's lock
    could be the one the emulator's own wait held, and it hung for good)."""
    from hapticdesk.runtime.signal_handoff import signals_handed_off

    return signals_handed_off({signal.SIGINT: lambda _: stop(), signal.SIGTERM: lambda _: stop()})


def _bus_address(bus: str) -> _BusAddress:
    interface, sep, channel = bus.partition(":")
    if not sep or not interface:
        raise ConfigError("--bus", f"expected INTERFACE:CHANNEL (e.g. virtual:desk), found {bus!r}")
    return _BusAddress(interface, channel)


def _samples(args: argparse.Namespace, profile: DeskProfile) -> Recording:
    """The recording to send, or the scene simulated; refused when empty."""
    if args.recording:
        rec = read_recording(args.recording, profile.sensor_names)
    else:
        from hapticdesk.sim import load_scene, simulate

        rec = simulate(profile, load_scene(args.scene), args.seed)
    if not len(rec):
        raise ConfigError(args.recording or args.scene, "nothing to send: no samples")
    if args.loop and len(rec) < 2:  # (one sample has no spacing: the loop sent it unpaced)
        raise ConfigError(
            "--loop",
            f"{args.recording or args.scene} has one sample: expected two or more to repeat "
            "(their spacing paces the loop)",
        )
    return rec


def _open_bus(bus_class: Callable[..., Any], address: _BusAddress, bitrate: int | None) -> Any:
    """The python-can bus (``can.Bus``) to send on (a virtual bus keeps the frames' sample
    times)."""
    from hapticdesk.canbus.bus_spec import bus_cannot_open

    kwargs: dict[str, Any] = {"interface": address.interface, "channel": address.channel}
    if address.interface == "virtual":  # frames keep their sample times, whatever the speed
        kwargs["preserve_timestamps"] = True
    if bitrate:
        kwargs["bitrate"] = bitrate
    try:
        return bus_class(**kwargs)
    except Exception as err:
        raise ConfigError(
            "--bus", bus_cannot_open(address.interface, address.channel, err)
        ) from None
