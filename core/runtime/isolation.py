"""Process isolation for an action: its calls run in a child process of their own.

A lane's worker thread isolates an action's *time* only in part. Threads share one GIL and one
heap: an action that spins in Python delays sensing (every switch back to the sensing thread
waits for the GIL), a hung call cannot be killed (its thread is left behind), and a leak grows
the run's own process. An action use that asks for it runs in a child process instead:

    do: {my_plugin_action: {option: 1, isolation: process, max_memory_mb: 300}}

- the child has its own interpreter and GIL, so a busy action cannot hold up sensing;
- a call past its timeout kills the child (really: SIGKILL) and a fresh one is started;
- after each call the child reports its resident memory (``/proc/self/statm``; not the peak
  ``ru_maxrss``, which a child started from a large run inherits across fork and exec); above
  ``max_memory_mb``
  (default :data:`DEFAULT_MAX_MEMORY_MB`) the child is replaced and the log says so.

The cost: starting a child (``spawn``: a fresh interpreter that imports the action's plugin,
a few hundred ms, paid at the start of the run and after each kill), and per call the event
pickled through a pipe and the answer back (about a tenth of a millisecond; see
``tests/runtime/test_runtime_isolation.py``). The action is built in the child from its
plugin's factory with a context holding the desk, the layout path and the layout's settings.
The action's ``order_key`` holds across the boundary: its calls take their turns with those of
the same key in the run's process, each waiting for the child's answer before the next is
let through. An action that needs a resource shared with the rest of the run
(``ActionContext.shared``, e.g. the run's one MQTT connection) cannot be isolated: a second
connection under the same client id would throw the first one off the broker, so building it
says so.
"""

from __future__ import annotations

import logging
import multiprocessing
import resource
import threading
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from hapticdesk.errors import ConfigError, Position
from hapticdesk.files.marked_values import MarkedDict
from hapticdesk.files.validators import number
from hapticdesk.gestures.event import GestureEvent
from hapticdesk.lazy_ref import resolve
from hapticdesk.runtime.dispatcher import ActionContext

if TYPE_CHECKING:
    from hapticdesk.registry import Registry

log = logging.getLogger(__name__)

ISOLATION_KEYS = ("isolation", "max_memory_mb")
DEFAULT_MAX_MEMORY_MB = 512.0
#: the largest limit an action's process may be given, MB (a terabyte: no machine a desk runs on
#: has more; beyond it the limit is a typing mistake that never holds)
MAX_MEMORY_LIMIT_MB = 1e6
DEFAULT_CALL_TIMEOUT_S = 5.0
START_TIMEOUT_S = 30.0  # a fresh interpreter importing the plugin, on a busy machine


class IsolatedActionFailed(RuntimeError):
    """A call in the child failed, ran too long, or the child died."""


@dataclass(frozen=True)
class IsolationSettings:
    """How an action use asked to be run: ``isolation: process`` and its memory limit."""

    max_memory_mb: float = DEFAULT_MAX_MEMORY_MB


def split_isolation(options: Any, position: Position | str) -> tuple[Any, IsolationSettings | None]:
    """The action's own options without the isolation keys, and the isolation asked for
    (None: a thread, the default). Bad values are a ConfigError at their place."""
    if not isinstance(options, dict) or not any(k in options for k in ISOLATION_KEYS):
        return options, None
    marked = options if isinstance(options, MarkedDict) else _marked(options, position)
    kind = marked.get("isolation", "thread")
    if kind not in ("thread", "process"):
        raise ConfigError(
            marked.where("isolation"), f"`isolation` must be thread or process, found {kind!r}"
        )
    if "max_memory_mb" in marked and kind != "process":
        raise ConfigError(
            marked.where("max_memory_mb", of_key=True),
            "`max_memory_mb` needs `isolation: process` (a thread's memory cannot be told apart)",
        )
    limit = number(
        marked,
        "max_memory_mb",
        "the action",
        default=DEFAULT_MAX_MEMORY_MB,
        minimum=16,
        maximum=MAX_MEMORY_LIMIT_MB,
    )
    rest = _marked({k: v for k, v in marked.items() if k not in ISOLATION_KEYS}, marked.where())
    rest.key_positions = {k: p for k, p in marked.key_positions.items() if k in rest}
    rest.value_positions = {k: p for k, p in marked.value_positions.items() if k in rest}
    return rest, IsolationSettings(limit) if kind == "process" else None


def action_use_validator(registry: Registry) -> Callable[[str, Any, Position | str], None]:
    """``validate_action(name, options, position)`` for a layout: the isolation keys are the
    runtime's and checked here; the rest goes to the action's plugin (unknown name or bad
    options: ConfigError)."""

    def validate(name: str, options: Any, position: Position | str) -> None:
        own, _ = split_isolation(options, position)
        registry.validate_action(name, own, position)

    return validate


def _marked(options: dict[str, Any], position: Position | str) -> MarkedDict:
    out = MarkedDict(options)
    out.position = position if isinstance(position, Position) else Position(str(position), 0, 0)
    out.key_positions, out.value_positions = {}, {}
    return out


