"""Compiled functions (the estimator's kernels, the CSV reader's parser) loaded from numba's
cache without readying numba's compiler. Such a function is compiled without numba's runtime
(``_nrt=False``) and with ``error_model="numpy"``, as the kernels are: one compiled with
numba's defaults crashed the process when loaded this way ("Symbol not found:
NRT_MemInfo_call_dtor": the runtime is linked in by the readying left out).

Before numba loads a cached function it readies its whole compiler
(``BaseContext.refresh``): it imports every module of typing and lowering rules (``numba.np``,
``numba.cpython``…) and installs their registries, and one of them imports ``scipy.linalg``
only to learn whether ``np.dot`` could call BLAS. A cached kernel needs none of it: its machine
code is loaded as it was saved and called with the argument types it was compiled for. That
readying was 0.33 s of CPU of the 0.36 s the kernels' cached load took (0.17 s without
``scipy.linalg``), a quarter of ``hapticdesk contacts`` on a minute of data
(docs/performance.md).

:func:`cache_loads` leaves it out while the kernels load. Should a kernel miss the cache and
be compiled, it is restored first (numba's ``numba:compile`` event comes before any compile
starts), and numba's compiler readies its contexts itself on each compile, so a compile in
this process, now or later, runs as it always does.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

from numba.core import event
from numba.core.compiler_lock import global_compiler_lock
from numba.core.registry import cpu_target


class _RestoreOnCompile(event.Listener):
    """Gives the target context its own ``refresh`` back when a compile starts."""

    def __init__(self, context: object) -> None:
        self.context = context

    def on_start(self, event: event.Event) -> None:
        _restore(self.context)

    def on_end(self, event: event.Event) -> None:
        pass


def _restore(context: object) -> None:
    context.__dict__.pop("refresh", None)  # (the class's method shows through again)


def _not_yet() -> None:
    """Stands for ``refresh`` while cached kernels load: they need no typing or lowering
    rules."""


@contextmanager
def cache_loads() -> Iterator[None]:
    """Within: numba loads cached functions without readying its compiler first (a compile
    still readies it). Holds numba's compiler lock, so no other thread compiles meanwhile."""
    context = cpu_target.target_context
    with global_compiler_lock, event.install_listener("numba:compile", _RestoreOnCompile(context)):
        context.refresh = _not_yet
        try:
            yield
        finally:
            _restore(context)
