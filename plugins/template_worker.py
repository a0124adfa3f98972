"""Templates rendered in worker processes: a deadline and a memory bound no C call can pass.

The sandbox (:mod:`.template_sandbox`) checks the size of everything it makes before making
it, and its budget of steps and time is checked at every loop turn and call. Neither can stop
one C call that was never foreseen: it holds the GIL until it returns, so no thread can
interrupt it (``{{ ((9**999)**999)**999 }}`` had frozen a desk for minutes, SIGTERM
ignored). So every rendering happens in a worker process of its own:

- its address space is limited (``RLIMIT_AS``) to what it holds after start-up plus
  :data:`MEMORY_BOUND_MB`; an allocation past it is a MemoryError in the worker, reported as
  a limit, and the worker is replaced;
- the process that asked waits :data:`KILL_SHARE` of the rendering's time limit for the
  answer, then kills the worker (SIGKILL) and says the template took too long; a fresh worker
  is started at once for the next rendering;
- its CPU time is limited (``RLIMIT_CPU``) to a few seconds past what it had used before each
  rendering, so a worker whose parent died mid-rendering does not spin on.

Workers hold nothing but Jinja2 and the sandbox: the environment they start with is stripped
to what Python needs (no tokens or passwords of the desk's), they read requests as JSON
lines on stdin and answer on stdout. A pool of up to :data:`MAX_WORKERS` serves the threads
of a run (dispatcher lanes render at once). Where no worker can be started, templates render
in this process (the sandbox's own bounds only), which the log says once.

Run as ``python -m hapticdesk.plugins.template_worker`` (the pool does this).
"""

from __future__ import annotations

import json
import logging
import os
import select
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Mapping
from typing import Any

log = logging.getLogger(__name__)

#: how much memory one rendering may take beyond what the worker holds when idle
MEMORY_BOUND_MB = 100
#: workers at most: renderings of different lanes at the same time
MAX_WORKERS = 4
#: the share of a rendering's time limit its worker's own budget gets (it then answers with
#: a clear error), and the share after which it is killed (a C call that does not return)
BUDGET_SHARE = 0.6
KILL_SHARE = 0.9
#: how long a worker may take to start (a loaded machine: importing Jinja2 takes ~0.3 s)
START_TIMEOUT_S = 20.0
#: a worker whose resident memory grew by this much since it started is replaced after
#: answering (fragments of a large rendering stay with the process)
REPLACE_AFTER_GROWTH_MB = 50
#: what of the environment a worker keeps: enough for Python to find its packages
KEPT_ENVIRONMENT = ("PATH", "PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV", "LANG", "LC_ALL", "TZ")


class WorkerLimit(Exception):
    """The worker reported a limit, was killed at the deadline, or ran out of memory."""


class WorkerFailed(Exception):
    """The rendering failed (a template error, not a limit)."""


# --- the worker (child) ------------------------------------------------------------------------


def _status_kb(field: str) -> int:
    return _process_status_kb(os.getpid(), field)


def _process_status_kb(pid: int, field: str) -> int:
    try:
        with open(f"/proc/{pid}/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith(field + ":"):
                    return int(line.split()[1])
    except (OSError, ValueError):
        pass
    return 0


def _limit_memory() -> None:
    try:
        import resource
    except ImportError:  # (not on this platform: the deadline still holds)
        return
    held = _status_kb("VmSize") * 1024
    if held:
        _, hard = resource.getrlimit(resource.RLIMIT_AS)
        soft = held + MEMORY_BOUND_MB * 1024 * 1024
        if hard != resource.RLIM_INFINITY:
            soft = min(soft, hard)
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))


def _limit_cpu(limit_s: float) -> None:
    """At most a few seconds of CPU from now (counted since the worker started)."""
    try:
        import resource
    except ImportError:
        return
    usage = resource.getrusage(resource.RUSAGE_SELF)
    used = usage.ru_utime + usage.ru_stime
    _, hard = resource.getrlimit(resource.RLIMIT_CPU)
    soft = int(used + 2.0 + 2.0 * limit_s) + 1
    if hard != resource.RLIM_INFINITY:
        soft = min(soft, hard)
    resource.setrlimit(resource.RLIMIT_CPU, (soft, hard))


