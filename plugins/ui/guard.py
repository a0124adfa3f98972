"""The guard every request to the browser UI passes, before any handler runs.

One ASGI middleware (docs/security.md, "The browser UI"), for HTTP and WebSocket alike:

- **Host and Origin**: a request from another site (its ``Origin``), or naming the server by
  a name it does not answer to (its ``Host``: DNS rebinding), is refused;
- **the token**, when one is set: ``?token=``, ``Authorization: Bearer`` or the page's own
  cookie; everything is behind it, ``/static`` included; a browser opening the page without
  it gets the form of :mod:`.login`, which sets the cookie;
- **the body's size**: past :data:`MAX_BODY_BYTES` a request is refused (413), on its declared
  length before anything is read, else as soon as it streams past;
- **confined reads**: whatever a request makes the server read through the layout's readers
  stays within the folders a layout from the page may use (its folder, its desk's, the
  shipped profiles and examples). The operator's own layout file is read as the operator's
  (:func:`operator_reads`).
"""

from __future__ import annotations

import contextvars
import hmac
import ipaddress
import os
import socket
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TypeVar

from starlette.datastructures import Headers
from starlette.requests import HTTPConnection
from starlette.responses import PlainTextResponse
from starlette.types import ASGIApp, Message, Receive, Scope, Send
from starlette.websockets import WebSocket

from hapticdesk.errors import ConfigError
from hapticdesk.files.file_safety import reads_confined_to
from hapticdesk.plugins.ui.answers import BadRequest, message_error, refusal
from hapticdesk.plugins.ui.login import LOGIN_PATH, login, login_page
from hapticdesk.plugins.ui.page_token import TOKEN_ENV

T = TypeVar("T")

#: the largest request body read (a layout, an edit, a stroke's points)
MAX_BODY_BYTES = 1_000_000
#: the cookie the page's own requests carry the token in (its scripts and styles under
#: /static are fetched by the browser, which adds no ?token= to them)
TOKEN_COOKIE = "hapticdesk_token"
#: names (besides IP addresses and the machine's own names) a server listening on every
#: address answers to, comma-separated
HOSTS_ENV = "HAPTICDESK_UI_HOSTS"
#: the names a server bound to loopback answers to: another Host is a page of another site
#: reaching it through DNS rebinding
LOOPBACK_NAMES = {"127.0.0.1", "localhost", "::1"}
#: the shortest token taken where other machines can reach the page
MIN_TOKEN_CHARS = 12


def check_token(host: str, token: str | None, where_host: str, where_token: str) -> None:
    """A ConfigError where a page listening on ``host`` beyond loopback has no token (at
    ``where_host``) or one under :data:`MIN_TOKEN_CHARS`, which other machines may guess (at
    ``where_token``): ``ui``'s options and ``run --ui`` alike (:class:`.server.UiServer`)."""
    if host in LOOPBACK_NAMES:
        return
    if not token:
        raise ConfigError(
            where_host,
            f"listening on {host} lets other machines in: give a token (--token-file PATH or "
            f"{TOKEN_ENV})",
        )
    if len(token) < MIN_TOKEN_CHARS:
        raise ConfigError(
            where_token,
            f"a token of {len(token)} characters lets other machines guess it: expected "
            f"{MIN_TOKEN_CHARS} or more (python3 -c 'import secrets; "
            "print(secrets.token_urlsafe(16))' makes one)",
        )


def host_names() -> frozenset[str]:
    """The names a server listening beyond loopback answers to: the machine's own names,
    loopback names, and those in $HAPTICDESK_UI_HOSTS (IP addresses always)."""
    names = {*LOOPBACK_NAMES, socket.gethostname(), socket.getfqdn()}
    names |= {n.strip() for n in os.environ.get(HOSTS_ENV, "").split(",") if n.strip()}
    return frozenset(n.lower() for n in names)


def _is_address(name: str) -> bool:
    try:
        ipaddress.ip_address(name)
    except ValueError:
        return False
    return True


