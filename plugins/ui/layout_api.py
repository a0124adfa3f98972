"""The layout endpoints: read, check, edit and save the layout file, and the designer's forms.

A layout the page sends is checked as ``hapticdesk check`` checks the layout file (the same
loader, so the same errors at the same line and column), its reads confined by the guard; a
save is refused when it adds or changes what only the operator may
(:mod:`hapticdesk.runtime.operator_secrets`), then written atomically and reloaded by the run.
"""

from __future__ import annotations

import asyncio
from typing import TYPE_CHECKING, Any

from starlette.requests import Request
from starlette.responses import JSONResponse, PlainTextResponse, Response
from starlette.routing import BaseRoute, Route

from hapticdesk.errors import ConfigError
from hapticdesk.gestures.options import GESTURE_OPTIONS
from hapticdesk.plugins.ui.answers import (
    BadRequest,
    body_text,
    error_dict,
    json_object,
    message_error,
    refusal,
)
from hapticdesk.plugins.ui.hub import Hub
from hapticdesk.plugins.ui.layout_edit import apply_edit, save_layout_text
from hapticdesk.plugins.ui.shown_desk import ShownDesk, desk_message

if TYPE_CHECKING:
    from hapticdesk.gestures.layout import Layout
    from hapticdesk.registry import Registry

#: how long a save waits for the run to take the saved layout
RELOAD_TIMEOUT_S = 10.0


async def get_layout(request: Request) -> Response:
    """``GET /api/layout``: the layout file's YAML text."""
    shown: ShownDesk = request.app.state.shown
    text = shown.layout_path.read_text(encoding="utf-8")
    return PlainTextResponse(text, media_type="application/yaml")


async def check(request: Request) -> Response:
    """``POST /api/check``: YAML text → its errors, and its regions when it is valid."""
    shown: ShownDesk = request.app.state.shown
    text = await body_text(request)
    errors, regions = await asyncio.to_thread(_describe, shown, text)
    return JSONResponse({"ok": not errors, "errors": errors, "regions": regions})


async def put_layout(request: Request) -> Response:
    """``PUT /api/layout``: save YAML text (comments kept) and have the run reload it."""
    shown: ShownDesk = request.app.state.shown
    if shown.read_only:
        message = "no layout file was given (start with --layout FILE to save)"
        return refusal(403, message_error(message))
    text = await body_text(request)
    errors, new_layout = await asyncio.to_thread(_check, shown, text)
    if errors:
        return JSONResponse({"ok": False, "errors": errors}, status_code=422)
    await asyncio.to_thread(save_layout_text, shown.layout_path, text)
    reloaded = False
    runtime = shown.runtime
    if runtime is not None:
        try:  # the sensing thread builds it between two blocks, then answers; it
            # takes over once no touch is in progress
            await asyncio.to_thread(runtime.reload, RELOAD_TIMEOUT_S)
            reloaded = True
        except ConfigError as err:  # e.g. an action that cannot be set up now
            return refusal(422, error_dict(err), saved=True)
        except TimeoutError:  # the run is not sensing (its source ended)
            reloaded = False
    hub: Hub = request.app.state.hub
    hub.publish(shown.message(new_layout))
    return JSONResponse({"ok": True, "errors": [], "reloaded": reloaded})


async def edit(request: Request) -> Response:
    """``POST /api/edit``: an edit the designer makes, applied to YAML text."""
    payload = await json_object(request)
    if not isinstance(payload.get("text", ""), str):
        raise BadRequest(400, "`text` must be the layout's text")
    try:
        text = apply_edit(payload.get("text", ""), payload)
    except ConfigError as err:
        return refusal(422, error_dict(err))
    except (TypeError, ValueError, AttributeError, KeyError, IndexError) as err:
        raise BadRequest(400, f"not an edit the designer makes: {err}") from None
    return JSONResponse({"ok": True, "text": text})


async def schema(request: Request) -> Response:
    """``GET /api/schema``: the designer's forms."""
    shown: ShownDesk = request.app.state.shown
    return JSONResponse(schemas(shown.registry))


#: this module's part of the HTTP contract (gathered in :data:`.server.ROUTES`)
ROUTES: list[BaseRoute] = [
    Route("/api/layout", get_layout, methods=["GET"]),
    Route("/api/layout", put_layout, methods=["PUT"]),
    Route("/api/check", check, methods=["POST"]),
    Route("/api/edit", edit, methods=["POST"]),
    Route("/api/schema", schema, methods=["GET"]),
]


def schemas(registry: Registry) -> dict[str, Any]:
    """Forms for the designer: each gesture's options (its recognizer's ``option_specs``, or
    the built-in table) and each action's options (the schema its plugin registered)."""
    gestures: dict[str, Any] = {}
    types = registry.recognizer_types()
    for name in sorted(set(GESTURE_OPTIONS) | set(types)):
        specs = GESTURE_OPTIONS.get(name)
        if specs is None:
            try:
                specs = getattr(types[name].load(), "option_specs", None) or {}
            except ConfigError:
                specs = {}
        gestures[name] = {
            key: {
                "kind": spec.kind,
                "default": spec.default,
                "help": spec.help,
                "choices": list(spec.choices),
                "role": spec.role,
            }
            for key, spec in specs.items()
        }
    actions = {
        name: {
            "description": record.description,
            "options": getattr(record, "options", None),
            "plugin": record.plugin,
        }
        for name, record in sorted(registry.actions.items())
        if name != "exec"  # the page never adds a program to run
    }
    return {"gestures": gestures, "actions": actions}


def _describe(
    shown: ShownDesk, text: str
) -> tuple[list[dict[str, Any]], list[dict[str, Any]] | None]:
    """The errors of ``text``, and its regions (to draw the edit) when it is valid."""
    try:
        layout, profile = shown.load(text)
    except ConfigError as err:
        return [error_dict(err)], None
    regions: list[dict[str, Any]] = desk_message(profile, layout, live=False)["regions"]
    return [], regions


def _check(shown: ShownDesk, text: str) -> tuple[list[dict[str, Any]], Layout | None]:
    """What `check` says of ``text``, then whether it adds or changes what only the
    operator may, compared with the layout file as it was when the server started: the
    errors, and the layout when there are none."""
    try:  # (loaded once, for both)
        layout, _ = shown.load(text)
    except ConfigError as err:
        return [error_dict(err)], None
    refused = shown.operator_secrets().refusal(
        layout.raw,
        shown.layout_path,
        shown.registry,
        "the page",
        "edit the layout file by hand and restart the desk",
    )
    return ([], layout) if refused is None else ([error_dict(refused)], None)
