"""The browser UI's server: the page, the layout API and a WebSocket hub, in its own thread.

Uvicorn runs in a thread with its own event loop, so nothing here runs on the sensing
thread. The run reaches the page through three doors, none of which can slow sensing:

- the latest contact sample, which the sensing thread already copies once per block into
  ``runtime.live.sample`` (O(1)); a *feed* thread here reads it 50 times a second;
- gesture events through the plugin's event sink (a dispatcher lane, off the sensing thread);
- the estimator's notices and the actions' counts, read by the same feed thread.

Each browser has a slot for the latest contact frame (a new one replaces an unsent one, so a
slow browser drops frames) and a bounded queue for the rest (gestures, notices, actions).
"""

from __future__ import annotations

import asyncio
import collections
import hmac
import json
import logging
import threading
import time
from pathlib import Path
from typing import Any

from hapticdesk.errors import ConfigError
from hapticdesk.files.file_safety import reads_confined_to
from hapticdesk.files.yamlfile import load_marked_yaml
from hapticdesk.plugins.ui.layout_edit import desk_message, message_error
from hapticdesk.plugins.ui.layout_edit import error_dict as error_of

log = logging.getLogger(__name__)

STATIC = Path(__file__).parent / "static"
#: contact frames per second sent to each browser (the page draws at most at this rate)
CONTACT_RATE_HZ = 50.0
#: gestures, notices and action counts a browser may fall behind by before the oldest go
CLIENT_QUEUE = 500
LOOPBACK = {"127.0.0.1", "localhost", "::1"}
PHASES = ("", "touch", "hold", "release")
#: the largest request body read (a layout, an edit, a stroke's points)
MAX_BODY_BYTES = 1_000_000


class BadRequest(Exception):
    """A request the page would not send: answered with ``status`` and one error, no trace."""

    def __init__(self, status: int, message: str) -> None:
        super().__init__(message)
        self.status = status
        self.message = message


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


#: the largest WebSocket message a client may send (the page sends none)
WS_MAX_MESSAGE_BYTES = 4096
#: browser pages (WebSocket clients) served at once; one more is refused, saying so (1,500
#: idle clients had been taken, 229 MB)
MAX_WS_CLIENTS = 32
#: connections uvicorn serves at once (pages and API calls); beyond, it answers 503
MAX_CONNECTIONS = MAX_WS_CLIENTS + 32
#: the cookie the page's own requests carry the token in (its scripts and styles under
#: /static are fetched by the browser, which adds no ?token= to them)
TOKEN_COOKIE = "hapticdesk_token"
#: names (besides IP addresses and the machine's own names) a server listening on every
#: address answers to, comma-separated
HOSTS_ENV = "HAPTICDESK_UI_HOSTS"
#: the names a server bound to loopback answers to: another Host is a page of another site
#: reaching it through DNS rebinding
LOOPBACK_NAMES = {"127.0.0.1", "localhost", "::1"}


def host_names() -> frozenset[str]:
    """The names a server listening beyond loopback answers to: the machine's own names,
    loopback names, and those in $HAPTICDESK_UI_HOSTS (IP addresses always)."""
    import os
    import socket

    names = {*LOOPBACK_NAMES, socket.gethostname(), socket.getfqdn()}
    names |= {n.strip() for n in os.environ.get(HOSTS_ENV, "").split(",") if n.strip()}
    return frozenset(n.lower() for n in names)


def _is_address(name: str) -> bool:
    import ipaddress

    try:
        ipaddress.ip_address(name)
    except ValueError:
        return False
    return True


def same_origin(headers: Any, bound: str, names: frozenset[str] | None = None) -> bool:
    """Whether a request comes from the page itself: an ``Origin`` (sent by browsers on
    cross-site requests and every WebSocket) naming the host it was sent to, and a ``Host``
    the server answers to: on loopback a loopback name, elsewhere an IP address or one of
    ``names`` (:func:`host_names`). Without this any web site the user visited could read
    the live desk and save layouts through the user's browser, and a name of an attacker's
    resolving to this machine (DNS rebinding) reach it as if it were the page."""
    host = headers.get("host", "")
    name = (host[1:].split("]")[0] if host.startswith("[") else host.rsplit(":", 1)[0]).lower()
    if bound in LOOPBACK_NAMES:
        if name not in LOOPBACK_NAMES:
            return False
    elif not (_is_address(name) or name in (names if names is not None else host_names())):
        return False
    origin = headers.get("origin")
    if origin is None:
        return True  # not from a browser's cross-site request (curl, a same-origin GET)
    return origin.split("://", 1)[-1].rstrip("/") == host


