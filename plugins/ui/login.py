"""The token asked for by the page itself, so it never stands in an address or a log line.

A server with a token printed its address with the token in it (``http://…/?token=…``): the
secret in a URL, in the terminal's scrollback and any log that keeps stderr. Now the address is
printed bare; a browser that opens it without the token gets :func:`login_page` (a form, no
script, nothing fetched from elsewhere), which posts the token to ``/login``
(:func:`login`): the right one is set as the page's ``HttpOnly``, ``SameSite=Strict`` cookie
(the one ``GET /?token=`` sets, which scripts may still use) and the browser sent on to the
page; a wrong one waits :data:`WRONG_TOKEN_DELAY_S` and asks again. The guard
(:mod:`.guard`) runs both before any handler, after its Host and Origin checks.
"""

from __future__ import annotations

import asyncio
import hmac
from urllib.parse import parse_qs

from starlette.responses import HTMLResponse, RedirectResponse, Response
from starlette.types import Receive

#: where the form posts the token
LOGIN_PATH = "/login"
#: the most of a login form read (a token, its field name)
MAX_FORM_BYTES = 4096
#: how long a wrong token waits before it is answered (guessing one at a time stays slow)
WRONG_TOKEN_DELAY_S = 1.0

_PAGE = """<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>hapticdesk: token</title>
<meta name="viewport" content="width=device-width, initial-scale=1">
<style>body{{font:16px system-ui,sans-serif;margin:3em auto;max-width:26em;padding:0 1em}}
input{{font:inherit;width:100%;margin:.5em 0;padding:.4em}}p.err{{color:#b00}}</style></head>
<body><h1>hapticdesk</h1>
<p>This desk's page asks for its token: the one given to <code>hapticdesk ui</code> or
<code>run --ui</code> (<code>--token-file</code> or <code>HAPTICDESK_UI_TOKEN</code>).</p>{said}
<form method="post" action="{action}">
<label for="token">Token</label>
<input id="token" name="token" type="password" autocomplete="current-password" autofocus required>
<input type="submit" value="Open the page">
</form></body></html>
"""


def login_page(wrong: bool = False) -> HTMLResponse:
    """The form asking for the token (401: the page was not opened with it)."""
    said = '<p class="err" role="alert">That is not the token.</p>' if wrong else ""
    return HTMLResponse(_PAGE.format(said=said, action=LOGIN_PATH), status_code=401)


async def login(receive: Receive, token: str, cookie: str) -> Response:
    """``POST /login``: the posted token against ``token``; right, sent on to the page with
    it as the ``cookie``; wrong (or a form too large to be one), the form again."""
    given = _posted_token(await _form(receive))
    if given is None or not hmac.compare_digest(given.encode(), token.encode()):
        await asyncio.sleep(WRONG_TOKEN_DELAY_S)
        return login_page(wrong=True)
    answer = RedirectResponse("/", status_code=303)
    answer.set_cookie(cookie, token, httponly=True, samesite="strict", path="/")
    return answer


async def _form(receive: Receive) -> bytes | None:
    """The request's body, None past :data:`MAX_FORM_BYTES`."""
    body = b""
    while True:
        message = await receive()
        if message["type"] != "http.request":
            return body
        body += message.get("body", b"")
        if len(body) > MAX_FORM_BYTES:
            return None
        if not message.get("more_body", False):
            return body


def _posted_token(body: bytes | None) -> str | None:
    """The form's ``token`` field (None: none, or not a form)."""
    if body is None:
        return None
    try:
        fields = parse_qs(body.decode("ascii"), max_num_fields=4)
    except (UnicodeDecodeError, ValueError):
        return None
    values = fields.get("token", [])
    return values[0] if len(values) == 1 else None
