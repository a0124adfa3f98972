"""The desk in the browser: a live view, a layout designer, stroke recording.

    hapticdesk ui --layout my-layout.yaml                 # the simulator's demo scene, no actions
    hapticdesk run --layout L --source can:socketcan:can0 --ui 8765

The page (``static/``, hand-written, nothing fetched at run time) is served by Starlette and
uvicorn in a thread of their own (the ``ui`` extra: ``pip install 'hapticdesk[ui]'``). This
module only registers hooks and imports nothing heavy (``hapticdesk --help`` loads it):

- ``register_commands``: ``hapticdesk ui``;
- ``event_sink``: with ``run --ui [HOST:]PORT`` (the ``ui`` override, with ``token_file``
  from ``run --token-file``), starts the server and hands it every gesture event, on a
  dispatcher lane;
- ``startup``: gives the server the run (the latest contact sample, notices, action counts,
  and the reload that a saved layout triggers).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

from hapticdesk.hookspecs import hookimpl
from hapticdesk.runtime.dispatcher import ActionContext

if TYPE_CHECKING:  # (numpy with them: the hooks load for `hapticdesk --help`)
    from hapticdesk.files.profile import DeskProfile
    from hapticdesk.gestures.event import GestureEvent
    from hapticdesk.gestures.layout import Layout
    from hapticdesk.plugins.ui.server import UiServer
    from hapticdesk.runtime.service import Runtime

SECTION = "ui"  # the override key `run --ui` sets
SHARED = "ui server"  # the ActionContext.shared key of a run's server


@hookimpl
def register_commands(register: Callable[..., None]) -> None:
    register(
        "ui",
        "hapticdesk.plugins.ui.command",
        "the desk in the browser: live view, layout designer, strokes",
    )


@hookimpl
def event_sink(
    desk: DeskProfile, layout: Layout, context: ActionContext
) -> Callable[[GestureEvent], None] | None:
    wanted = context.overrides.get(SECTION)
    if not wanted:
        return None

    from hapticdesk.extras import require

    require("starlette", "uvicorn", "ruamel.yaml", needed_by="the browser UI (`--ui`)")

    def open_server() -> UiServer:
        from hapticdesk.plugins.ui.page_token import page_token
        from hapticdesk.plugins.ui.server import UiServer, parse_listen

        host, port = parse_listen(str(wanted["listen"]))
        token, where = page_token(wanted.get("token"), wanted.get("token_file"))
        server = UiServer(
            layout.path,
            None,  # the registry arrives with the run, in startup
            host=host,
            port=port,
            token=token,
            token_from=where,  # (a short token's refusal names the file it came from)
            desk=desk,
        )
        server.start()
        import sys

        print(server.said, file=sys.stderr, flush=True)
        return server

    server: UiServer = context.shared(SHARED, open_server)  # closed with the run's resources
    return server.on_gesture


@hookimpl
def startup(runtime: Runtime) -> None:
    server = runtime.scene.context.resource(SHARED) if runtime is not None else None
    if server is not None:
        server.registry = runtime.scene.registry
        server.attach(runtime)