def serve(stdin: Any = None, stdout: Any = None) -> None:
    """The worker's loop: one JSON request a line in, one JSON answer a line out."""
    from hapticdesk.plugins.template_sandbox import (
        TemplateLimitError,
        environment,
        render_bounded,
    )

    stdin = stdin or sys.stdin
    stdout = stdout or sys.stdout
    env = environment()
    compiled: dict[str, Any] = {}
    _limit_memory()
    start_rss = _status_kb("VmRSS")
    stdout.write(json.dumps({"ready": True, "rss_kb": start_rss}) + "\n")
    stdout.flush()
    for line in stdin:
        replace = False
        try:
            request = json.loads(line)
            text = request["template"]
            limit_s = float(request["limit_s"])
            _limit_cpu(limit_s)
            template = compiled.get(text)
            if template is None:
                if len(compiled) >= 256:
                    compiled.clear()
                template = compiled[text] = env.from_string(text)
            rendered = render_bounded(
                template,
                request["variables"],
                max_steps=int(request["max_steps"]),
                limit_s=limit_s * BUDGET_SHARE,
                limit_shown_s=limit_s,
            )
            answer: dict[str, Any] = {"text": rendered}
        except TemplateLimitError as err:
            answer = {"error": str(err), "limit": True}
        except MemoryError:
            answer = {"error": f"it needs more than {MEMORY_BOUND_MB} MB", "limit": True}
            replace = True
        except RecursionError:
            answer = {"error": "it nests or recurses too deep", "limit": True}
        except Exception as err:  # the template's own failure, reported by the caller
            answer = {"error": f"{type(err).__name__}: {err}", "limit": False}
        if _status_kb("VmRSS") - start_rss > REPLACE_AFTER_GROWTH_MB * 1024:
            replace = True
        answer["replace"] = replace
        answer["peak_growth_kb"] = _status_kb("VmHWM") - start_rss  # (the most it ever held)
        stdout.write(json.dumps(answer) + "\n")
        stdout.flush()
        if replace:
            return


# --- the pool (the process that renders) -------------------------------------------------------


def _worker_environment() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k in KEPT_ENVIRONMENT}
    env["PYTHONDONTWRITEBYTECODE"] = "1"
    return env


class _Worker:
    """One worker process and its pipes."""

    def __init__(self) -> None:
        self.process = subprocess.Popen(
            [sys.executable, "-m", "hapticdesk.plugins.template_worker"],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            env=_worker_environment(),
            cwd="/",
            close_fds=True,
        )
        self._buffer = b""
        self.alive = True
        #: how far the worker's resident memory has ever grown past what it held at start
        self.peak_growth_kb = 0
        try:
            ready = self._answer(time.monotonic() + START_TIMEOUT_S)
        except (WorkerLimit, OSError):
            self.kill()
            raise OSError("the template worker did not start") from None
        if not ready.get("ready"):
            self.kill()
            raise OSError("the template worker did not start")
        self.start_rss_kb = int(ready.get("rss_kb", 0))

    def render(self, request: dict[str, Any], wait_s: float) -> str:
        """The rendered text; WorkerLimit or WorkerFailed otherwise."""
        assert self.process.stdin is not None
        deadline = time.monotonic() + wait_s
        data = (json.dumps(request, default=str) + "\n").encode("utf-8")
        try:
            self.process.stdin.write(data)
            self.process.stdin.flush()
        except OSError:
            self.kill()
            raise
        try:
            answer = self._answer(deadline)
        except WorkerLimit:
            self.kill()
            raise
        self.peak_growth_kb = int(answer.get("peak_growth_kb", 0))
        if answer.get("replace"):
            self.kill()
        if "text" in answer:
            return str(answer["text"])
        if answer.get("limit"):
            raise WorkerLimit(str(answer.get("error")))
        raise WorkerFailed(str(answer.get("error")))

    def _answer(self, deadline: float) -> dict[str, Any]:
        """The next line the worker writes, as JSON; WorkerLimit past ``deadline``."""
        assert self.process.stdout is not None
        fd = self.process.stdout.fileno()
        while b"\n" not in self._buffer:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise WorkerLimit("deadline")
            ready, _, _ = select.select([fd], [], [], remaining)
            if not ready:
                continue
            chunk = os.read(fd, 1 << 16)
            if not chunk:  # the worker died: killed by its CPU or memory limit
                self.alive = False
                raise WorkerLimit(self._death())
            self._buffer += chunk
        line, _, self._buffer = self._buffer.partition(b"\n")
        answer: dict[str, Any] = json.loads(line)
        return answer

    def _death(self) -> str:
        try:
            code = self.process.wait(1.0)
        except subprocess.TimeoutExpired:
            return "the worker stopped answering"
        if code in (-signal.SIGXCPU, -signal.SIGKILL):
            return "it used too much CPU time"
        return f"it needs more than {MEMORY_BOUND_MB} MB (the worker ended with status {code})"

    def kill(self) -> None:
        """SIGKILL; the process is reaped by a thread of its own (a worker holding 100 MB
        takes a tenth of a second to go, which the rendering that waited must not)."""
        self.alive = False
        if self.process.poll() is None:
            held = _process_status_kb(self.process.pid, "VmHWM")  # (what it took until now)
            if held and getattr(self, "start_rss_kb", 0):
                self.peak_growth_kb = max(self.peak_growth_kb, held - self.start_rss_kb)
            self.process.kill()
        for pipe in (self.process.stdin, self.process.stdout):
            try:
                if pipe is not None:
                    pipe.close()
            except OSError:
                pass
        threading.Thread(
            target=self.process.wait, name="template worker reaper", daemon=True
        ).start()


