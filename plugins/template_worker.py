"""A template worker: the process a template renders in, its memory and CPU time bounded.

The sandbox (:mod:`.template_sandbox`) checks the size of everything it makes before making
it, and its budget of steps and time is checked at every loop turn and call. Neither can stop
one C call that was never foreseen: it holds the GIL until it returns, so no thread can
interrupt it (``{{ ((9**999)**999)**999 }}`` had frozen a desk for minutes, SIGTERM
ignored). So every rendering happens in a worker process (started and killed by the pool,
:mod:`.template_pool`), which bounds itself:

- its address space is limited (``RLIMIT_AS``) to what it holds after start-up plus
  :data:`MEMORY_BOUND_MB`; an allocation past it is a MemoryError, reported as a limit, and
  the worker ends so that the pool replaces it;
- its CPU time is limited (``RLIMIT_CPU``) to a few seconds past what it had used before each
  rendering, so a worker whose parent died mid-rendering does not spin on;
- its own budget is :data:`BUDGET_SHARE` of the rendering's time limit, so it answers with a
  clear error before the pool kills it.

A worker holds nothing but Jinja2 and the sandbox; it reads requests as JSON lines on stdin
and answers on stdout. Run as ``python -m hapticdesk.plugins.template_worker`` (the pool
does this).
"""

from __future__ import annotations

import json
import os
import signal
import sys
from typing import Any, TextIO

from hapticdesk.plugins.template_limits import TemplateLimitError
from hapticdesk.plugins.template_sandbox import environment, render_bounded

#: how much memory one rendering may take beyond what the worker holds when idle
MEMORY_BOUND_MB = 100
#: the share of a rendering's time limit the worker's own budget gets (it then answers with
#: a clear error; the pool kills it later)
BUDGET_SHARE = 0.6
#: a worker whose resident memory grew by this much since it started ends after answering
#: (fragments of a large rendering stay with the process)
REPLACE_AFTER_GROWTH_MB = 50
#: templates a worker keeps compiled (then it forgets them all)
MAX_COMPILED = 256


def _status_kb(field: str) -> int:
    return process_status_kb(os.getpid(), field)


def process_status_kb(pid: int, field: str) -> int:
    """A field of ``/proc/<pid>/status`` in kB (VmSize, VmRSS, VmHWM); 0 when unknown."""
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


def serve(stdin: TextIO | None = None, stdout: TextIO | None = None) -> None:
    """The worker's loop: one JSON request a line in, one JSON answer a line out."""
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
                if len(compiled) >= MAX_COMPILED:
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


if __name__ == "__main__":
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C goes to the run; it ends us by EOF
    serve()
