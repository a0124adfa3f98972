"""``hapticdesk run``: sense, recognise gestures and dispatch actions until the source ends.

    hapticdesk run --layout living-room.yaml --source can:socketcan:can0
    hapticdesk run --layout demo.yaml --source replay:session.csv --speed 0 --events out.jsonl
    hapticdesk run --layout plate.yaml --source replay:walk.c3d --plate 2   # the plate is the desk

SIGINT (Ctrl-C) or SIGTERM stop it cleanly: queued commands get ``--drain`` seconds to go out
and whatever did not is reported. A second signal stops at once.

Exit status: 0 when every command was delivered, 3 when the run went through but some were
not (an action failed, timed out or dropped events, or a broker refused the login or was away
at the end; the last line says which), 1 on an error that stopped sensing, 2 on a bad layout
or option.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from hapticdesk.commands.output_path import check_output_path
from hapticdesk.commands.recording_input import plate_number, source_desk
from hapticdesk.errors import ConfigError
from hapticdesk.plugin_loading import load_registry
from hapticdesk.runtime.assembly import build_scene
from hapticdesk.runtime.run_report import RunReport, report_json
from hapticdesk.runtime.service import Runtime

UNDELIVERED_EXIT = 3


#: the longest wait a time option takes (a day)
MAX_SECONDS = 86_400.0


def seconds(text: str) -> float:
    """An argparse type: a finite number of seconds, 0 or more."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected seconds (a number), found {text!r}") from None
    if not math.isfinite(value) or value < 0:
        raise argparse.ArgumentTypeError(f"expected a finite number of seconds >= 0, found {text}")
    if value > MAX_SECONDS:  # (a wait that long overflows the clock's timeout)
        raise argparse.ArgumentTypeError(f"expected at most {MAX_SECONDS:g} seconds, found {text}")
    return value


def positive_seconds(text: str) -> float:
    """An argparse type: a finite number of seconds above 0."""
    value = seconds(text)
    if value == 0:
        raise argparse.ArgumentTypeError("expected a number of seconds above 0, found 0")
    return value


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--layout", required=True, help="the layout YAML")
    parser.add_argument("--desk", help="desk profile name or path (overrides the layout's desk:)")
    parser.add_argument(
        "--plate",
        type=plate_number,
        metavar="N",
        help="with --source replay:FILE.c3d and no --desk: the file's force plate that is the "
        "desk, from 1 (default 1)",
    )
    parser.add_argument(
        "--source",
        required=True,
        help="sim:SCENE.yaml, replay:FILE (recording or CAN log), can:INTERFACE:CHANNEL, "
        "serial:PORT[?baud=N] (a board on a serial line)",
    )
    parser.add_argument(
        "--speed",
        type=float,
        default=1.0,
        help="replay/simulation speed: 1 real time (default), 0 as fast as possible",
    )
    parser.add_argument("--events", metavar="FILE.jsonl", help="write every gesture event here")
    parser.add_argument(
        "--mqtt", metavar="URL", help="broker URL, overriding the layout's mqtt.broker"
    )
    parser.add_argument(
        "--strict", action="store_true", help="a plugin that fails to load is fatal"
    )
    parser.add_argument(
        "--status",
        action="store_true",
        help="show the live status line even when stderr is not a terminal",
    )
    parser.add_argument(
        "--action-timeout",
        type=positive_seconds,
        metavar="S",
        help="give up on an action call after S seconds (default: the action's own, else 5)",
    )
    parser.add_argument(
        "--drain",
        type=seconds,
        default=5.0,
        metavar="S",
        help="at the end, wait up to S seconds for queued commands (default 5)",
    )
    parser.add_argument(
        "--ui",
        metavar="[HOST:]PORT",
        help="serve the browser view and layout designer (127.0.0.1 unless a HOST is given; "
        "another host needs a token, see `hapticdesk ui --help`); needs the `ui` extra",
    )
    parser.add_argument(
        "--token-file",
        metavar="PATH",
        help="with --ui: the page's token, the file's first line (keep it mode 600; default "
        "$HAPTICDESK_UI_TOKEN)",
    )
    parser.add_argument("--json", action="store_true", help="print the run's report as JSON")


def run(args: argparse.Namespace) -> int:
    if args.token_file and not args.ui:
        raise ConfigError("--token-file", "is the token of the page --ui serves: give --ui too")
    if args.events:
        check_events_path(args)
    registry = load_registry(strict=args.strict)
    # a C3D replay brings its desk, its plate, unless --desk says otherwise
    desk = source_desk(args.source, args.plate, given=args.desk) or args.desk
    scene = build_scene(
        args.layout,
        args.source,
        registry,
        desk=desk,
        speed=args.speed,
        overrides=overrides(args),
        action_timeout_s=args.action_timeout,
    )
    if desk is not args.desk and "desk" in scene.layout.raw:  # (the plate's desk, not it)
        print(
            f"hapticdesk run: the layout's `desk: {scene.layout.raw['desk']}` is not used: a "
            f"C3D replay's desk is its force plate {args.plate or 1} (--desk chooses another)",
            file=sys.stderr,
        )
    show_status = args.status or sys.stderr.isatty()
    runtime = Runtime(
        scene,
        events_path=args.events,
        status=sys.stderr if show_status else None,
        drain_timeout_s=args.drain,
    )
    report = runtime.run()
    for line in report.summary():
        print(line, file=sys.stderr)
    if args.json:
        print(report_json(report))
    if report.error:
        return 1
    problems = undelivered(report, scene.context.failures) + report.output_failures
    if problems:
        print(f"error: not everything was delivered: {'; '.join(problems)}", file=sys.stderr)
        return UNDELIVERED_EXIT
    return 0


def check_events_path(args: argparse.Namespace) -> None:
    """``--events`` names a file to write, none that the run reads: ``--events rec.csv``
    with ``--source replay:rec.csv`` wrote over the recording as it was replayed (the run
    then failed on a line it had cut), ``--events`` at the layout replaced it."""
    check_output_path(
        Path(args.events),
        "--events",
        what="the events",
        reads={
            "the layout": args.layout,
            "the desk profile": args.desk,
            "the file --source reads": args.source.partition(":")[2],
        },
    )


def overrides(args: argparse.Namespace) -> dict[str, dict[str, str]]:
    """Command-line values over plugins' layout sections, by section name: ``--mqtt`` for
    the MQTT plugin's ``mqtt:`` (the flag predates plugin sections), ``--ui`` for the UI's."""
    out: dict[str, dict[str, str]] = {}
    if args.mqtt:
        out["mqtt"] = {"broker": args.mqtt}
    if getattr(args, "ui", None):
        out["ui"] = {"listen": args.ui}
        if getattr(args, "token_file", None):  # (the path: the page's plugin reads the token)
            out["ui"]["token_file"] = args.token_file
    return out


def undelivered(report: RunReport, failures: list[str]) -> list[str]:
    """What the run did not deliver: action calls that did not succeed, and what shared
    connections (MQTT) reported when they closed."""
    d = report.dispatch.totals
    lost = d.failed + d.timed_out + d.dropped + d.not_run
    calls = [f"{lost} action call(s) failed, timed out, were dropped or not run"] if lost else []
    return calls + failures
