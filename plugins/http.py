"""The ``http`` action: call a webhook with the standard library.

    do: {http: {url: "http://homeassistant.local:8123/api/webhook/desk"}}       # POST event JSON
    do: {http: {url: "http://10.0.0.5/set", method: GET}}
    do: {http: {url: "...", json: {light: "{{ region }}", level: "{{ value }}"},
                headers: {Authorization: {env: HA_TOKEN, prefix: "Bearer "}}, timeout_s: 3}}

Without ``json`` or ``body`` the event itself is POSTed as JSON. A status of 300 or more
(redirects are not followed), a refused connection or a timeout counts as a failure.

Secrets never sit in the layout: a URL with ``user:password@`` is refused, and a header that
carries credentials (``Authorization``, ``Cookie``, ``X-Api-Key``, any name with ``token``,
``secret``, ``password`` or ``key``) takes its value from ``{env: VARIABLE}`` or
``{file: PATH}`` (optionally with a ``prefix`` such as ``"Bearer "``). Log lines show the URL
as ``scheme://host:port/…``: the path of a webhook is itself a secret.

``timeout_s`` bounds the whole call (connecting, sending, and reading the answer), not each
socket read: a server that answers a byte at a time is cut off at the deadline.

The calls to one server (scheme, host and port, as written) keep the gestures' order across
every ``http`` action of the run: a webhook that turns a light on and another that turns it
off, a moment later, reach the server in that order.
"""

from __future__ import annotations

import http.client
import json
import os
import socket
import threading
import urllib.parse
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hapticdesk.errors import ConfigError, Position
from hapticdesk.files.validators import choice, require_mapping
from hapticdesk.gestures.event import GestureEvent
from hapticdesk.hookspecs import hookimpl
from hapticdesk.plugins.action_options import options_mapping, seconds, text, where
from hapticdesk.plugins.templating import (
    CHECK_EVENTS,
    Template,
    TemplatedValue,
    compile_template,
    compile_value,
    event_variables,
)
from hapticdesk.runtime.dispatcher import ActionContext

DEFAULT_TIMEOUT_S = 5.0
METHODS = ("POST", "PUT", "PATCH", "GET", "DELETE")
SECRET_HEADERS = ("authorization", "proxy-authorization", "cookie")
SECRET_WORDS = ("token", "secret", "password", "key", "auth")


#: the options `http` takes (what the validator allows; the designer's form and the reference
#: are made from it)
OPTIONS: dict[str, dict[str, Any]] = {
    "url": {"kind": "text", "required": True, "help": "http(s)://host/path, no password"},
    "method": {"kind": "text", "choices": list(METHODS), "help": "POST by default"},
    "json": {"kind": "mapping", "help": "a JSON body (templated); the event itself by default"},
    "body": {"kind": "text", "help": "a text body (templated), instead of `json`"},
    "headers": {
        "kind": "mapping",
        "help": "{name: text}; one carrying credentials comes from {env: VARIABLE} or "
        '{file: PATH}, with an optional prefix ("Bearer ")',
    },
    "timeout_s": {
        "kind": "number",
        "help": f"seconds for the whole call (default {DEFAULT_TIMEOUT_S:g})",
    },
}


class HttpFailed(RuntimeError):
    """The request failed or the server answered with an error status."""


@dataclass(frozen=True)
class HttpOptions:
    url: Template
    method: str
    json: TemplatedValue | None
    body: Template | None
    headers: dict[str, Template]
    secret_headers: dict[str, SecretHeader]
    timeout_s: float


@dataclass(frozen=True)
class SecretHeader:
    """A header whose value comes from an environment variable or a file, read per call (so a
    rotated token is picked up) and never logged."""

    env: str | None
    file: Path | None
    prefix: str

    def value(self) -> str:
        if self.env is not None:
            if self.env not in os.environ:
                raise HttpFailed(f"the environment variable {self.env} is not set")
            secret = os.environ[self.env]
        else:
            assert self.file is not None
            try:
                secret = self.file.read_text(encoding="utf-8").strip()
            except OSError as err:
                raise HttpFailed(f"cannot read {self.file}: {err.strerror}") from None
        return self.prefix + secret


