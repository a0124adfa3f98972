"""The ``log`` action: print a line for each gesture (for trying a layout out, and for logs).

do: {log: {}}                                     # the event as JSON
do: {log: {message: "{{ region }} {{ gesture }} at {{ x }}, {{ y }}"}}
"""

from __future__ import annotations

import sys
import threading
from dataclasses import dataclass
from typing import Any

from hapticdesk.files.yamlfile import Position
from hapticdesk.gestures.event import GestureEvent
from hapticdesk.hookspecs import hookimpl
from hapticdesk.plugins.action_options import options_mapping, text, where
from hapticdesk.plugins.templating import (
    CHECK_EVENTS,
    Template,
    compile_template,
    event_variables,
)
from hapticdesk.runtime.dispatcher import ActionContext

_print_lock = threading.Lock()  # lines from several action threads must not interleave


@dataclass(frozen=True)
class LogOptions:
    message: Template | None


def parse_options(options: Any, position: Position | str) -> LogOptions:
    m = options_mapping(options, position, "`log`", allowed={"message"})
    if "message" not in m:
        return LogOptions(None)
    message = text(m, "message", "`log`")
    return LogOptions(compile_template(message, m.where("message"), "`message` of `log`"))


def validate(options: Any, position: Position | str) -> None:
    parse_options(options, position)


class LogAction:
    """Prints ``[desk] message`` (or the event's JSON) to standard output."""

    timeout_s = 2.0

    def __init__(self, options: Any, context: ActionContext) -> None:
        self.options = parse_options(options, where(options, "`log`"))
        self.desk = context.desk_name

    def __call__(self, event: GestureEvent) -> None:
        if self.options.message is None:
            text = event.to_json()
        else:
            text = self.options.message.render(event_variables(event, self.desk))
        with _print_lock:
            print(f"[{self.desk}] {text}", file=sys.stdout, flush=True)


@hookimpl
def register_actions(register: Any) -> None:
    register(
        "log",
        LogAction,
        "print a line for each gesture",
        validate=validate,
        check_events=CHECK_EVENTS,
        options={
            "message": {
                "kind": "text",
                "help": "the line to print, a template ({{ gesture }}, {{ region }}, ...); "
                "the event as JSON when not given",
            }
        },
    )
