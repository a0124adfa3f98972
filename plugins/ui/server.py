"""The browser UI's server: the page, the layout API and a WebSocket hub, in its own thread.

Uvicorn runs in a thread with its own event loop, so nothing here runs on the sensing
thread. The run reaches the page through three doors, none of which can slow sensing:

- the latest contact sample, which the sensing thread already copies once per block into
  ``runtime.live.sample`` (O(1)); the feed thread (:mod:`.feed`) reads it 50 times a second;
- gesture events through the plugin's event sink (a dispatcher lane, off the sensing thread);
- the estimator's notices and the actions' counts, read by the same feed thread.

Every request passes one guard first (:mod:`.guard`: Host and Origin, the token, the body's
size, confined reads); the handlers are grouped by job: the page (:mod:`.page`), the layout
(:mod:`.layout_api`), strokes (:mod:`.strokes_api`), the set-up check (:mod:`.setup_api`),
the set-up with a known weight (:mod:`.known_weight_setup`) and the WebSocket hub (:mod:`.hub`).
"""

from __future__ import annotations

import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING

import uvicorn
from starlette.applications import Starlette
from starlette.middleware import Middleware
from starlette.routing import BaseRoute

from hapticdesk.errors import ConfigError
from hapticdesk.plugins.ui import (
    hub,
    known_weight_setup,
    layout_api,
    page,
    setup_api,
    strokes_api,
)
from hapticdesk.plugins.ui.answers import EXCEPTION_HANDLERS, OneLineErrors
from hapticdesk.plugins.ui.feed import Feed
from hapticdesk.plugins.ui.guard import PageGuard, check_token, host_names
from hapticdesk.plugins.ui.hub import MAX_WS_CLIENTS, WS_MAX_MESSAGE_BYTES, Hub
from hapticdesk.plugins.ui.shown_desk import ShownDesk

if TYPE_CHECKING:
    from hapticdesk.files.profile import DeskProfile
    from hapticdesk.gestures.event import GestureEvent
    from hapticdesk.gestures.layout import Layout
    from hapticdesk.registry import Registry
    from hapticdesk.runtime.service import Runtime

#: connections uvicorn serves at once (pages and API calls); beyond, it answers 503
MAX_CONNECTIONS = MAX_WS_CLIENTS + 32
#: at the close, how long open connections are given to end before they are dropped (s); the
#: close waits twice this for the server's thread
CLOSE_GRACE_S = 1.0

#: the modules whose ``ROUTES`` the page's server serves, one a job (a new group of endpoints
#: is a module with its ``ROUTES``, named here)
ROUTE_MODULES = [
    page,
    layout_api,
    strokes_api,
    setup_api,
    known_weight_setup,
    hub,
]

#: the HTTP contract (README, "Browser UI"; docs/reference from these routes)
ROUTES: list[BaseRoute] = [route for module in ROUTE_MODULES for route in module.ROUTES]


def parse_listen(text: str) -> tuple[str, int]:
    """``[HOST:]PORT`` → (host, port); host 127.0.0.1 when not given."""
    host, _, port = text.rpartition(":")
    try:
        number = int(port)
    except ValueError:
        raise ConfigError("--ui", f"expected [HOST:]PORT, found {text!r}") from None
    if not 0 <= number <= 65535:
        raise ConfigError("--ui", f"expected a port 0..65535, found {number}")
    return (host.strip("[]") or "127.0.0.1"), number