class ProcessAction:
    """An action whose calls run in a child process (see the module docstring).

    ``factory`` is the plugin's action factory (a module-level callable or a "module:attr"
    text, so the child can import it); ``options`` its options without the isolation keys.
    """

    def __init__(
        self,
        label: str,
        factory: Any,
        options: Any,
        *,
        desk: str,
        layout_path: Path | None,
        settings: Any,
        isolation: IsolationSettings,
    ) -> None:
        self.label = label
        self.isolation = isolation
        self._spec = (factory, options, desk, layout_path, dict(settings or {}))
        self._mp = multiprocessing.get_context("spawn")  # fork is unsafe beside threads
        self._lock = threading.Lock()
        self._process: Any = None
        self._conn: Any = None
        self.restarts = 0
        self.order_key: str | None = None  # the child's action's (set by _start)
        self.call_timeout_s = DEFAULT_CALL_TIMEOUT_S
        self.call_timeout_s = self._start()
        # the lane's watchdog only steps in when killing and restarting the child failed
        self.timeout_s = self.call_timeout_s + START_TIMEOUT_S

    def __call__(self, event: GestureEvent) -> None:
        with self._lock:  # a lane calls one at a time; a replaced worker may overlap
            if self._process is None or not self._process.is_alive():
                self.restarts += 1
                self._start()
            conn = self._conn
            try:
                conn.send(event)
                if not conn.poll(self.call_timeout_s):
                    self._kill()
                    raise IsolatedActionFailed(
                        f"ran longer than {self.call_timeout_s:g} s; its process was killed "
                        "and a new one is started for the next event"
                    )
                kind, detail, resident_mb = conn.recv()
            except (EOFError, OSError, BrokenPipeError):
                code = self._process.exitcode if self._process is not None else None
                self._kill()
                raise IsolatedActionFailed(
                    f"its process died (exit code {code}); a new one is started for the next event"
                ) from None
            if resident_mb > self.isolation.max_memory_mb:
                log.warning(
                    "%s: its process grew to %.0f MB (limit max_memory_mb: %.0f); it is "
                    "replaced by a fresh one",
                    self.label,
                    resident_mb,
                    self.isolation.max_memory_mb,
                )
                self._kill()
        if kind == "failed":
            raise IsolatedActionFailed(detail)

    def close(self) -> None:
        """Let the child close its action and end; kill it if it does not."""
        with self._lock:
            if self._process is None:
                return
            try:
                self._conn.send(None)
                self._process.join(2.0)
            except (OSError, BrokenPipeError):
                pass
            self._kill()

    # --- internals ----------------------------------------------------------------------------

    def _start(self) -> float:
        """Start a child and build the action in it; its own timeout (or the default)."""
        parent, child = self._mp.Pipe()
        process = self._mp.Process(
            target=_child_main, args=(child, *self._spec), name=f"action {self.label}", daemon=True
        )
        try:
            process.start()
        except Exception as err:  # e.g. a factory that cannot be pickled (a lambda)
            raise ConfigError(
                None,
                f"{self.label}: cannot run in a process of its own: {type(err).__name__}: {err}",
            ) from None
        child.close()
        self._process, self._conn = process, parent
        if not parent.poll(START_TIMEOUT_S):
            self._kill()
            raise IsolatedActionFailed(f"its process did not start within {START_TIMEOUT_S:g} s")
        try:
            kind, detail = parent.recv()
        except EOFError:
            self._kill()
            raise IsolatedActionFailed("its process ended while starting") from None
        if kind == "setup-failed":
            self._kill()
            raise ConfigError(None, f"{self.label}: could not be set up: {detail}")
        own, order_key = detail
        # the action's turn among those of its `order_key` is kept here, in the run, where the
        # lanes' turnstile waits for a call's answer from the child (lane.Lane reads it)
        self.order_key = order_key if isinstance(order_key, str) and order_key else None
        return float(own) if own else DEFAULT_CALL_TIMEOUT_S

    def _kill(self) -> None:
        process, self._process = self._process, None
        if self._conn is not None:
            self._conn.close()
            self._conn = None
        if process is not None and process.is_alive():
            process.kill()
        if process is not None:
            process.join(2.0)


def _resident_mb() -> float:
    """This process's resident memory now, in MB.

    Not ``ru_maxrss``: Linux carries the peak over fork and exec, so a child started by a run
    that once held 500 MB would report 500 MB before doing anything."""
    try:
        with open("/proc/self/statm", encoding="ascii") as statm:
            resident_pages = int(statm.read().split()[1])
        return resident_pages * resource.getpagesize() / 2**20
    except (OSError, ValueError, IndexError):  # no /proc: the peak is the best there is
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # kB on Linux


class _ChildContext(ActionContext):
    """The context of an action in its own process: the run's shared resources stay behind."""

    def shared(self, key: str, create: Any) -> Any:
        raise RuntimeError(
            f"it uses the run's shared `{key}` resource, which stays in the run's own "
            "process; remove `isolation: process` from this action"
        )


def _child_main(
    conn: Any,
    factory: Any,
    options: Any,
    desk: str,
    layout_path: Path | None,
    settings: dict[str, Any],
) -> None:
    """The child: build the action, then call it for each event until None arrives."""
    context = _ChildContext(desk, layout_path=layout_path, settings=settings)
    try:
        action = resolve(factory)(options, context)
    except Exception as err:
        conn.send(("setup-failed", f"{type(err).__name__}: {err}"))
        return
    order_key = getattr(action, "order_key", None)
    conn.send(("ready", (getattr(action, "timeout_s", None), order_key)))
    while True:
        try:
            event = conn.recv()
        except EOFError:  # the run ended without saying so
            break
        if event is None:
            break
        try:
            action(event)
            answer: tuple[str, str] = ("ok", "")
        except Exception as err:
            answer = ("failed", f"{type(err).__name__}: {err}")
        conn.send((*answer, _resident_mb()))
    close = getattr(action, "close", None)
    if close is not None:
        try:
            close()
        except Exception:
            pass
    context.close_resources(2.0)