class WorkerPool:
    """Up to :data:`MAX_WORKERS` workers shared by the threads of this process; a spare one
    is started as soon as one is killed, so the next rendering does not wait for it."""

    def __init__(self, size: int = MAX_WORKERS) -> None:
        self.size = size
        self._idle: list[_Worker] = []
        self._count = 0  # workers in use, idle or starting
        self._cond = threading.Condition()
        self.unavailable: str | None = None  # why no worker could be started
        self.killed = 0  # workers killed at a deadline or a limit
        #: the most a worker's resident memory grew past its start, over every rendering
        self.peak_growth_kb = 0

    def render(
        self, text: str, variables: Mapping[str, Any], *, max_steps: int, limit_s: float
    ) -> str:
        """``text`` rendered with ``variables`` by a worker; WorkerLimit, WorkerFailed, or
        OSError when no worker can be started."""
        worker = self._take()
        request = {
            "template": text,
            "variables": dict(variables),
            "max_steps": max_steps,
            "limit_s": limit_s,
        }
        try:
            return worker.render(request, limit_s * KILL_SHARE)
        except WorkerLimit as err:
            with self._cond:
                self.killed += 1
            if str(err) == "deadline":
                raise WorkerLimit(f"it takes longer than {limit_s:g} s") from None
            raise
        finally:
            self.peak_growth_kb = max(self.peak_growth_kb, worker.peak_growth_kb)
            self._give_back(worker)

    def warm(self) -> None:
        """Start a worker in the background when none is running yet."""
        with self._cond:
            if self._count or self.unavailable is not None:
                return
            self._count += 1
        threading.Thread(target=self._start_spare, name="template worker", daemon=True).start()

    def _start_spare(self) -> None:
        try:
            worker = self._new_worker()
        except OSError:
            return
        with self._cond:
            self._idle.append(worker)
            self._cond.notify_all()

    def _new_worker(self) -> _Worker:
        """A started worker (already counted); OSError, said in :attr:`unavailable`."""
        try:
            return _Worker()
        except OSError as err:
            with self._cond:
                self._count -= 1
                self.unavailable = str(err)
                self._cond.notify_all()
            raise

    def _take(self) -> _Worker:
        with self._cond:
            while True:
                while self._idle:
                    worker = self._idle.pop()
                    if worker.alive and worker.process.poll() is None:
                        return worker
                    worker.kill()
                    self._count -= 1
                if self._count < self.size:
                    self._count += 1
                    break
                self._cond.wait(0.5)
        return self._new_worker()

    def _give_back(self, worker: _Worker) -> None:
        with self._cond:
            if worker.alive and worker.process.poll() is None:
                self._idle.append(worker)
                self._cond.notify_all()
                return
            self._count -= 1
            self._cond.notify_all()
        worker.kill()
        self.warm()  # the next rendering finds a worker ready

    def close(self) -> None:
        """Stop every idle worker (the others end when their rendering does)."""
        with self._cond:
            idle, self._idle = self._idle, []
            self._count -= len(idle)
        for worker in idle:
            worker.kill()


_POOL: WorkerPool | None = None
_POOL_LOCK = threading.Lock()


def pool() -> WorkerPool:
    """This process's pool of template workers (made on first use)."""
    global _POOL
    with _POOL_LOCK:
        if _POOL is None:
            _POOL = WorkerPool()
            import atexit

            atexit.register(_POOL.close)
        return _POOL


def _forget_pool_after_fork() -> None:
    # a forked child (an action isolated in a process) must not share the parent's pipes
    global _POOL
    _POOL = None


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_pool_after_fork)


if __name__ == "__main__":
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C goes to the run; it ends us by EOF
    serve()
