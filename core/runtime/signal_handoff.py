"""Signals answered off their handler: a thread of its own does what a signal asks.

A Python signal handler runs in the main thread between two of its bytecodes, wherever that
thread is. One that stops a run by setting a ``threading.Event`` (or closing a source, taking
a queue's lock) takes a lock the interrupted code may hold at that moment, in the Event's own
``wait``: the lock is never released and the process hangs for good, deaf to any further
Ctrl-C or kill (``emulate --serial`` did, in a test; a loop of 100 signals into such a wait
hung 3 of 3 runs). Raising from the handler can leave the lock taken alike. So the handlers
here do nothing but let Python's C-level handler write the signal's number to a pipe
(``signal.set_wakeup_fd``), and a watcher thread reads it and calls the work for it, where
taking a lock only waits for the main thread to let it go.
"""

from __future__ import annotations

import contextlib
import os
import signal
import threading
from collections.abc import Callable, Iterator, Mapping
from types import FrameType

#: what a signal asks for, called in the watcher thread with the signal's number
Work = Callable[[int], None]


def _nothing(_signum: int, _frame: FrameType | None) -> None:
    """The Python handler: none needed (its C side writes the number to the wakeup pipe)."""


@contextlib.contextmanager
def signals_handed_off(work: Mapping[signal.Signals, Work]) -> Iterator[None]:
    """While the block runs, each signal of ``work`` calls its work in a watcher thread
    (``work[signum](signum)``), once per signal received. Only the main thread can set
    handlers: from another, the block runs without them (its caller stops it)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    read_end, write_end = os.pipe()
    os.set_blocking(write_end, False)  # (a full pipe drops a signal, never blocks a handler)
    previous_fd = signal.set_wakeup_fd(write_end, warn_on_full_buffer=False)
    previous = {s: signal.signal(s, _nothing) for s in work}
    watcher = threading.Thread(
        target=_watch, args=(read_end, work), name="hapticdesk-signals", daemon=True
    )
    watcher.start()
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
        signal.set_wakeup_fd(previous_fd)
        os.close(write_end)  # (the watcher reads the end of the pipe and returns)
        watcher.join(timeout=5.0)
        os.close(read_end)


def _watch(read_end: int, work: Mapping[signal.Signals, Work]) -> None:
    """Reads the signals' numbers until the pipe closes; calls each one's work."""
    wanted = {int(s): w for s, w in work.items()}
    while True:
        try:
            numbers = os.read(read_end, 64)
        except OSError:
            return
        if not numbers:
            return
        for number in numbers:
            if number in wanted:
                wanted[number](number)
