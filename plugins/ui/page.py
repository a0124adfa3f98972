"""The page itself: ``GET /`` and its scripts and style under ``/static`` (nothing fetched
from elsewhere at run time). Both are behind the guard's token like the rest; the page sets
the token as an ``HttpOnly``, ``SameSite=Strict`` cookie, so the browser's requests for its
scripts carry it back."""

from __future__ import annotations

from pathlib import Path

from starlette.requests import Request
from starlette.responses import FileResponse, Response
from starlette.routing import BaseRoute, Route
from starlette.staticfiles import StaticFiles

from hapticdesk.plugins.ui.guard import TOKEN_COOKIE

STATIC = Path(__file__).parent / "static"
_FILES = StaticFiles(directory=STATIC)


async def index(request: Request) -> Response:
    """``GET /``: the page."""
    response = FileResponse(STATIC / "index.html", media_type="text/html")
    token: str | None = request.app.state.token
    if token is not None:  # the page's own /static requests carry it back
        response.set_cookie(TOKEN_COOKIE, token, httponly=True, samesite="strict", path="/")
    return response


async def static(request: Request) -> Response:
    """``GET /static/{path}``: the page's script and style (behind the token: the page's
    scripts say which API it has)."""
    return await _FILES.get_response(request.path_params["path"], request.scope)


#: this module's part of the HTTP contract (gathered in :data:`.server.ROUTES`)
ROUTES: list[BaseRoute] = [
    Route("/", index),
    Route("/static/{path:path}", static, methods=["GET", "HEAD"]),
]
