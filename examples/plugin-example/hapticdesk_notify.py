"""A hapticdesk action plugin: ``notify`` appends one line per gesture to a file.

    bindings:
      - gesture: tap
        region: lamp
        do: {notify: {file: taps.log, message: "{{ region }} tapped at {{ t }} s"}}

Copy this module to start your own action: one ``@hookimpl`` that registers the action, a
``validate`` that points at the layout's ``file:line:column`` when the options are wrong, and
a class that is built once per run and called once per matching gesture.
"""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Any

from hapticdesk.errors import ConfigError
from hapticdesk.files.marked_values import MarkedDict
from hapticdesk.files.validators import check_keys
from hapticdesk.hookspecs import hookimpl
from hapticdesk.plugins.templating import compile_template, event_variables

__version__ = "0.1.0"

DEFAULT_MESSAGE = "{{ action }} at {{ '%.2f' | format(t) }} s"


def validate(options: Any, position: Any) -> None:
    """Check the options while the layout loads; raise ConfigError naming where and what."""
    if not isinstance(options, MarkedDict):
        raise ConfigError(position, "`notify` needs a mapping: {file: PATH, message: TEMPLATE}")
    check_keys(options, {"file", "message"}, "`notify`", required={"file"})
    if not isinstance(options["file"], str) or not options["file"]:
        raise ConfigError(options.where("file"), "`file` of `notify` must be a file path")
    message = options.get("message", DEFAULT_MESSAGE)
    if not isinstance(message, str):
        raise ConfigError(options.where("message"), "`message` of `notify` must be text")
    compile_template(message, options.where("message"), "`message` of `notify`")


class Notify:
    """Built once per run with the action's options; called for each matching gesture."""

    #: how long one call may take before hapticdesk gives up on it (seconds)
    timeout_s = 2.0

    def __init__(self, options: Any, context: Any) -> None:
        # ``context.resolve_path`` makes the path relative to the layout file, like every
        # other path in a layout; ``context.desk`` is the desk's name
        self.path = Path(context.resolve_path(options["file"]))
        self.message = compile_template(options.get("message", DEFAULT_MESSAGE), "notify")
        self.desk = context.desk
        self._lock = threading.Lock()

    def __call__(self, event: Any) -> None:
        line = self.message.render(event_variables(event, self.desk))
        with self._lock, self.path.open("a", encoding="utf-8") as fh:
            fh.write(line + "\n")

    def close(self) -> None:
        """Called once when the run ends (nothing to release here)."""


@hookimpl
def register_actions(register: Any) -> None:
    register("notify", Notify, "append a line per gesture to a file", validate=validate)
