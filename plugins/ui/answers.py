"""What the page's API answers when something is wrong: errors in the page's one shape.

Every error the page shows is ``{line, column, message}`` (0, 0 when it has no place in the
layout file), in ``{"ok": false, "errors": [...]}`` with the status saying why. A request the
page would not send is a :class:`BadRequest` (one error, no trace); an error no handler
expected is answered 500 as JSON and logged as one line (:class:`OneLineErrors`).
"""

from __future__ import annotations

import json
import logging
from typing import Any

from starlette.requests import Request
from starlette.responses import JSONResponse, Response
from starlette.routing import BaseRoute
from starlette.types import ASGIApp, Receive, Scope, Send

from hapticdesk.errors import ConfigError, Position

log = logging.getLogger(__name__)


class BadRequest(Exception):
    """A request the page would not send: answered with ``status`` and one error, no trace."""

    def __init__(self, status: int, message: str) -> None:
        super().__init__(message)
        self.status = status
        self.message = message


def error_dict(err: ConfigError) -> dict[str, Any]:
    """A ConfigError as ``{line, column, message}`` (0, 0 when it has no place in the file)."""
    where = err.where
    if isinstance(where, Position):
        return {"line": where.line, "column": where.column, "message": err.message}
    return message_error(err.message if where is None else f"{where}: {err.message}")


def message_error(message: str) -> dict[str, Any]:
    """An error with no place in the layout file, as :func:`error_dict` gives one."""
    return {"line": 0, "column": 0, "message": message}


def refusal(status: int, error: dict[str, Any], **extra: Any) -> JSONResponse:
    """``{"ok": false, "errors": [error], **extra}`` with ``status``."""
    return JSONResponse({"ok": False, "errors": [error], **extra}, status_code=status)


async def json_object(request: Request) -> dict[str, Any]:
    """The request's body as a JSON object (BadRequest, 400, for anything else)."""
    try:
        payload = json.loads(await request.body())
    except (ValueError, RecursionError):  # (not JSON, not UTF-8, nested too deep)
        payload = None
    if not isinstance(payload, dict):
        raise BadRequest(400, "the request's body must be a JSON object")
    return payload


async def body_text(request: Request) -> str:
    """The request's body as text (a layout's YAML)."""
    return (await request.body()).decode("utf-8", errors="replace")


async def _refuse_bad_request(request: Request, err: Exception) -> Response:
    assert isinstance(err, BadRequest)
    return refusal(err.status, message_error(err.message))


async def _internal_error(request: Request, err: Exception) -> Response:
    return refusal(500, message_error(f"internal error: {type(err).__name__}"))


#: the app's exception handlers: a BadRequest with its status, anything else 500
EXCEPTION_HANDLERS = {BadRequest: _refuse_bad_request, Exception: _internal_error}


class OneLineErrors:
    """The app, with an error no handler expected logged as one line (``--debug`` shows its
    traceback) after Starlette answered it (500, JSON): ``/api/setup/finish`` on points of
    any shape had written a traceback into the log."""

    def __init__(self, app: Any) -> None:
        self.app = app

    @property
    def routes(self) -> list[BaseRoute]:
        """The wrapped app's routes (the reference of the HTTP contract is made from them)."""
        routes: list[BaseRoute] = self.app.routes
        return routes

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        app: ASGIApp = self.app
        try:
            await app(scope, receive, send)
        except Exception as err:  # (answered already by the app's handler for Exception)
            log.error("ui: %s %s failed: %s: %s", scope.get("method", "WS"), scope.get("path"),
                      type(err).__name__, err)  # fmt: skip
            log.debug("the error's traceback", exc_info=True)
