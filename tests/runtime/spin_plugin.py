"""Misbehaving actions for the isolation tests, importable by a child process (``spawn``)."""

from __future__ import annotations

import time
from typing import Any

from hapticdesk.gestures.event import GestureEvent
from hapticdesk.hookspecs import hookimpl

_kept: list[bytearray] = []


class Spin:
    """Busy for about ``seconds``: ``mode: python`` a pure-Python loop (the interpreter hands
    the GIL over every 5 ms), ``mode: c`` one long C call that holds the GIL throughout
    (``sum(range(n))``, as a regex that backtracks or a C extension without
    ``Py_BEGIN_ALLOW_THREADS`` would)."""

    timeout_s = 30.0

    def __init__(self, options: Any, context: Any) -> None:
        self.seconds = float((options or {}).get("seconds", 1.0))
        self.mode = str((options or {}).get("mode", "python"))

    def __call__(self, event: GestureEvent) -> None:
        if self.mode == "c":
            sum(range(int(self.seconds * 7e7)))  # ~7e7 per second here
            return
        end = time.perf_counter() + self.seconds
        n = 0
        while time.perf_counter() < end:
            n += 1


class Leak:
    """Keeps ``mb`` more megabytes on every call (and touches them, so they count)."""

    timeout_s = 10.0

    def __init__(self, options: Any, context: Any) -> None:
        self.mb = int((options or {}).get("mb", 40))

    def __call__(self, event: GestureEvent) -> None:
        _kept.append(bytearray(b"x" * (self.mb << 20)))


class Hang:
    """Never returns while ``hang`` is in the event's region name."""

    timeout_s = 0.5

    def __init__(self, options: Any, context: Any) -> None:
        pass

    def __call__(self, event: GestureEvent) -> None:
        if "hang" in (event.region or ""):
            time.sleep(3600)


class Stamp:
    """Appends ``label`` and the event's time to the file ``path`` after ``seconds``, under
    the ``order_key`` ``"stamps"``: two of them keep the gestures' order only by their turns."""

    order_key = "stamps"
    timeout_s = 5.0

    def __init__(self, options: Any, context: Any) -> None:
        self.path = str(options["path"])
        self.label = str(options["label"])
        self.seconds = float(options.get("seconds", 0.0))

    def __call__(self, event: GestureEvent) -> None:
        time.sleep(self.seconds)
        with open(self.path, "a", encoding="utf-8") as out:
            out.write(f"{self.label} {event.t}\n")


@hookimpl
def register_actions(register: Any) -> None:
    register("spin", Spin, "a busy loop")
    register("leak", Leak, "keeps memory")
    register("hang", Hang, "never returns")