def same_origin(
    headers: Mapping[str, str], bound: str, names: frozenset[str] | None = None
) -> bool:
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


def operator_reads(call: Callable[..., T], *args: object) -> T:
    """``call(*args)`` outside the confinement of the request it serves: for the operator's
    own layout file, whose ``desk:``, ``templates:`` and ``layouts:`` may lie anywhere the
    operator chose (never for what a page sent)."""
    return contextvars.Context().run(call, *args)


class PageGuard:
    """The middleware (see the module docstring). ``bound``: the address the server listens
    on; ``token``: required when not None; ``names``: the Host names it answers to beyond
    loopback; ``roots``: the folders a page's layout may read (asked once, at the first
    request)."""

    def __init__(
        self,
        app: ASGIApp,
        *,
        bound: str,
        token: str | None,
        names: frozenset[str],
        roots: Callable[[], Sequence[Path]],
    ) -> None:
        self.app = app
        self.bound = bound
        self.token = token
        self.names = names
        self._roots = roots
        self._read_roots: Sequence[Path] | None = None

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] not in ("http", "websocket"):  # (the lifespan)
            await self.app(scope, receive, send)
            return
        connection = HTTPConnection(scope)
        if self._login(scope, connection):  # (the page's own form: no handler behind it)
            assert self.token is not None
            await (await login(receive, self.token, TOKEN_COOKIE))(scope, receive, send)
            return
        if not self.allowed(connection):
            if scope["type"] == "websocket":
                await WebSocket(scope, receive, send).close(code=4401)
                return
            if self._asks_for_page(scope, connection):
                await login_page()(scope, receive, send)
                return
            refused = (
                "a token is needed (the page asks for it; a script: Authorization: Bearer), "
                "from the page's own address"
            )
            await PlainTextResponse(refused, status_code=401)(scope, receive, send)
            return
        declared = Headers(scope=scope).get("content-length", "")
        if declared.isdigit() and int(declared) > MAX_BODY_BYTES:
            await refusal(413, message_error(_too_big().message))(scope, receive, send)
            return
        if self._read_roots is None:  # (the layout file as it was at the first request)
            self._read_roots = self._roots()
        with reads_confined_to(*self._read_roots):
            await self.app(scope, _bounded(receive), send)

    def _login(self, scope: Scope, connection: HTTPConnection) -> bool:
        """A token posted by the page's form (:mod:`.login`), from the page's own address."""
        return (
            self.token is not None
            and scope["type"] == "http"
            and scope["method"] == "POST"
            and scope["path"] == LOGIN_PATH
            and same_origin(connection.headers, self.bound, self.names)
        )

    def _asks_for_page(self, scope: Scope, connection: HTTPConnection) -> bool:
        """A browser opening the page without the token, at the page's own address: it gets
        the form that asks for it."""
        return (
            self.token is not None
            and scope["method"] in ("GET", "HEAD")
            and scope["path"] == "/"
            and same_origin(connection.headers, self.bound, self.names)
        )

    def allowed(self, connection: HTTPConnection) -> bool:
        """The right Host and Origin, and the token when one is set."""
        if not same_origin(connection.headers, self.bound, self.names):
            return False
        if self.token is None:
            return True
        given = connection.query_params.get("token") or connection.cookies.get(TOKEN_COOKIE, "")
        auth = connection.headers.get("authorization", "")
        if auth.lower().startswith("bearer "):
            given = auth[7:]
        return hmac.compare_digest(given.encode(), self.token.encode())


def _too_big() -> BadRequest:
    return BadRequest(413, f"the request is larger than {MAX_BODY_BYTES:,} bytes")


def _bounded(receive: Receive) -> Receive:
    """``receive``, raising BadRequest (413) once the body streams past MAX_BODY_BYTES: the
    handler reading it stops there, and the app answers with the error."""
    size = 0

    async def bounded() -> Message:
        nonlocal size
        message = await receive()
        if message["type"] == "http.request":
            size += len(message.get("body", b""))
            if size > MAX_BODY_BYTES:
                raise _too_big()
        return message

    return bounded
