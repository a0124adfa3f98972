"""The ``http`` action: call a webhook with the standard library.

    do: {http: {url: "http://homeassistant.local:8123/api/webhook/desk"}}       # POST event JSON
    do: {http: {url: "http://10.0.0.5/set", method: GET}}
    do: {http: {url: "...", json: {light: "{{ region }}", level: "{{ value }}"},
                headers: {Authorization: "Bearer ..."}, timeout_s: 3}}

Without ``json`` or ``body`` the event itself is POSTed as JSON. A status of 400 or more, a
refused connection or a timeout counts as a failure.
"""

from __future__ import annotations

import json
import urllib.error
import urllib.parse
import urllib.request
from dataclasses import dataclass
from typing import Any

from hapticdesk.files.yamlfile import ConfigError, Position, choice, require_mapping
from hapticdesk.gestures.event import GestureEvent
from hapticdesk.hookspecs import hookimpl
from hapticdesk.plugins.action_options import options_mapping, seconds, text, where
from hapticdesk.plugins.templating import (
    Template,
    TemplatedValue,
    compile_template,
    compile_value,
    event_variables,
)
from hapticdesk.runtime.dispatcher import ActionContext

DEFAULT_TIMEOUT_S = 5.0
METHODS = ("POST", "PUT", "PATCH", "GET", "DELETE")


class HttpFailed(RuntimeError):
    """The request failed or the server answered with an error status."""


@dataclass(frozen=True)
class HttpOptions:
    url: Template
    method: str
    json: TemplatedValue | None
    body: Template | None
    headers: dict[str, Template]
    timeout_s: float


def parse_options(options: Any, position: Position | str) -> HttpOptions:
    m = options_mapping(
        options,
        position,
        "`http`",
        {"url", "method", "json", "body", "headers", "timeout_s"},
        {"url"},
    )
    url = text(m, "url", "`http`")
    scheme = urllib.parse.urlsplit(url).scheme if "{" not in url.split("//")[0] else "http"
    if scheme not in ("http", "https"):
        raise ConfigError(
            m.where("url"), f"`url` of `http` must start with http:// or https://, found {url!r}"
        )
    if "json" in m and "body" in m:
        raise ConfigError(m.where("body", of_key=True), "`http` takes `json` or `body`, not both")
    headers = {}
    if "headers" in m:
        h = require_mapping(m["headers"], m.where("headers"), "`headers` of `http`")
        for key, value in h.items():
            if not isinstance(value, str):
                raise ConfigError(h.where(key), f"header `{key}` must be text")
            headers[str(key)] = compile_template(value, h.where(key), f"header `{key}`")
    return HttpOptions(
        url=compile_template(url, m.where("url"), "`url` of `http`"),
        method=choice(m, "method", METHODS, "`http`", default="POST"),
        json=compile_value(m["json"], m.where("json"), "`json` of `http`") if "json" in m else None,
        body=compile_template(text(m, "body", "`http`"), m.where("body"), "`body`")
        if "body" in m
        else None,
        headers=headers,
        timeout_s=seconds(m, "timeout_s", "`http`", DEFAULT_TIMEOUT_S),
    )


def validate(options: Any, position: Position | str) -> None:
    parse_options(options, position)


class HttpAction:
    """One request per event."""

    def __init__(self, options: Any, context: ActionContext) -> None:
        self.options = parse_options(options, where(options, "`http`"))
        self.desk = context.desk_name
        self.timeout_s = self.options.timeout_s + 2.0

    def __call__(self, event: GestureEvent) -> None:
        o = self.options
        variables = event_variables(event, self.desk)
        headers = {key: value.render(variables) for key, value in o.headers.items()}
        data: bytes | None = None
        if o.body is not None:
            data = o.body.render(variables).encode("utf-8")
        elif o.method != "GET":
            document = o.json.render(variables) if o.json is not None else event.to_dict()
            data = json.dumps(document, allow_nan=False).encode("utf-8")
            headers.setdefault("Content-Type", "application/json")
        url = o.url.render(variables)
        request = urllib.request.Request(url, data=data, headers=headers, method=o.method)
        try:
            with urllib.request.urlopen(request, timeout=o.timeout_s) as response:
                response.read(65536)
        except urllib.error.HTTPError as err:
            raise HttpFailed(f"{o.method} {url} answered {err.code} {err.reason}") from None
        except (urllib.error.URLError, TimeoutError, OSError) as err:
            reason = getattr(err, "reason", err)
            raise HttpFailed(f"{o.method} {url} failed: {reason}") from None


@hookimpl
def register_actions(register: Any) -> None:
    register(
        "http", HttpAction, "call a webhook (standard library, no extra package)", validate=validate
    )