async def _close_on_message(socket: Any, client: Any) -> None:
    """Read what a WebSocket client sends; anything at all ends its socket (see ``ws``)."""
    try:
        message = await socket.receive()
        if message.get("type") != "websocket.disconnect":
            await socket.close(code=1008)  # policy: the page sends nothing
    except Exception:  # (the socket is gone already)
        pass
    client.wake.set()  # the sending loop finds the socket closed and ends


class _OneLineErrors:
    """The app, with an error no handler expected logged as one line (``--debug`` shows its
    traceback) after Starlette answered it (500, JSON): ``/api/setup/finish`` on points of
    any shape had written a traceback into the log."""

    def __init__(self, app: Any) -> None:
        self.app = app

    @property
    def routes(self) -> Any:
        """The wrapped app's routes (the reference of the HTTP contract is made from them)."""
        return self.app.routes

    async def __call__(self, scope: Any, receive: Any, send: Any) -> None:
        try:
            await self.app(scope, receive, send)
        except Exception as err:  # (answered already by the app's handler for Exception)
            log.error("ui: %s %s failed: %s: %s", scope.get("method", "WS"), scope.get("path"),
                      type(err).__name__, err)  # fmt: skip
            log.debug("the error's traceback", exc_info=True)


class _Client:
    """One browser: its latest contact frame and a bounded queue of everything else."""

    def __init__(self) -> None:
        self.contact: str | None = None
        self.queue: collections.deque[str] = collections.deque(maxlen=CLIENT_QUEUE)
        self.wake = asyncio.Event()
        self.sent_contacts = 0
        self.dropped_contacts = 0


