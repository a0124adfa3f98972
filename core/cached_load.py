"""Compiled functions (the estimator's kernels, the CSV reader's parser) loaded from numba's
cache without readying numba's compiler, and without the code other compiles would link
against. Such a function is compiled without numba's runtime (``_nrt=False``) and with
``error_model="numpy"``, as the kernels are: one compiled with numba's defaults crashed the
process when loaded this way ("Symbol not found: NRT_MemInfo_call_dtor": the runtime is
linked in by the readying left out).

Before numba loads a cached function it readies its whole compiler
(``BaseContext.refresh``): it imports every module of typing and lowering rules (``numba.np``,
``numba.cpython``…) and installs their registries, and one of them imports ``scipy.linalg``
only to learn whether ``np.dot`` could call BLAS. A cached kernel needs none of it: its machine
code is loaded as it was saved and called with the argument types it was compiled for. That
readying was 0.33 s of CPU of the 0.36 s the kernels' cached load took (0.17 s without
``scipy.linalg``), a quarter of ``hapticdesk contacts`` on a minute of data
(docs/performance.md).

Beside its machine code, numba's cache holds each function's LLVM bitcode, whole, for a
later compile that calls the function to link it in; loading parses it (``parse_bitcode``)
and walks its symbols, three quarters of a cached load's time (the estimator's entries,
0.4 MB of bitcode each: 35 of 45 ms). The kernels are called from Python, never linked into
other code, so :func:`cache_loads` keeps the bitcode unparsed, marks only the loaded
function's own two symbols as defined (numba looks a function's address up by them), and
parses it should a compile start in this process, before that compile could link anything
(:class:`_LinkOnCompile`; numba announces a dispatcher's compile, not a ``@cfunc``'s: one
calling a kernel loaded so would be refused by numba as "unfit for linking", and none does).

Should a kernel miss the cache and be compiled, numba's compiler is readied first and its
own load is back (numba's ``numba:compile`` event comes before any compile starts, and the
functions a compile calls are linked in whole), and numba's compiler readies its
contexts itself on each compile, so a compile in this process, now or later, runs as it
always does. A numba without the private parts used here loads as numba does.
"""

from __future__ import annotations

import weakref
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import llvmlite.binding as llvm
from numba.core import event
from numba.core.compiler_lock import global_compiler_lock
from numba.core.registry import cpu_target


class _RestoreOnCompile(event.Listener):
    """Gives the target context and its code generator their own methods back when a
    compile starts (the functions it calls load from the cache as numba loads them: it
    links them in)."""

    def __init__(self, context: object) -> None:
        self.context = context

    def on_start(self, event: event.Event) -> None:
        _restore(self.context)

    def on_end(self, event: event.Event) -> None:
        pass


def _restore(context: Any) -> None:
    for name in ("refresh", "get_executable"):
        context.__dict__.pop(name, None)  # (the class's method shows through again)
    context.codegen().__dict__.pop("unserialize_library", None)


def _not_yet() -> None:
    """Stands for ``refresh`` while cached kernels load: they need no typing or lowering
    rules."""


class _LinkOnCompile(event.Listener):
    """Parses the bitcode of the libraries loaded without it when a compile starts (it
    could link one of them in), as numba's own load would have (registered once, for every
    compile of the process)."""

    def __init__(self, codegen: Any) -> None:
        self.codegen = codegen
        self.waiting: list[tuple[weakref.ref[Any], bytes]] = []

    def on_start(self, event: event.Event) -> None:
        waiting, self.waiting = self.waiting, []
        for library_ref, bitcode in waiting:
            library = library_ref()
            if library is not None:
                library._shared_module = llvm.parse_bitcode(bitcode)
                self.codegen._engine._load_defined_symbols(library._shared_module)

    def on_end(self, event: event.Event) -> None:
        pass


_linking: list[_LinkOnCompile] = []  # (the one listener, once registered)


def _unlinked_loads(codegen: Any) -> Callable[[Any], Any] | None:
    """numba's ``unserialize_library`` of ``codegen`` without the bitcode for linking (see
    the module docstring); None where this numba lacks a part it needs."""
    parts = (
        getattr(codegen, "create_library", None),
        getattr(getattr(codegen, "_engine", None), "_defined_symbols", None),
    )
    if any(part is None for part in parts):
        return None
    if not _linking:
        _linking.append(_LinkOnCompile(codegen))
        event.register("numba:compile", _linking[0])
    waiting = _linking[0].waiting
    numba_load = codegen.unserialize_library

    def load(serialized: Any) -> Any:
        name, kind, data = serialized
        library = codegen.create_library(name)
        if kind != "object" or not hasattr(library, "_set_compiled_object"):
            return numba_load(serialized)
        object_code, bitcode = data
        library.enable_object_caching()
        library._set_compiled_object(object_code)
        library._finalize_final_module()  # (its machine code linked into the process)
        waiting.append((weakref.ref(library), bitcode))
        return library

    return load


def _defining(context: Any, codegen: Any) -> Callable[[Any, Any, Any], Any]:
    """numba's ``get_executable`` of ``context``, the loaded function's symbols marked
    defined first (numba gives an address only for a symbol it knows to be defined)."""
    numba_executable = context.get_executable
    defined = codegen._engine._defined_symbols

    def executable(library: Any, fndesc: Any, env: Any) -> Any:
        defined.update((fndesc.llvm_func_name, fndesc.llvm_cpython_wrapper_name))
        return numba_executable(library, fndesc, env)

    return executable


@contextmanager
def cache_loads() -> Iterator[None]:
    """Within: numba loads cached functions without readying its compiler first (a compile
    still readies it) and without parsing their bitcode for linking (a compile parses it).
    Holds numba's compiler lock, so no other thread compiles meanwhile."""
    context = cpu_target.target_context
    codegen = context.codegen()
    with global_compiler_lock, event.install_listener("numba:compile", _RestoreOnCompile(context)):
        context.refresh = _not_yet
        load = _unlinked_loads(codegen)
        if load is not None:
            codegen.unserialize_library = load
            context.get_executable = _defining(context, codegen)
        try:
            yield
        finally:
            _restore(context)
