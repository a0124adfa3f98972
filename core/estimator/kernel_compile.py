"""How the estimator's kernel is compiled: numba's options, where its cache goes, its stamp.

Every compiled function of the kernel (:mod:`hapticdesk.estimator.kernel` and the
``kernel_*`` modules) is made with :data:`compiled`, :data:`inlined` or :data:`inlined_entry`
from here: compiled once and cached (an entry Python calls; a function only compiled code
calls is compiled with its callers, into their caches), the GIL released, IEEE division, no
reference counting (the kernel allocates nothing, and every call between its functions
otherwise paid for atomic increments of each array argument, 68 ns a call); the entries are
compiled with LLVM's SLP vectorizer on (:func:`vectorized`) and numba's negative-index
wraparound and slice clamping off (:func:`unchecked_indices`: every index of the kernel is in
range by construction), both around ``kernel.warm``.

numba stamps a cached function by the content of its own file only, while the compiled
code of an entry holds the code of the functions it calls from other files and the
constants it reads (:mod:`.kernel_slots`). So every cache made here is stamped also with
the content of all ``kernel*.py`` files of this folder: a change in any of them makes every
kernel compile anew, never a cache outliving the code it was made from. numba has no public
hook for that stamp: it is set on a private attribute of numba's cache index (the numba
versions pyproject.toml allows have it); a numba without it gets the kernels uncached,
compiled anew in every process, and a line in the log saying so.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import logging
import os
import tempfile
from collections.abc import Callable, Iterator
from typing import Any

import numba
from numba import config, njit
from numba.core import cgutils, event, types
from numba.core.compiler_lock import global_compiler_lock
from numba.misc.appdirs import AppDirs

log = logging.getLogger("hapticdesk.estimator")


def _writable(folder: str) -> bool:
    try:
        os.makedirs(folder, exist_ok=True)
        tempfile.TemporaryFile(dir=folder).close()
    except OSError:
        return False
    return True


# numba caches a compiled kernel beside this file (__pycache__) or, where that cannot be
# written (an installed package, a read-only folder), in the user's cache directory (numba's
# own choice, in that order); where neither can be, in a folder of this process's own
# (compiled once per process then), never a failure at import
if not getattr(config, "CACHE_DIR", "") and not (
    _writable(os.path.join(os.path.dirname(__file__), "__pycache__"))
    or _writable(AppDirs(appname="numba", appauthor=False).user_cache_dir)
):
    setattr(config, "CACHE_DIR", tempfile.mkdtemp(prefix="hapticdesk-kernels-"))  # noqa: B010


def _kernel_sources() -> str:
    """A digest of every ``kernel*.py`` file of this folder (the code one entry compiles)."""
    digest = hashlib.sha256()
    folder = os.path.dirname(os.path.abspath(__file__))
    for name in sorted(os.listdir(folder)):
        if name.startswith("kernel") and name.endswith(".py"):
            with open(os.path.join(folder, name), "rb") as source:
                digest.update(name.encode() + b"\0" + source.read())
    return digest.hexdigest()


KERNEL_SOURCES = _kernel_sources()


@contextlib.contextmanager
def vectorized() -> Iterator[None]:
    """LLVM's SLP vectorizer on while the kernels compile in this block (numba leaves it off
    by default since numba#8705, a miscompilation in an LLVM numba no longer ships). It packs
    the kernel's side-by-side arithmetic into vector instructions — the channels→wrench
    matrix's six sums (the map cost 47 ns a sample on the paper's desk, 25 with it), the six
    lanes of a filter — without reordering any sum: the same values to the bit
    (tests/core/test_core_golden.py)."""
    before = getattr(config, "SLP_VECTORIZE", 0)
    setattr(config, "SLP_VECTORIZE", 1)  # noqa: B010 (numba reads it as it compiles)
    try:
        yield
    finally:
        setattr(config, "SLP_VECTORIZE", before)  # noqa: B010


@contextlib.contextmanager
def unchecked_indices() -> Iterator[None]:
    """numba's negative-index wraparound and slice clamping off while the kernels compile in
    this block. Every index and slice of the kernel is in range by construction (the offsets
    params.py lays out, ring positions wrapped by hand, a -1 sentinel always tested before it
    could index), so those checks only cost: about a fifth of a sample's time on the paper's
    desk (measured, docs/performance.md), the same outputs to the bit. A slice's stop is still
    held to the length (``a[i:]``), without a branch; a negative index or slice bound would
    now read outside the array, so the kernel has none. numba has no public switch for this:
    two functions of its array lowering (``arrayobj.fix_integer_index``,
    ``slicing.fix_slice``) are swapped at the first compile in the block (a cached load
    imports none of that lowering: 0.1 s less at start-up) until its end, under numba's
    compiler lock, so no other code compiles meanwhile; a numba without them compiles with
    its checks."""
    swapped: list[tuple[Any, Any, Any, Any] | None] = []

    class _Swap(event.Listener):
        def on_start(self, ev: event.Event) -> None:
            if not swapped:
                swapped.append(_swap_index_fixes())

        def on_end(self, ev: event.Event) -> None:
            pass

    with global_compiler_lock, event.install_listener("numba:compile", _Swap()):
        try:
            yield
        finally:
            for restore in swapped:
                if restore is not None:
                    arrayobj, fix_index, slicing, fix_slice = restore
                    setattr(arrayobj, "fix_integer_index", fix_index)  # noqa: B010
                    setattr(slicing, "fix_slice", fix_slice)  # noqa: B010


def _swap_index_fixes() -> tuple[Any, Any, Any, Any] | None:
    """numba's index and slice fixes swapped for ones that assume them in range (see
    :func:`unchecked_indices`). Returns (arrayobj, its fix, slicing, its fix) to restore;
    None where this numba has neither to swap."""
    from numba.cpython import slicing  # (only when compiling: see unchecked_indices)
    from numba.np import arrayobj

    fix_index = getattr(arrayobj, "fix_integer_index", None)
    fix_slice = getattr(slicing, "fix_slice", None)
    if fix_index is None or fix_slice is None:
        return None

    def in_range_index(context: Any, builder: Any, idxty: Any, idx: Any, size: Any) -> Any:
        if not idxty.signed:
            return fix_index(context, builder, idxty, idx, size)
        return context.cast(builder, idx, idxty, types.intp)

    def in_range_slice(builder: Any, slice_: Any, size: Any) -> None:
        with builder.if_else(cgutils.is_neg_int(builder, slice_.step)) as (backwards, forwards):
            with forwards:
                for bound in ("start", "stop"):
                    value = getattr(slice_, bound)
                    over = builder.icmp_signed(">", value, size)
                    setattr(slice_, bound, builder.select(over, size, value))
            with backwards:
                fix_slice(builder, slice_, size)

    setattr(arrayobj, "fix_integer_index", in_range_index)  # noqa: B010
    setattr(slicing, "fix_slice", in_range_slice)  # noqa: B010
    return arrayobj, fix_index, slicing, fix_slice


def _stamped(options: dict[str, Any]) -> Callable[[Callable[..., Any]], Any]:
    """An njit decorator with ``options`` whose cache is stamped with :data:`KERNEL_SOURCES`
    too (numba's index keeps the stamp it was saved with and ignores a cache whose stamp
    differs; numba has no public hook for a stamp of several files, so this sets a private
    attribute of numba's cache index, ``_source_stamp``, as numba 0.60–0.68 name it). Where
    that attribute is missing (another numba), the kernels are compiled without a cache:
    every process compiles them anew, and the log says so once."""

    def decorate(function: Callable[..., Any]) -> Any:
        dispatcher = njit(**options)(function)
        index: Any = getattr(getattr(dispatcher, "_cache", None), "_cache_file", None)
        if not hasattr(index, "_source_stamp"):
            _no_stamp()
            return njit(**{**options, "cache": False})(function)
        index._source_stamp = (index._source_stamp, KERNEL_SOURCES)
        return dispatcher

    return decorate


@functools.cache
def _no_stamp() -> None:
    """Says once that the kernels are not cached (the log line of :func:`_stamped`)."""
    log.warning(
        "numba %s has no cache stamp hapticdesk can extend: the estimator's kernels are not "
        "cached and compile anew in every process (~30 s); hapticdesk is tested with the "
        "numba versions its package allows",
        numba.__version__,
    )


# compiled once and cached; the GIL released while it runs (a reader thread keeps pace); IEEE
# division (a division by zero gives inf, never an exception); no reference counting (the
# kernel allocates nothing; see the module docstring)
_OPTIONS: dict[str, Any] = {"cache": True, "nogil": True, "error_model": "numpy", "_nrt": False}
compiled = _stamped(_OPTIONS)  # an entry, called from Python: loaded from its cache
# a stage's function, inlined into its callers by LLVM and compiled with them: not cached on
# its own (its callers' caches hold its code; a cache of its own, never loaded while every
# kernel's cache is stamped alike, cost its index at every import: ~10 ms of start-up)
inlined = njit(**{**_OPTIONS, "cache": False, "forceinline": True})
inlined_entry = _stamped({**_OPTIONS, "forceinline": True})  # (inlined; Python calls it too)