class UiServer:
    """The page and its API for one layout file, and the live view of whichever run is
    attached (:meth:`attach`). ``token``: required from every request when not None."""

    def __init__(
        self,
        layout_path: Path,
        registry: Any,
        *,
        host: str = "127.0.0.1",
        port: int = 8765,
        token: str | None = None,
        desk: Any = None,
        read_only: bool = False,
    ) -> None:
        if host not in LOOPBACK and not token:
            raise ConfigError(
                "--ui",
                f"listening on {host} lets other machines in: give a token "
                "(--token or HAPTICDESK_UI_TOKEN)",
            )
        self.layout_path = Path(layout_path)
        self._registry = registry
        self.host, self.port = host, port
        self._read_roots: list[Path] | None = None  # (see _confined)
        # the layout as the operator started with it: what a page may not add to or change
        # (read now; its held parts are made once the run's registry is known)
        try:
            self._started_doc: Any = load_marked_yaml(self.layout_path)
        except ConfigError:
            self._started_doc = None
        self._secrets: Any = None
        self.token = token
        self.desk = desk  # a DeskProfile overriding the layout's desk:, or None
        self.read_only = read_only  # the shipped demo layout: shown, never written
        self.runtime: Any = None
        self.setup: Any = None  # the set-up check session recording, or None
        self._clients: set[_Client] = set()
        self._sockets = 0  # WebSockets accepted and not yet closed (see MAX_WS_CLIENTS)
        self.refused_sockets = 0
        self._host_names = host_names()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._server: Any = None
        self._thread: threading.Thread | None = None
        self._feed: threading.Thread | None = None
        self._stop = threading.Event()
        #: contact frames published by the feed, and replaced before a browser took them
        self.contacts_published = 0
        self.contacts_dropped = 0

    # --- life ---------------------------------------------------------------------------------

    def start(self, timeout_s: float = 10.0) -> None:
        """Start serving in a thread; returns once the port is bound (ConfigError if not)."""
        import uvicorn

        config = uvicorn.Config(
            self.app(),
            host=self.host,
            port=self.port,
            log_level="warning",
            lifespan="on",
            ws_max_size=WS_MAX_MESSAGE_BYTES,  # the page sends nothing; uvicorn's 16 MB each
            limit_concurrency=MAX_CONNECTIONS,
        )
        self._server = uvicorn.Server(config)
        self._server.install_signal_handlers = lambda: None  # the run owns the signals
        self._thread = threading.Thread(target=self._server.run, name="ui server", daemon=True)
        self._thread.start()
        deadline = time.monotonic() + timeout_s
        while not self._server.started:
            if not self._thread.is_alive() or time.monotonic() > deadline:
                raise ConfigError("--ui", f"cannot listen on {self.host}:{self.port}")
            time.sleep(0.02)
        sockets = [s for srv in self._server.servers for s in srv.sockets]
        if sockets:
            self.port = sockets[0].getsockname()[1]  # port 0: the one the system chose
        self._feed = threading.Thread(target=self._feed_loop, name="ui feed", daemon=True)
        self._feed.start()

    @property
    def url(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{host}:{self.port}/" + (f"?token={self.token}" if self.token else "")

    def close(self, timeout_s: float = 2.0) -> None:
        """Stop serving (idempotent)."""
        self._stop.set()
        if self._server is not None:
            self._server.should_exit = True
        if self._thread is not None:
            self._thread.join(timeout_s)

    def attach(self, runtime: Any) -> None:
        """Show ``runtime``'s desk live; browsers get the desk message again."""
        self.runtime = runtime
        self.broadcast_desk()

    def detach(self, runtime: Any) -> None:
        if self.runtime is runtime:
            self.runtime = None

    # --- what goes to browsers ----------------------------------------------------------------

    def publish(self, message: dict[str, Any]) -> None:
        """Send ``message`` to every browser; any thread. Contacts replace unsent contacts."""
        loop = self._loop
        if loop is None or not self._clients:
            return
        text = json.dumps(message, allow_nan=False)
        loop.call_soon_threadsafe(self._fan_out, message["type"] == "contact", text)

    def _fan_out(self, is_contact: bool, text: str) -> None:
        if is_contact:
            self.contacts_published += 1
        for client in self._clients:
            if is_contact:
                if client.contact is not None:
                    client.dropped_contacts += 1
                    self.contacts_dropped += 1
                client.contact = text
            else:
                client.queue.append(text)
            client.wake.set()

    def broadcast_desk(self, layout: Any = None) -> None:
        """Send the desk message again: of ``layout`` (one just saved, which the sensing
        thread swaps in at its next block), else of what is running or saved."""
        try:
            if layout is not None:
                profile = self.runtime.scene.profile if self.runtime else layout.desk
                message = desk_message(profile, layout, live=self.runtime is not None)
                self.publish(self._with_actions(message))
                return
            self.publish(self._desk_message())
        except ConfigError as err:
            self.publish({"type": "notice", "kind": "layout", "message": str(err)})

    def _desk_message(self) -> dict[str, Any]:
        runtime = self.runtime
        if runtime is not None:
            message = desk_message(runtime.scene.profile, runtime.scene.layout, live=True)
            return self._with_actions(message)
        from hapticdesk.runtime.assembly import load_scene_layout

        layout, profile = load_scene_layout(self.layout_path, self.registry, self.desk)
        return self._with_actions(desk_message(profile, layout, live=False))

    def _with_actions(self, message: dict[str, Any]) -> dict[str, Any]:
        """The desk message with ``actions``: whether the running desk runs its layout's
        actions (false for `hapticdesk ui` without --actions: the page says so), null when
        nothing runs."""
        runtime = self.runtime
        message["actions"] = None if runtime is None else bool(runtime.scene.actions)
        return message

    def on_gesture(self, event: Any) -> None:
        """The event sink: one gesture event, on a dispatcher lane's thread."""
        self.publish({"type": "gesture", **event.to_dict(), "action": event.action_name})

    def _feed_loop(self) -> None:
        """Read the run's latest sample, notices and action counts, CONTACT_RATE_HZ times a
        second, and publish what changed; nothing is read while no browser is connected."""
        seen_blocks = -1
        seen_notices = 0
        lane_counts: dict[int, tuple[int, int, int, int]] = {}
        runtime_seen = None
        period = 1.0 / CONTACT_RATE_HZ
        tick = time.monotonic()
        # on a fixed beat (not a sleep after the work), so a busy machine does not slow it more
        while not self._stop.wait(max(0.0, tick + period - time.monotonic())):
            tick = max(tick + period, time.monotonic() - period)
            runtime = self.runtime
            if runtime is None or not self._clients:
                continue
            if runtime is not runtime_seen:
                runtime_seen, seen_blocks, lane_counts = runtime, -1, {}
                seen_notices = runtime.scene.estimator.notices.total
            live = runtime.live
            blocks, sample = live.blocks, live.sample
            if sample is not None and blocks != seen_blocks:
                seen_blocks = blocks
                t, x, y, force, phase, surface = sample
                profile = runtime.scene.profile
                self.publish(
                    {
                        "type": "contact",
                        "t": round(t, 4),
                        "x": None if x is None else round(x, 5),
                        "y": None if y is None else round(y, 5),
                        "force_n": round(force, 3),
                        "phase": PHASES[phase] if 0 <= phase < len(PHASES) else "",
                        "surface": profile.surfaces[surface].name if surface >= 0 else None,
                        "tared": live.tared,
                        "paused": live.paused,  # (gestures not sent: the page says so)
                    }
                )
            notices = runtime.scene.estimator.notices
            for notice in notices.since(seen_notices):
                self.publish(
                    {
                        "type": "notice",
                        "t": notice.t,
                        "kind": notice.kind,
                        "message": notice.message,
                    }
                )
            seen_notices = notices.total
            for lane in (ln for route in runtime.scene.dispatcher.routes for ln in route.lanes):
                s = lane.stats
                counts = (s.ok, s.failed, s.timed_out, s.dropped)
                if lane_counts.get(id(lane), (0, 0, 0, 0)) != counts:
                    lane_counts[id(lane)] = counts
                    self.publish(
                        {
                            "type": "action",
                            "label": lane.label,
                            "ok": s.ok,
                            "failed": s.failed,
                            "timed_out": s.timed_out,
                            "dropped": s.dropped,
                        }
                    )

    # --- the web app --------------------------------------------------------------------------

    def app(self) -> Any:
        """The Starlette application (routes of the contract in README, "Browser UI")."""
        import contextlib

        from starlette.applications import Starlette
        from starlette.requests import Request
        from starlette.responses import FileResponse, JSONResponse, PlainTextResponse, Response
        from starlette.routing import Route, WebSocketRoute
        from starlette.staticfiles import StaticFiles
        from starlette.websockets import WebSocket, WebSocketDisconnect

        from hapticdesk.plugins.ui import strokes_api
        from hapticdesk.plugins.ui.known_weight_setup import weight_setup_routes

        static_files = StaticFiles(directory=STATIC)
        from hapticdesk.plugins.ui.layout_edit import apply_edit, save_layout_text

        def allowed(request: Request | WebSocket) -> bool:
            if not same_origin(request.headers, self.host, self._host_names):
                return False
            if self.token is None:
                return True
            given = request.query_params.get("token") or request.cookies.get(TOKEN_COOKIE, "")
            auth = request.headers.get("authorization", "")
            if auth.lower().startswith("bearer "):
                given = auth[7:]
            return hmac.compare_digest(given.encode(), self.token.encode())

        def refused() -> Response:
            return PlainTextResponse(
                "a token is needed (?token=...), from the page's own address", status_code=401
            )

        async def page(request: Request) -> Response:
            if not allowed(request):
                return refused()
            response = FileResponse(STATIC / "index.html", media_type="text/html")
            if self.token is not None:  # the page's own /static requests carry it back
                response.set_cookie(
                    TOKEN_COOKIE, self.token, httponly=True, samesite="strict", path="/"
                )
            return response

        async def static(request: Request) -> Response:
            # behind the token like the rest: the page's scripts say which API it has
            if not allowed(request):
                return refused()
            return await static_files.get_response(request.path_params["path"], request.scope)

        async def get_layout(request: Request) -> Response:
            if not allowed(request):
                return refused()
            text = self.layout_path.read_text(encoding="utf-8")
            return PlainTextResponse(text, media_type="application/yaml")

        async def body_bytes(request: Request) -> bytes:
            """The request's body, refused (BadRequest, 413) past MAX_BODY_BYTES before more
            is read: its declared length first, then as it streams in."""
            declared = request.headers.get("content-length", "")
            too_big = BadRequest(413, f"the request is larger than {MAX_BODY_BYTES:,} bytes")
            if declared.isdigit() and int(declared) > MAX_BODY_BYTES:
                raise too_big
            data = bytearray()
            async for chunk in request.stream():
                data += chunk
                if len(data) > MAX_BODY_BYTES:
                    raise too_big
            return bytes(data)

        async def body_text(request: Request) -> str:
            return (await body_bytes(request)).decode("utf-8", errors="replace")

        async def json_object(request: Request) -> dict[str, Any]:
            """The request's body as a JSON object (BadRequest, 400, for anything else)."""
            try:
                payload = json.loads(await body_bytes(request))
            except (ValueError, RecursionError):  # (not JSON, not UTF-8, nested too deep)
                payload = None
            if not isinstance(payload, dict):
                raise BadRequest(400, "the request's body must be a JSON object")
            return payload

        async def refuse_bad_request(request: Request, err: Exception) -> Response:
            assert isinstance(err, BadRequest)
            errors = [message_error(err.message)]
            return JSONResponse({"ok": False, "errors": errors}, status_code=err.status)

        async def check(request: Request) -> Response:
            if not allowed(request):
                return refused()
            text = await body_text(request)
            errors, regions = await asyncio.to_thread(self._describe, text)
            return JSONResponse({"ok": not errors, "errors": errors, "regions": regions})

        async def put_layout(request: Request) -> Response:
            if not allowed(request):
                return refused()
            if self.read_only:
                message = "no layout file was given (start with --layout FILE to save)"
                return JSONResponse(
                    {"ok": False, "errors": [message_error(message)]},
                    status_code=403,
                )
            text = await body_text(request)
            errors, new_layout = await asyncio.to_thread(self._check, text)
            if errors:
                return JSONResponse({"ok": False, "errors": errors}, status_code=422)
            await asyncio.to_thread(save_layout_text, self.layout_path, text)
            reloaded = False
            runtime = self.runtime
            if runtime is not None:
                try:  # the sensing thread builds it between two blocks, then answers; it
                    # takes over once no touch is in progress
                    await asyncio.to_thread(runtime.reload, 10.0)
                    reloaded = True
                except ConfigError as err:  # e.g. an action that cannot be set up now
                    return JSONResponse(
                        {"ok": False, "errors": [error_of(err)], "saved": True}, status_code=422
                    )
                except TimeoutError:  # the run is not sensing (its source ended)
                    reloaded = False
            self.broadcast_desk(new_layout)
            return JSONResponse({"ok": True, "errors": [], "reloaded": reloaded})

        async def edit(request: Request) -> Response:
            if not allowed(request):
                return refused()
            payload = await json_object(request)
            if not isinstance(payload.get("text", ""), str):
                raise BadRequest(400, "`text` must be the layout's text")
            try:
                text = apply_edit(payload.get("text", ""), payload)
            except ConfigError as err:
                return JSONResponse({"ok": False, "errors": [error_of(err)]}, status_code=422)
            except (TypeError, ValueError, AttributeError, KeyError, IndexError) as err:
                raise BadRequest(400, f"not an edit the designer makes: {err}") from None
            return JSONResponse({"ok": True, "text": text})

        async def schema(request: Request) -> Response:
            if not allowed(request):
                return refused()
            from hapticdesk.plugins.ui.layout_edit import schemas

            return JSONResponse(schemas(self.registry))

        async def strokes(request: Request) -> Response:
            if not allowed(request):
                return refused()
            payload = await json_object(request)
            layout_text = self.layout_path.read_text(encoding="utf-8")
            try:
                result = await asyncio.to_thread(
                    strokes_api.score, payload, self.layout_path, layout_text, self
                )
            except ConfigError as err:
                return JSONResponse({"ok": False, "errors": [error_of(err)]}, status_code=422)
            return JSONResponse(result)

        async def setup_start(request: Request) -> Response:
            if not allowed(request):
                return refused()
            from hapticdesk.plugins.ui.setup_api import SetupSession, read_points

            payload = await json_object(request)
            runtime = self.runtime
            if runtime is None:
                problem = "the set-up check needs a running desk (`hapticdesk ui` or `run --ui`)"
                error = message_error(problem)
                return JSONResponse({"ok": False, "errors": [error]}, status_code=422)
            try:
                points = read_points(payload, runtime.scene.profile)
            except ConfigError as err:
                return JSONResponse({"ok": False, "errors": [error_of(err)]}, status_code=422)
            if self.setup is not None:
                await asyncio.to_thread(self.setup.finish_quietly)
            self.setup = SetupSession(runtime, points)
            return JSONResponse({"ok": True})

        async def setup_finish(request: Request) -> Response:
            if not allowed(request):
                return refused()
            session, self.setup = self.setup, None
            if session is None:
                error = message_error("no set-up check was started")
                return JSONResponse({"ok": False, "errors": [error]}, status_code=422)
            try:
                result = await asyncio.to_thread(session.finish)
            except ConfigError as err:
                return JSONResponse({"ok": False, "errors": [error_of(err)]}, status_code=422)
            return JSONResponse(result)

        async def ws(socket: WebSocket) -> None:
            if not allowed(socket):
                await socket.close(code=4401)
                return
            await socket.accept()
            if self._sockets >= MAX_WS_CLIENTS:  # said, then closed: "try again later"
                self.refused_sockets += 1
                if self.refused_sockets in (1, 10, 100) or self.refused_sockets % 1000 == 0:
                    log.warning(
                        "ui: %d pages are open, the most served at once; %d refused so far",
                        MAX_WS_CLIENTS,
                        self.refused_sockets,
                    )
                message = f"{MAX_WS_CLIENTS} pages are open already, the most served at once"
                refusal = {"type": "notice", "kind": "refused", "message": message}
                await socket.send_text(json.dumps(refusal))
                await socket.close(code=1013, reason="too many pages open")
                return
            self._sockets += 1
            try:
                await serve_socket(socket)
            finally:
                self._sockets -= 1

        async def serve_socket(socket: WebSocket) -> None:
            client = _Client()
            # the page sends nothing: whatever a client sends is read (not left for the server
            # to buffer, 30 clients of 3 × 15 MB had taken it past 1 GB) and ends its socket
            reader = asyncio.create_task(_close_on_message(socket, client))
            try:
                first = await asyncio.to_thread(self._desk_message)
            except ConfigError as err:
                first = {"type": "notice", "kind": "layout", "message": str(err)}
            await socket.send_text(json.dumps(first, allow_nan=False))
            runtime = self.runtime
            if runtime is not None:  # what the estimator said before this page connected
                for notice in list(runtime.scene.estimator.notices)[-20:]:
                    message = {"type": "notice", "t": notice.t, "kind": notice.kind}
                    message["message"] = notice.message
                    await socket.send_text(json.dumps(message, allow_nan=False))
            self._clients.add(client)
            try:
                while True:
                    await client.wake.wait()
                    client.wake.clear()
                    while client.queue:
                        await socket.send_text(client.queue.popleft())
                    contact, client.contact = client.contact, None
                    if contact is not None:
                        await socket.send_text(contact)
                        client.sent_contacts += 1
            except (WebSocketDisconnect, RuntimeError, OSError):
                pass
            finally:
                reader.cancel()
                self._clients.discard(client)

        @contextlib.asynccontextmanager
        async def lifespan(app: Any) -> Any:
            self._loop = asyncio.get_running_loop()
            yield
            self._loop = None

        routes = [
            Route("/", page),
            Route("/api/layout", get_layout, methods=["GET"]),
            Route("/api/layout", put_layout, methods=["PUT"]),
            Route("/api/check", check, methods=["POST"]),
            Route("/api/edit", edit, methods=["POST"]),
            Route("/api/schema", schema, methods=["GET"]),
            Route("/api/strokes", strokes, methods=["POST"]),
            Route("/api/setup/start", setup_start, methods=["POST"]),
            Route("/api/setup/finish", setup_finish, methods=["POST"]),
            *weight_setup_routes(self, allowed, refused, json_object),
            WebSocketRoute("/ws", ws),
            Route("/static/{path:path}", static, methods=["GET", "HEAD"]),
        ]

        async def internal_error(request: Request, err: Exception) -> Response:
            error = message_error(f"internal error: {type(err).__name__}")
            return JSONResponse({"ok": False, "errors": [error]}, status_code=500)

        app = Starlette(
            routes=routes,
            lifespan=lifespan,
            exception_handlers={BadRequest: refuse_bad_request, Exception: internal_error},
        )
        return _OneLineErrors(app)

    @property
    def registry(self) -> Any:
        if self._registry is None:
            from hapticdesk.plugin_loading import load_registry

            self._registry = load_registry()
        return self._registry

    @registry.setter
    def registry(self, value: Any) -> None:
        self._registry = value

    def _describe(self, text: str) -> tuple[list[dict[str, Any]], list[dict[str, Any]] | None]:
        """The errors of ``text``, and its regions (to draw the edit) when it is valid."""
        try:
            layout, profile = self._load_sent(text)
        except ConfigError as err:
            return [error_of(err)], None
        return [], desk_message(profile, layout, live=False)["regions"]

    def _check(self, text: str) -> tuple[list[dict[str, Any]], Any]:
        """What `check` says of ``text``, then whether it adds or changes what only the
        operator may (:mod:`hapticdesk.runtime.operator_secrets`): compared with the layout
        file as it was when this server started, not as the last save left it. The errors,
        and the layout when there are none."""
        try:  # (loaded once, for both)
            layout, _ = self._load_sent(text)
        except ConfigError as err:
            return [error_of(err)], None
        refused = self._operator_secrets().refusal(
            layout.raw,
            self.layout_path,
            self.registry,
            "the page",
            "edit the layout file by hand and restart the desk",
        )
        return ([], layout) if refused is None else ([error_of(refused)], None)

    def _operator_secrets(self) -> Any:
        from hapticdesk.runtime.operator_secrets import OperatorSecrets

        if self._secrets is None:
            doc = self._started_doc if isinstance(self._started_doc, dict) else {}
            named = {}
            layouts = doc.get("layouts")
            if isinstance(layouts, dict):
                named = {
                    str(k): self.layout_path.parent / Path(str(v)).expanduser()
                    for k, v in layouts.items()
                }
            self._secrets = OperatorSecrets.from_start(doc, self.layout_path, self.registry, named)
        return self._secrets

    def _load_sent(self, text: str) -> Any:
        """``text``, a layout the page sent, loaded as `check` would as the layout file (its
        reads confined); ConfigError at its first problem."""
        from hapticdesk.runtime.assembly import load_scene_layout

        with self._confined():
            return load_scene_layout(self.layout_path, self.registry, self.desk, text=text)

    def _confined(self) -> Any:
        """Reads confined to the folders a layout from the page may use: the layout's, its
        desk profile's when the server started, the shipped profiles and examples (a page's
        `desk: /etc/passwd` had been read and quoted back in the error)."""
        if self._read_roots is None:
            from importlib import resources

            from hapticdesk.plugins.mqtt.demo import examples_dir
            from hapticdesk.runtime.assembly import load_scene_layout

            roots = [self.layout_path.parent, examples_dir()]
            roots.append(Path(str(resources.files("hapticdesk.profiles"))))
            try:  # (the file as it was given, before any page touched it)
                _, profile = load_scene_layout(self.layout_path, self.registry, self.desk)
                if profile.path is not None:
                    roots.append(Path(profile.path).parent)
            except ConfigError:
                pass
            self._read_roots = roots
        return reads_confined_to(*self._read_roots)

    @property
    def clients(self) -> int:
        return len(self._clients)
