"""``hapticdesk ui``: the browser view of a desk, with the layout designer.

    hapticdesk ui [--layout L] [--desk D] [--source SPEC] [--speed X] [--host H] [--port P]

Like ``run`` without actions (``--actions`` runs them): the layout's gestures are recognised
and shown, nothing is sent. A ``--layout`` that does not exist yet is created as ``hapticdesk
init`` makes one (for ``--desk``, else the paper's desk). ``--source`` defaults to the
simulator playing the demo scene. The page stays up after a finite source ends, until
Ctrl-C. Without ``--layout`` the demo layout is shown and cannot be saved. Listening anywhere
but loopback needs a token of 12 characters or more (``--token-file PATH``, the file's first
line; ``HAPTICDESK_UI_TOKEN``; or ``--token``, which ``ps`` shows other users: :mod:`.page_token`);
the address printed never carries it: the page asks for it (``.login``).
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from pathlib import Path

from hapticdesk.errors import ConfigError
from hapticdesk.plugins.ui.page_token import TOKEN_ENV


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--layout", help="the layout YAML to show and edit (saved in place; created if missing)"
    )
    parser.add_argument("--desk", help="desk profile name or path (overrides the layout's desk:)")
    parser.add_argument(
        "--source", help="sim:SCENE.yaml, replay:FILE, can:IF:CHANNEL (default: the demo scene)"
    )
    parser.add_argument("--speed", type=float, default=1.0, help="1 real time (default)")
    parser.add_argument("--host", default="127.0.0.1", help="where to listen (127.0.0.1)")
    parser.add_argument("--port", type=int, default=8765, help="port (8765; 0: any free one)")
    given = parser.add_mutually_exclusive_group()
    given.add_argument(
        "--token-file",
        metavar="PATH",
        help=f"the page's token: the file's first line (keep it mode 600; default ${TOKEN_ENV})",
    )
    given.add_argument(
        "--token",
        help=f"required from the page (default ${TOKEN_ENV}; on the command line it is "
        "visible to this machine's other users: prefer --token-file)",
    )
    parser.add_argument(
        "--actions", action="store_true", help="run the layout's actions too (off by default)"
    )


def _token(args: argparse.Namespace) -> str | None:
    """The page's token, checked as the server checks it (guard.check_token) but before a
    new layout is written and naming this command's options (``ui --layout new.yaml --host
    0.0.0.0`` wrote new.yaml, then refused)."""
    from hapticdesk.plugins.ui.guard import check_token
    from hapticdesk.plugins.ui.page_token import page_token

    token, where = page_token(args.token, args.token_file)
    check_token(args.host, token, "--host", where)
    return token


def run(args: argparse.Namespace) -> int:
    from hapticdesk.extras import require

    require("starlette", "uvicorn", "ruamel.yaml", needed_by="the browser UI")
    if not 0 <= args.port <= 65535:  # (uvicorn's bind failed with a traceback in its thread)
        raise ConfigError("--port", f"expected a port 0..65535, found {args.port}")
    from hapticdesk.files.profile_reader import load_profile
    from hapticdesk.plugin_loading import load_registry
    from hapticdesk.plugins.mqtt.demo import examples_dir
    from hapticdesk.plugins.ui.server import UiServer
    from hapticdesk.runtime.assembly import build_scene
    from hapticdesk.runtime.lane import Lane
    from hapticdesk.runtime.service import Runtime
    from hapticdesk.runtime.signal_handoff import signals_handed_off

    token = _token(args)  # (before a new layout is written)
    examples = examples_dir()
    layout = Path(args.layout) if args.layout else examples / "layouts" / "demo.yaml"
    if args.layout and not layout.exists():  # a new layout: started as `hapticdesk init` does
        from hapticdesk.commands.init import DEFAULT_DESK, write_starter

        desk = write_starter(layout, args.desk or DEFAULT_DESK)
        print(f"hapticdesk ui: created {layout}, a new layout for desk {desk}", file=sys.stderr)
    source = args.source or f"sim:{examples / 'scenes' / 'demo.yaml'}"
    registry = load_registry()
    server = UiServer(
        layout,
        registry,
        host=args.host,
        port=args.port,
        token=token,
        desk=load_profile(args.desk) if args.desk else None,
        read_only=args.layout is None,
    )
    scene = build_scene(
        layout, source, registry, desk=args.desk, speed=args.speed, actions=args.actions
    )
    scene.dispatcher.add_sink(Lane("every event → ui", server.on_gesture))
    server.start()
    print(server.said, file=sys.stderr, flush=True)
    runtime = Runtime(scene, drain_timeout_s=1.0)
    server.attach(runtime)
    report = runtime.run()
    server.detach(runtime)  # a save now only writes the file; the view shows the saved layout
    server.broadcast_desk()
    for line in report.summary():
        print(line, file=sys.stderr)
    if runtime.report.stopped_by is None:  # the source ended: the page stays for the designer
        print("the source ended; the page stays up (Ctrl-C to stop)", file=sys.stderr, flush=True)
        stop = threading.Event()
        # (set off the handler: in it, the Event's lock could be the one its wait held)
        ended = {s: (lambda _signum: stop.set()) for s in (signal.SIGINT, signal.SIGTERM)}
        with signals_handed_off(ended):
            while not stop.wait(0.5):
                pass
    server.close()
    return 1 if report.error else 0