class UiServer:
    """The page and its API for one layout file, and the live view of whichever run is
    attached (:meth:`attach`). ``token``: required from every request when not None (a
    refusal of it names ``token_from``: where it came from); ``desk``: a profile overriding
    the layout's ``desk:``; ``read_only``: the shipped demo layout, shown and never written."""

    def __init__(
        self,
        layout_path: Path,
        registry: Registry | None,
        *,
        host: str = "127.0.0.1",
        port: int = 8765,
        token: str | None = None,
        token_from: str = "--ui",
        desk: DeskProfile | None = None,
        read_only: bool = False,
    ) -> None:
        check_token(host, token, "--ui", token_from)
        self.shown = ShownDesk(layout_path, registry, desk, read_only)
        self.hub = Hub()
        self.host, self.port = host, port
        self.token = token
        self._host_names = host_names()
        self._server: uvicorn.Server | None = None
        self._thread: threading.Thread | None = None
        self._feed = Feed(self.shown, self.hub)

    def app(self) -> OneLineErrors:
        """The Starlette application: :data:`ROUTES` behind the guard."""
        guard = Middleware(
            PageGuard,
            bound=self.host,
            token=self.token,
            names=self._host_names,
            roots=self.shown.read_roots,
        )
        app = Starlette(
            routes=ROUTES,
            middleware=[guard],
            lifespan=self.hub.lifespan,
            exception_handlers=EXCEPTION_HANDLERS,
        )
        app.state.shown, app.state.hub, app.state.token = self.shown, self.hub, self.token
        app.state.setup = None  # the set-up check under way (setup_api)
        return OneLineErrors(app)

    # --- life ---------------------------------------------------------------------------------

    def start(self, timeout_s: float = 10.0) -> None:
        """Start serving in a thread; returns once the port is bound (ConfigError if not)."""
        config = uvicorn.Config(
            self.app(),
            host=self.host,
            port=self.port,
            log_level="warning",
            lifespan="on",
            ws_max_size=WS_MAX_MESSAGE_BYTES,  # the page sends nothing; uvicorn's 16 MB each
            limit_concurrency=MAX_CONNECTIONS,
            # a page that stopped reading (a browser gone without a goodbye) is not waited for
            # at the close: its connection is dropped, so the server's thread ends within it
            timeout_graceful_shutdown=CLOSE_GRACE_S,
        )
        server = self._server = uvicorn.Server(config)
        server.install_signal_handlers = lambda: None  # the run owns the signals
        self._thread = threading.Thread(target=server.run, name="ui server", daemon=True)
        self._thread.start()
        deadline = time.monotonic() + timeout_s
        while not server.started:
            if not self._thread.is_alive() or time.monotonic() > deadline:
                raise ConfigError("--ui", f"cannot listen on {self.host}:{self.port}")
            time.sleep(0.02)
        sockets = [s for srv in server.servers for s in srv.sockets]
        if sockets:
            self.port = sockets[0].getsockname()[1]  # port 0: the one the system chose
        self._feed.start()

    @property
    def url(self) -> str:
        """The page's address, printed for the user: never with the token in it (a secret
        in an address and a log line); the page asks for it (:mod:`.login`)."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{host}:{self.port}/"

    @property
    def said(self) -> str:
        """The line printed when it serves: its address, and that the page asks for the
        token when there is one."""
        asks = " (the page asks for its token)" if self.token else ""
        return f"hapticdesk ui: {self.url}{asks}"

    def close(self, timeout_s: float = 2 * CLOSE_GRACE_S) -> None:
        """Stop serving (idempotent)."""
        self._feed.close()
        if self._server is not None:
            self._server.should_exit = True
        if self._thread is not None:
            self._thread.join(timeout_s)

    # --- the run shown ------------------------------------------------------------------------

    @property
    def runtime(self) -> Runtime | None:
        """The run shown live (None while nothing runs)."""
        return self.shown.runtime

    @runtime.setter
    def runtime(self, runtime: Runtime | None) -> None:
        self.shown.runtime = runtime

    @property
    def registry(self) -> Registry:
        """The run's registry (the installed plugins' until a run gives its own)."""
        return self.shown.registry

    @registry.setter
    def registry(self, registry: Registry) -> None:
        self.shown.registry = registry

    def attach(self, runtime: Runtime) -> None:
        """Show ``runtime``'s desk live; browsers get the desk message again."""
        self.shown.runtime = runtime
        self.broadcast_desk()

    def detach(self, runtime: Runtime) -> None:
        if self.shown.runtime is runtime:
            self.shown.runtime = None

    def broadcast_desk(self, layout: Layout | None = None) -> None:
        """Send the desk message again (:meth:`ShownDesk.message`)."""
        self.hub.publish(self.shown.message(layout))

    def on_gesture(self, event: GestureEvent) -> None:
        """The event sink: one gesture event, on a dispatcher lane's thread."""
        self.hub.publish({"type": "gesture", **event.to_dict(), "action": event.action_name})

    @property
    def clients(self) -> int:
        """The pages open."""
        return len(self.hub.clients)
