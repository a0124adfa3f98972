"""The pool of template workers: renderings in processes the desk can kill.

Every rendering of a template happens in a worker process (:mod:`.template_worker`), so that
one C call nobody foresaw cannot hold the desk: the process that asked waits
:data:`KILL_SHARE` of the rendering's time limit for the answer, then kills the worker
(SIGKILL) and says the template took too long; a fresh worker is started at once for the next
rendering. Workers are started with an environment stripped to what Python needs (no tokens
or passwords of the desk's). A pool of up to :data:`MAX_WORKERS` serves the threads of a run
(dispatcher lanes render at once); where no worker can be started, templates render in this
process (the sandbox's own bounds only), which the log says once (:mod:`.templating`).
"""

from __future__ import annotations

import json
import os
import select
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Mapping
from typing import Any

from hapticdesk.plugins.template_limits import TemplateError, TemplateLimitError
from hapticdesk.plugins.template_worker import MEMORY_BOUND_MB, process_status_kb

#: workers at most: renderings of different lanes at the same time
MAX_WORKERS = 4
#: the share of a rendering's time limit after which its worker is killed (a C call that does
#: not return; the worker's own budget ends earlier, :data:`.template_worker.BUDGET_SHARE`)
KILL_SHARE = 0.9
#: how long a worker may take to start (a loaded machine: importing Jinja2 takes ~0.3 s)
START_TIMEOUT_S = 20.0
#: what of the environment a worker keeps: enough for Python to find its packages
KEPT_ENVIRONMENT = ("PATH", "PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV", "LANG", "LC_ALL", "TZ")


class _PastDeadline(Exception):
    """The worker did not answer in time."""


def _worker_environment() -> dict[str, str]:
    """What of this process's environment a worker starts with (no secrets of the desk's)."""
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
        except (_PastDeadline, TemplateLimitError, OSError):
            self.kill()
            raise OSError("the template worker did not start") from None
        if not ready.get("ready"):
            self.kill()
            raise OSError("the template worker did not start")
        self.start_rss_kb = int(ready.get("rss_kb", 0))

    def render(self, request: dict[str, Any], wait_s: float) -> str:
        """The rendered text; TemplateLimitError or TemplateError (the worker's answer),
        _PastDeadline (the worker is killed) otherwise."""
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
        except (_PastDeadline, TemplateLimitError):
            self.kill()
            raise
        self.peak_growth_kb = int(answer.get("peak_growth_kb", 0))
        if answer.get("replace"):
            self.kill()
        if "text" in answer:
            return str(answer["text"])
        if answer.get("limit"):
            raise TemplateLimitError(str(answer.get("error")))
        raise TemplateError(str(answer.get("error")))

    def _answer(self, deadline: float) -> dict[str, Any]:
        """The next line the worker writes, as JSON; _PastDeadline past ``deadline``,
        TemplateLimitError when the worker died (its CPU or memory limit)."""
        assert self.process.stdout is not None
        fd = self.process.stdout.fileno()
        while b"\n" not in self._buffer:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise _PastDeadline
            ready, _, _ = select.select([fd], [], [], remaining)
            if not ready:
                continue
            chunk = os.read(fd, 1 << 16)
            if not chunk:  # the worker died: killed by its CPU or memory limit
                self.alive = False
                raise TemplateLimitError(self._death())
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
            held = process_status_kb(self.process.pid, "VmHWM")  # (what it took until now)
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
        """``text`` rendered with ``variables`` by a worker; TemplateLimitError past the
        limits (the worker killed at ``limit_s``), TemplateError when the template fails, or
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
        except _PastDeadline:
            with self._cond:
                self.killed += 1
            raise TemplateLimitError(f"it takes longer than {limit_s:g} s") from None
        except TemplateLimitError:
            with self._cond:
                self.killed += 1
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