def is_secret_header(name: str) -> bool:
    """Whether a header (by name) carries credentials."""
    lower = name.lower()
    return lower in SECRET_HEADERS or any(word in lower for word in SECRET_WORDS)


def redact_url(url: str) -> str:
    """``scheme://host[:port]/…``: what may go into a log line (no user, path or query)."""
    try:
        parts = urllib.parse.urlsplit(url)
        host = parts.hostname or "?"
        port = f":{parts.port}" if parts.port else ""
    except ValueError:
        return "(an invalid URL)"
    rest = "/…" if (parts.path not in ("", "/") or parts.query) else "/"
    return f"{parts.scheme}://{host}{port}{rest}"


def parse_options(options: Any, position: Position | str) -> HttpOptions:
    m = options_mapping(options, position, "`http`", OPTIONS, {"url"})
    url = text(m, "url", "`http`")
    if "@" in urllib.parse.urlsplit(url).netloc:
        raise ConfigError(
            m.where("url"),
            "`url` of `http` must not hold `user:password@` (it would be logged, and the "
            "password sits in the layout); give the credentials as a header from the "
            "environment or a file, e.g. headers: {Authorization: {env: HA_TOKEN, prefix: "
            '"Bearer "}}',
        )
    scheme = urllib.parse.urlsplit(url).scheme if "{" not in url.split("//")[0] else "http"
    if scheme not in ("http", "https"):
        raise ConfigError(
            m.where("url"), f"`url` of `http` must start with http:// or https://, found {url!r}"
        )
    parts = urllib.parse.urlsplit(url)
    if "{" not in parts.netloc:  # (a templated server is known at the call only)
        try:
            _ = parts.port  # (urllib checks it as it reads it)
        except ValueError:
            raise ConfigError(
                m.where("url"), f"`url` of `http` has no valid port (0-65535): {parts.netloc!r}"
            ) from None
    if "json" in m and "body" in m:
        raise ConfigError(m.where("body", of_key=True), "`http` takes `json` or `body`, not both")
    headers = {}
    secret_headers = {}
    if "headers" in m:
        h = require_mapping(m["headers"], m.where("headers"), "`headers` of `http`")
        for key, value in h.items():
            if isinstance(value, dict):
                secret_headers[str(key)] = _secret_header(value, h.where(key), str(key))
                continue
            if not isinstance(value, str):
                raise ConfigError(h.where(key), f"header `{key}` must be text")
            if is_secret_header(str(key)):
                raise ConfigError(
                    h.where(key),
                    f"header `{key}` carries credentials: take it from the environment or a "
                    f'file, e.g. {key}: {{env: VARIABLE, prefix: "Bearer "}} or '
                    f"{key}: {{file: secrets/token.txt}}, not written in the layout",
                )
            headers[str(key)] = compile_template(value, h.where(key), f"header `{key}`")
    return HttpOptions(
        url=compile_template(url, m.where("url"), "`url` of `http`"),
        method=choice(m, "method", METHODS, "`http`", default="POST"),
        json=compile_value(m["json"], m.where("json"), "`json` of `http`") if "json" in m else None,
        body=compile_template(text(m, "body", "`http`"), m.where("body"), "`body`")
        if "body" in m
        else None,
        headers=headers,
        secret_headers=secret_headers,
        timeout_s=seconds(m, "timeout_s", "`http`", DEFAULT_TIMEOUT_S),
    )


def _secret_header(value: Any, position: Position | str, name: str) -> SecretHeader:
    what = f"header `{name}`"
    h = options_mapping(value, position, what, {"env", "file", "prefix"})
    if ("env" in h) == ("file" in h):
        raise ConfigError(h.where(), f"{what} needs `env: VARIABLE` or `file: PATH` (one)")
    prefix = h.get("prefix", "")
    if not isinstance(prefix, str):
        raise ConfigError(h.where("prefix"), f"`prefix` of {what} must be text")
    if "env" in h:
        return SecretHeader(text(h, "env", what), None, prefix)
    return SecretHeader(None, Path(text(h, "file", what)).expanduser(), prefix)


def validate(options: Any, position: Position | str) -> None:
    parse_options(options, position)


