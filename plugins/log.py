"""The ``log`` action: print a line for each gesture (for trying a layout out, and for logs).

do: {log: {}}                                     # the event as JSON
do: {log: {message: "{{ region }} {{ gesture }} at {{ x }}, {{ y }}"}}
do: {log: {updates: every}}                       # every update of a slide, too

One line per gesture: a slide's or a force's updates (20 a second while the finger moves)
are not printed one by one but counted, and its ``end`` (or ``cancel``) line says how many
there were and the value they went to (``"updates": 38`` in the JSON, ``(38 updates, value
0.74)`` after a message). A binding that takes updates but no begin still shows the first
update of each touch. ``updates: every`` prints each.
"""

from __future__ import annotations

import json
import sys
import threading
from dataclasses import dataclass
from typing import Any

from hapticdesk.errors import Position
from hapticdesk.files.validators import choice
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

UPDATES = ("summary", "every")

#: the options `log` takes (what the validator allows; the designer's form and the reference
#: are made from it)
OPTIONS: dict[str, dict[str, Any]] = {
    "message": {
        "kind": "text",
        "help": "the line to print, a template ({{ gesture }}, {{ region }}, ...); "
        "the event as JSON when not given",
    },
    "updates": {
        "kind": "text",
        "choices": list(UPDATES),
        "help": "summary (default): a slide's or force's updates counted on its end line; "
        "every: a line for each",
    },
}


@dataclass(frozen=True)
class LogOptions:
    message: Template | None
    updates: str = "summary"


def parse_options(options: Any, position: Position | str) -> LogOptions:
    m = options_mapping(options, position, "`log`", allowed=OPTIONS)
    updates = choice(m, "updates", UPDATES, "`log`", default="summary")
    if "message" not in m:
        return LogOptions(None, updates)
    message = text(m, "message", "`log`")
    return LogOptions(compile_template(message, m.where("message"), "`message` of `log`"), updates)


def validate(options: Any, position: Position | str) -> None:
    parse_options(options, position)


@dataclass
class _Updates:
    """A continuous gesture's updates since its begin: how many, and the last value."""

    count: int = 0
    value: float | None = None


class LogAction:
    """Prints ``[desk] message`` (or the event's JSON) to standard output."""

    timeout_s = 2.0
    # every binding's log prints to one standard output: in the gestures' order (each
    # binding's action has its lane, so at --speed 0 a later tap's line came out first)
    order_key = "log"

    def __init__(self, options: Any, context: ActionContext) -> None:
        self.options = parse_options(options, where(options, "`log`"))
        self.desk = context.desk_name
        #: (gesture, region) -> updates of the continuous gesture going on there
        self._going: dict[tuple[str, str | None], _Updates] = {}

    def __call__(self, event: GestureEvent) -> None:
        summary = self._summary(event) if self.options.updates == "summary" else None
        if summary is False:
            return  # an update, counted for its end line
        if self.options.message is None:
            document = event.to_dict()
            if summary:
                document["updates"] = summary.count
            line = json.dumps(document, ensure_ascii=False)
        else:
            line = self.options.message.render(event_variables(event, self.desk))
            if summary:
                value = "" if summary.value is None else f", value {summary.value:.2f}"
                line += f" ({summary.count} updates{value})"
        with _print_lock:
            print(f"[{self.desk}] {line}", file=sys.stdout, flush=True)

    def _summary(self, event: GestureEvent) -> _Updates | bool | None:
        """False for an update to count and not print; the updates counted for an end or a
        cancel that had some; None for a line printed as it is."""
        key = (event.gesture, event.region)
        if event.phase == "begin":
            self._going[key] = _Updates()
        elif event.phase == "update":
            going = self._going.get(key)
            if going is None:  # no begin seen (a binding of updates only): show this one
                self._going[key] = _Updates()
                return None
            going.count += 1
            going.value = event.value
            return False
        elif event.phase in ("end", "cancel"):
            going = self._going.pop(key, None)
            if going is not None and going.count:
                return going
        return None


@hookimpl
def register_actions(register: Any) -> None:
    register(
        "log",
        LogAction,
        "print a line for each gesture (a slide's updates counted on its end line)",
        validate=validate,
        options=OPTIONS,
        check_events=CHECK_EVENTS,
    )
