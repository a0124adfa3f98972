"""The ``exec`` action: run a program with templated arguments, never through a shell.

    do: {exec: {argv: [notify-send, "desk", "{{ region }}: {{ gesture }}"], timeout_s: 5}}

Each argument is rendered on its own and passed as one argv item, so nothing a template
renders can become shell syntax. A non-zero exit status or a timeout counts as a failure
(with the end of the program's stderr in the log).

The program runs in a session (and process group) of its own; at the timeout the whole group
is killed, so ``sh -c "sleep 40 & sleep 100"`` leaves no orphan behind.
"""

from __future__ import annotations

import logging
import os
import shutil
import signal
import subprocess
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hapticdesk.errors import ConfigError, Position
from hapticdesk.files.marked_values import MarkedList
from hapticdesk.gestures.event import GestureEvent
from hapticdesk.hookspecs import hookimpl
from hapticdesk.plugins.action_options import options_mapping, seconds, text, where
from hapticdesk.plugins.templating import (
    CHECK_EVENTS,
    Template,
    compile_template,
    event_variables,
)
from hapticdesk.runtime.dispatcher import ActionContext

log = logging.getLogger(__name__)

DEFAULT_TIMEOUT_S = 10.0

#: the options `exec` takes (what the validator allows; the reference lists them from here)
OPTIONS: dict[str, dict[str, Any]] = {
    "argv": {
        "kind": "list",
        "required": True,
        "help": "[program, argument, ...]: each item a template rendered on its own and passed "
        "as one argument, never through a shell",
    },
    "timeout_s": {
        "kind": "number",
        "help": f"seconds the program may run before its whole process group is killed "
        f"(default {DEFAULT_TIMEOUT_S:g})",
    },
    "cwd": {"kind": "text", "help": "the folder it runs in, relative to the layout"},
}


class ExecFailed(RuntimeError):
    """The program exited with an error or ran too long."""


@dataclass(frozen=True)
class ExecOptions:
    argv: tuple[Template, ...]
    timeout_s: float
    cwd: str | None


def parse_options(options: Any, position: Position | str) -> ExecOptions:
    m = options_mapping(options, position, "`exec`", OPTIONS, {"argv"})
    raw = m["argv"]
    if not isinstance(raw, list) or not raw:
        raise ConfigError(
            m.where("argv"), "`argv` of `exec` must be a non-empty list: [program, arg, ...]"
        )
    argv = []
    for i, item in enumerate(raw):
        pos = raw.where(i) if isinstance(raw, MarkedList) else m.where("argv")
        if isinstance(item, bool) or not isinstance(item, str | int | float):
            raise ConfigError(pos, f"argument {i + 1} of `exec` must be text, found {item!r}")
        argv.append(compile_template(str(item), pos, f"argument {i + 1} of `exec`"))
    cwd = text(m, "cwd", "`exec`") if "cwd" in m else None
    return ExecOptions(tuple(argv), seconds(m, "timeout_s", "`exec`", DEFAULT_TIMEOUT_S), cwd)


def validate(options: Any, position: Position | str) -> None:
    parse_options(options, position)


class ExecAction:
    """Runs the program once per event and waits for it (up to its timeout)."""

    def __init__(self, options: Any, context: ActionContext) -> None:
        self.options = parse_options(options, where(options, "`exec`"))
        self.desk = context.desk_name
        self.cwd: Path | None = context.resolve_path(self.options.cwd) if self.options.cwd else None
        # the dispatcher's watchdog only steps in when the program's own timeout failed
        self.timeout_s = self.options.timeout_s + 2.0
        program = self.options.argv[0]
        if program.compiled is None and shutil.which(program.text, path=None) is None:
            log.warning("exec: program %r is not found on PATH; its calls will fail", program.text)

    def __call__(self, event: GestureEvent) -> None:
        variables = event_variables(event, self.desk)
        argv = [arg.render(variables) for arg in self.options.argv]
        returncode, stderr = run_in_own_group(argv, self.cwd, self.options.timeout_s)
        if returncode != 0:
            tail = stderr.decode("utf-8", "replace").strip()[-300:]
            raise ExecFailed(
                f"{argv[0]} exited with status {returncode}" + (f": {tail}" if tail else "")
            )


def run_in_own_group(argv: list[str], cwd: Path | None, timeout_s: float) -> tuple[int, bytes]:
    """Run ``argv`` in a new session; at ``timeout_s`` kill its whole process group.

    Returns (exit status, stderr). ``subprocess.run``'s timeout kills only the direct child:
    whatever it started in the background would live on as an orphan.
    """
    try:
        process = subprocess.Popen(
            argv,
            cwd=cwd,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            start_new_session=True,  # its own session and process group, with id process.pid
        )
    except OSError as err:
        raise ExecFailed(f"cannot run {argv[0]}: {err.strerror or err}") from None
    with process:
        try:
            _, stderr = process.communicate(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            _kill_group(process.pid)
            process.wait()
            raise ExecFailed(
                f"{argv[0]} ran longer than {timeout_s:g} s and was killed "
                "(with every process it started)"
            ) from None
    return process.returncode, stderr


def _kill_group(pgid: int) -> None:
    try:
        os.killpg(pgid, signal.SIGKILL)
    except ProcessLookupError:  # everyone in it has ended meanwhile
        pass


@hookimpl
def register_actions(register: Any) -> None:
    register(
        "exec",
        ExecAction,
        "run a program with templated arguments (no shell)",
        validate=validate,
        options=OPTIONS,
        check_events=CHECK_EVENTS,
        operator_only=True,  # a program may read anything: only whoever starts the desk adds one
    )