def server_key(url: str) -> str | None:
    """The ``order_key`` of calls to ``url``'s server, ``http scheme://host:port`` (the
    scheme's port where none is written); None where the server part is templated."""
    parts = urllib.parse.urlsplit(url)
    if "{" in parts.netloc or "}" in parts.netloc or not parts.hostname:
        return None
    port = parts.port or (443 if parts.scheme == "https" else 80)
    return f"http {parts.scheme}://{parts.hostname.lower()}:{port}"


class HttpAction:
    """One request per event."""

    def __init__(self, options: Any, context: ActionContext) -> None:
        o = parse_options(options, where(options, "`http`"))
        # a token file is relative to the layout, like every path in it
        secrets = {
            name: SecretHeader(h.env, context.resolve_path(h.file), h.prefix) if h.file else h
            for name, h in o.secret_headers.items()
        }
        self.options = HttpOptions(o.url, o.method, o.json, o.body, o.headers, secrets, o.timeout_s)
        self.desk = context.desk_name
        self.timeout_s = self.options.timeout_s + 2.0
        #: the calls of every `http` action to one server take their turns in the gestures'
        #: order (a light switched on and then off through two webhooks ends off), each once the
        #: calls before it have ended or been given up on; none where the server is templated
        self.order_key = server_key(str(options["url"]))

    def __call__(self, event: GestureEvent) -> None:
        o = self.options
        variables = event_variables(event, self.desk)
        headers = {key: value.render(variables) for key, value in o.headers.items()}
        headers.update({key: secret.value() for key, secret in o.secret_headers.items()})
        data: bytes | None = None
        if o.body is not None:
            data = o.body.render(variables).encode("utf-8")
        elif o.method != "GET":
            document = o.json.render(variables) if o.json is not None else event.to_dict()
            data = json.dumps(document, allow_nan=False).encode("utf-8")
            headers.setdefault("Content-Type", "application/json")
        call(o.method, o.url.render(variables), data, headers, o.timeout_s)


def call(
    method: str, url: str, data: bytes | None, headers: dict[str, str], timeout_s: float
) -> int:
    """One request, all of it within ``timeout_s``; the status, or :class:`HttpFailed` whose
    message holds only the redacted URL."""
    shown = f"{method} {redact_url(url)}"
    try:
        parts = urllib.parse.urlsplit(url)
        port = parts.port
    except ValueError as err:
        raise HttpFailed(f"{shown}: invalid URL: {err}") from None
    if parts.scheme not in ("http", "https") or not parts.hostname:
        raise HttpFailed(f"{shown}: the URL must be http(s)://host/...")
    if "@" in parts.netloc:  # a template rendered one: urllib would take user:pass as the host
        raise HttpFailed(f"{shown}: the URL holds `user:password@`, which is refused")
    kind = http.client.HTTPSConnection if parts.scheme == "https" else http.client.HTTPConnection
    connection = kind(parts.hostname, port, timeout=timeout_s)
    target = urllib.parse.urlunsplit(("", "", parts.path or "/", parts.query, ""))
    expired = threading.Event()

    def expire() -> None:  # the deadline: end the call whatever it is waiting for
        expired.set()
        sock = connection.sock
        if sock is not None:
            try:
                sock.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass

    timer = threading.Timer(timeout_s, expire)
    timer.daemon = True
    timer.start()
    try:
        connection.connect()
        if expired.is_set():
            raise TimeoutError
        connection.request(method, target, body=data, headers=headers)
        response = connection.getresponse()
        response.read(65536)
        status = response.status
    except (OSError, http.client.HTTPException) as err:
        if expired.is_set() or isinstance(err, TimeoutError):
            raise HttpFailed(f"{shown} took longer than {timeout_s:g} s in all") from None
        reason = getattr(err, "strerror", None) or str(err) or type(err).__name__
        raise HttpFailed(f"{shown} failed: {reason}") from None
    finally:
        timer.cancel()
        connection.close()
    if status >= 300:
        redirect = " (redirects are not followed)" if status < 400 else ""
        raise HttpFailed(f"{shown} answered {status} {response.reason}{redirect}")
    return status


@hookimpl
def register_actions(register: Any) -> None:
    register(
        "http",
        HttpAction,
        "call a webhook (standard library, no extra package)",
        validate=validate,
        options=OPTIONS,
        check_events=CHECK_EVENTS,
    )
