"""Telling a running desk what to do: re-tare, pause, resume, reload or switch its layout.

A :class:`ControlQueue` is the one way in, for the command line's SIGHUP, a plugin's network
channel (the MQTT plugin's ``<prefix>/set``, through the ``control_channel`` hook) and Python
code (the browser UI): :meth:`ControlQueue.request` only queues a :class:`ControlCommand` and
returns a :class:`concurrent.futures.Future`; the sensing thread applies what is queued
between two blocks (:meth:`hapticdesk.runtime.service.Runtime.apply_control`), so sensing
never waits for a command and a command never sees half a block.

The commands (:data:`COMMANDS`):

- ``tare``: forget the zero and take it again over the next ``tare_s`` of a still desk.
- ``pause`` / ``resume``: gestures are recognised but not sent while paused; sensing goes on,
  so the zero keeps following drift and no new tare is needed after ``resume``. A pause ends
  by itself after ``for_s`` seconds (default and at most :data:`MAX_PAUSE_S`; any client of
  the broker can send one, so none lasts for ever), and says so.
- ``reload``: read the current layout file again and rebuild the gesture engine and the
  actions; the estimator (and its zero) and shared connections (the MQTT session) are kept.
- ``layout NAME``: switch to one of the layout's ``layouts:`` (``default`` is the layout the
  run started with), as a reload of that file.

As JSON (what ``<prefix>/set`` takes): ``{"command": "tare"}``, ``{"command": "layout",
"layout": "evening"}``, ``{"command": "pause", "for_s": 600}``, or the short forms
``"tare"``, ``{"tare": true}``, ``{"layout": "evening"}``, ``{"pause": 600}``.
"""

from __future__ import annotations

import json
import queue
from concurrent.futures import Future
from dataclasses import dataclass
from typing import Any

#: every command a running desk takes
COMMANDS = ("tare", "pause", "resume", "reload", "layout")
MAX_PAYLOAD = 4096  # bytes: a command is a word or two; anything longer is not one
MAX_WAITING = 64  # commands queued at most (a flood from the network cannot grow memory)
#: the longest a pause lasts (seconds) unless it asks for less: it ends by itself then
MAX_PAUSE_S = 3600.0


class ControlError(ValueError):
    """A command that is not one (unknown name, bad JSON, missing layout name)."""


@dataclass(frozen=True)
class ControlCommand:
    """One command; ``argument`` is the layout's name for ``layout``, else None."""

    name: str
    argument: str | None = None

    def __str__(self) -> str:
        return self.name if self.argument is None else f"{self.name} {self.argument}"


def parse_command(payload: bytes | str) -> ControlCommand:
    """A command from its JSON (see the module docstring); ControlError says what is wrong."""
    if isinstance(payload, bytes):
        if len(payload) > MAX_PAYLOAD:
            raise ControlError(f"a command is at most {MAX_PAYLOAD} bytes, found {len(payload)}")
        try:
            payload = payload.decode("utf-8")
        except UnicodeDecodeError:
            raise ControlError("a command must be UTF-8 JSON") from None
    text = payload.strip()
    if text.isidentifier():  # a bare word is accepted too
        return command(text)
    try:
        value = json.loads(text)
    except (json.JSONDecodeError, RecursionError):
        raise ControlError(
            f'expected JSON such as {{"command": "tare"}}, found {text[:60]!r}'
        ) from None
    if isinstance(value, str):
        return command(value)
    if not isinstance(value, dict):
        raise ControlError(f"expected a JSON object or a command name, found {text[:60]!r}")
    if "command" in value:
        name = value["command"]
        if not isinstance(name, str):
            raise ControlError(f"`command` must be one of {', '.join(COMMANDS)}, found {name!r}")
        return command(name, value.get("for_s") if name == "pause" else value.get("layout"))
    named = [k for k in value if k in COMMANDS]
    if len(named) != 1:
        raise ControlError(
            f"expected one command of {', '.join(COMMANDS)}, found keys {sorted(value)}"
        )
    name = named[0]
    argument = value[name] if name in ("layout", "pause") else None
    if name == "pause" and argument is True:  # {"pause": true}
        argument = None
    return command(name, argument)


def command(name: str, argument: Any = None) -> ControlCommand:
    """A checked :class:`ControlCommand` (ControlError if ``name`` is not a command)."""
    if name not in COMMANDS:
        shown = name if len(name) <= 60 else f"{name[:60]}…"  # (a 4 kB word was echoed whole)
        raise ControlError(f"unknown command {shown!r}; known: {', '.join(COMMANDS)}")
    if name == "layout":
        if not isinstance(argument, str) or not argument:
            raise ControlError('`layout` needs the name of a layout: {"layout": "evening"}')
        return ControlCommand(name, argument)
    if name == "pause" and argument is not None:
        seconds = pause_seconds(argument)
        return ControlCommand(name, f"{seconds:g}")
    return ControlCommand(name)


def pause_seconds(argument: Any) -> float:
    """A pause's length from its argument: a number of seconds, 1 to MAX_PAUSE_S."""
    try:
        seconds = float(argument)
    except (TypeError, ValueError):
        seconds = float("nan")
    if isinstance(argument, bool) or not 1.0 <= seconds <= MAX_PAUSE_S:
        raise ControlError(
            f"`pause` takes `for_s`, seconds from 1 to {MAX_PAUSE_S:g}, found {argument!r}"
        )
    return seconds


class ControlQueue:
    """Commands waiting for the sensing thread; :meth:`request` is safe from any thread."""

    def __init__(self) -> None:
        self._queue: queue.Queue[tuple[ControlCommand, Future[str]]] = queue.Queue(MAX_WAITING)

    def request(self, name: str | ControlCommand, argument: str | None = None) -> Future[str]:
        """Queue a command; never blocks. The future's result is a line saying what was done,
        or its exception (ControlError, or a ConfigError from a layout that does not load,
        in which case the run goes on with the layout it had)."""
        cmd = name if isinstance(name, ControlCommand) else command(name, argument)
        future: Future[str] = Future()
        try:
            self._queue.put_nowait((cmd, future))
        except queue.Full:
            future.set_exception(ControlError(f"{MAX_WAITING} commands are already waiting"))
        return future

    def take(self) -> list[tuple[ControlCommand, Future[str]]]:
        """Everything queued so far (the sensing thread, between blocks)."""
        out = []
        while True:
            try:
                out.append(self._queue.get_nowait())
            except queue.Empty:
                return out
