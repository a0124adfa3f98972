"""The WebSocket hub: every open page gets what the desk says, and none can slow it.

Anything (the feed thread, a dispatcher lane, a handler) hands a message to
:meth:`Hub.publish` from any thread; the server's event loop fans it out. Each page has a
slot for the latest contact frame (a new one replaces an unsent one, so a slow browser drops
frames) and a bounded queue for the rest (gestures, notices, actions). The page sends
nothing: whatever a client sends ends its socket. At most :data:`MAX_WS_CLIENTS` pages are
served at once; one more is told why and closed (1013, try again later).
"""

from __future__ import annotations

import asyncio
import collections
import contextlib
import json
import logging
from collections.abc import AsyncIterator
from typing import TYPE_CHECKING, Any

from starlette.applications import Starlette
from starlette.routing import BaseRoute, WebSocketRoute
from starlette.websockets import WebSocket, WebSocketDisconnect

from hapticdesk.plugins.ui.shown_desk import ShownDesk

if TYPE_CHECKING:
    from hapticdesk.estimator.notices import Notice

log = logging.getLogger(__name__)

#: gestures, notices and action counts a browser may fall behind by before the oldest go
CLIENT_QUEUE = 500
#: the largest WebSocket message a client may send (the page sends none)
WS_MAX_MESSAGE_BYTES = 4096
#: browser pages (WebSocket clients) served at once; one more is refused, saying so (1,500
#: idle clients had been taken, 229 MB)
MAX_WS_CLIENTS = 32
#: the estimator's notices a page gets when it connects (what it said before)
NOTICES_ON_CONNECT = 20


class _Client:
    """One browser: its latest contact frame and a bounded queue of everything else."""

    def __init__(self) -> None:
        self.contact: str | None = None
        self.queue: collections.deque[str] = collections.deque(maxlen=CLIENT_QUEUE)
        self.wake = asyncio.Event()
        self.sent_contacts = 0
        self.dropped_contacts = 0


class Hub:
    """The open pages and what goes to them (see the module docstring)."""

    def __init__(self) -> None:
        self.clients: set[_Client] = set()
        self._sockets = 0  # WebSockets accepted and not yet closed (see MAX_WS_CLIENTS)
        self.refused_sockets = 0
        self._loop: asyncio.AbstractEventLoop | None = None
        #: contact frames published, and replaced before a browser took them
        self.contacts_published = 0
        self.contacts_dropped = 0

    @contextlib.asynccontextmanager
    async def lifespan(self, app: Starlette) -> AsyncIterator[None]:
        """The server's life: messages are fanned out on its event loop while it runs."""
        self._loop = asyncio.get_running_loop()
        yield
        self._loop = None

    def publish(self, message: dict[str, Any]) -> None:
        """Send ``message`` to every browser; any thread. Contacts replace unsent contacts."""
        loop = self._loop
        if loop is None or not self.clients:
            return
        text = json.dumps(message, allow_nan=False)
        loop.call_soon_threadsafe(self._fan_out, message["type"] == "contact", text)

    def _fan_out(self, is_contact: bool, text: str) -> None:
        if is_contact:
            self.contacts_published += 1
        for client in self.clients:
            if is_contact:
                if client.contact is not None:
                    client.dropped_contacts += 1
                    self.contacts_dropped += 1
                client.contact = text
            else:
                client.queue.append(text)
            client.wake.set()

    async def serve(self, socket: WebSocket, shown: ShownDesk) -> None:
        """Serve one page (accepted already): the desk message of ``shown`` and the
        estimator's recent notices, then what is published, until it goes; past
        MAX_WS_CLIENTS it is told why and closed."""
        if self._sockets >= MAX_WS_CLIENTS:  # said, then closed: "try again later"
            await self._refuse(socket)
            return
        self._sockets += 1
        try:
            await self._send_until_gone(socket, shown)
        finally:
            self._sockets -= 1

    async def _refuse(self, socket: WebSocket) -> None:
        self.refused_sockets += 1
        if self.refused_sockets in (1, 10, 100) or self.refused_sockets % 1000 == 0:
            log.warning(
                "ui: %d pages are open, the most served at once; %d refused so far",
                MAX_WS_CLIENTS,
                self.refused_sockets,
            )
        message = f"{MAX_WS_CLIENTS} pages are open already, the most served at once"
        await socket.send_text(
            json.dumps({"type": "notice", "kind": "refused", "message": message})
        )
        await socket.close(code=1013, reason="too many pages open")

    async def _send_until_gone(self, socket: WebSocket, shown: ShownDesk) -> None:
        client = _Client()
        # the page sends nothing: whatever a client sends is read (not left for the server
        # to buffer, 30 clients of 3 × 15 MB had taken it past 1 GB) and ends its socket
        reader = asyncio.create_task(_close_on_message(socket, client))
        for message in await _first_messages(shown):
            await socket.send_text(json.dumps(message, allow_nan=False))
        self.clients.add(client)
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
            self.clients.discard(client)


async def _close_on_message(socket: WebSocket, client: _Client) -> None:
    """Read what a WebSocket client sends; anything at all ends its socket."""
    try:
        message = await socket.receive()
        if message.get("type") != "websocket.disconnect":
            await socket.close(code=1008)  # policy: the page sends nothing
    except Exception:  # (the socket is gone already)
        pass
    client.wake.set()  # the sending loop finds the socket closed and ends


def notice_message(notice: Notice) -> dict[str, Any]:
    """One of the estimator's notices, as the page gets it."""
    return {"type": "notice", "t": notice.t, "kind": notice.kind, "message": notice.message}


async def _first_messages(shown: ShownDesk) -> list[dict[str, Any]]:
    """What a page gets first: the desk message, and what the estimator said before."""
    first = [await asyncio.to_thread(shown.message)]
    runtime = shown.runtime
    if runtime is not None:
        notices = list(runtime.scene.estimator.notices)[-NOTICES_ON_CONNECT:]
        first += [notice_message(notice) for notice in notices]
    return first


async def ws(socket: WebSocket) -> None:
    """``WS /ws``: the desk message, the estimator's recent notices, then everything the
    desk says (JSON messages, one per frame)."""
    hub: Hub = socket.app.state.hub
    await socket.accept()
    await hub.serve(socket, socket.app.state.shown)


#: this module's part of the HTTP contract (gathered in :data:`.server.ROUTES`)
ROUTES: list[BaseRoute] = [WebSocketRoute("/ws", ws)]
