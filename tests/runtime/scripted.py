"""Runs for the runtime tests: a layout over a recording, with calls made on the sensing thread
at chosen sample times (the control tests' :class:`ScriptedSource`), and the process's memory."""

from __future__ import annotations

import json
from collections.abc import Callable
from concurrent.futures import Future
from pathlib import Path
from types import SimpleNamespace
from typing import Any

from hapticdesk.files.recording import Recording
from hapticdesk.hookspecs import hookimpl
from hapticdesk.plugin_loading import load_registry
from hapticdesk.runtime.assembly import build_scene
from hapticdesk.runtime.service import Runtime

from .test_runtime_control import ScriptedSource


def scripted_run(
    layout: Path,
    recording: Recording,
    script: dict[float, Callable[[Runtime], Any]],
    events_path: Path,
    **runtime_options: Any,
) -> tuple[Runtime, list[dict[str, Any]]]:
    """Run ``layout`` over ``recording`` as fast as it goes; ``script`` maps a sample time to
    ``f(runtime)``, called on the sensing thread before the first block at or after it.
    Returns the runtime and the events written (the run must end without an error)."""
    holder: dict[str, Runtime] = {}
    source = ScriptedSource(
        recording, {t: (lambda f=f: f(holder["rt"])) for t, f in script.items()}
    )
    plugin = SimpleNamespace(
        register_sources=hookimpl(
            lambda register: register("scripted", lambda argument, profile, **o: source)
        )
    )
    registry = load_registry(entry_points=False, plugins=[("scripted", plugin)])
    scene = build_scene(layout, "scripted:", registry, speed=0)
    runtime = holder["rt"] = Runtime(scene, events_path=events_path, **runtime_options)
    assert runtime.run(handle_signals=False).error is None
    events = [json.loads(line) for line in events_path.read_text().splitlines()]
    return runtime, events


def answer_into(answers: list[str]) -> Callable[[Future[str]], None]:
    """A future's callback appending its result, or its error's text, to ``answers``."""

    def done(future: Future[str]) -> None:
        error = future.exception()
        answers.append(str(error) if error is not None else future.result())

    return done


def rss_kb() -> int:
    """This process's resident memory, kB."""
    with open("/proc/self/status", encoding="ascii") as fh:
        for line in fh:
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    return 0
