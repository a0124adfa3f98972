"""How the estimator's kernel is compiled: numba's options, where its cache goes, its stamp.

Every compiled function of the kernel (:mod:`hapticdesk.estimator.kernel` and the
``kernel_*`` modules) is made with :data:`compiled` or :data:`inlined` from here: compiled
once and cached, the GIL released, IEEE division, no reference counting (the kernel
allocates nothing, and every call between its functions otherwise paid for atomic
increments of each array argument, 68 ns a call); the entries are compiled with LLVM's SLP
vectorizer on (:func:`vectorized`, around ``kernel.warm``).

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
compiled = _stamped(_OPTIONS)
inlined = _stamped({**_OPTIONS, "forceinline": True})  # (into its callers, by LLVM)
