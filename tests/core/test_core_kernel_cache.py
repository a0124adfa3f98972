"""Where the estimator's compiled kernels come from (issue 29 item 4): numba is imported only
where estimation happens; the compiled kernels are cached beside the package, or in the
user's cache directory when the package's folder cannot be written; the first compile says
so once on stderr. Checked in fresh interpreters, by what they import and print."""

from __future__ import annotations

import logging
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
MESSAGE = "compiling the estimator's kernels, once"

PROBE = """
import contextlib, io, json, sys
from hapticdesk.cli import main
out = io.StringIO()
with contextlib.redirect_stdout(out), contextlib.redirect_stderr(out):
    try:
        main({argv!r})
    except SystemExit:
        pass
print(json.dumps([m for m in ("numba", "llvmlite") if m in sys.modules]))
"""


@pytest.mark.parametrize(
    "argv",
    [
        ["--help"],
        ["check", str(ROOT / "examples" / "layouts" / "buttons.yaml")],
        ["strokes", "classify", str(ROOT / "examples" / "strokes")],
    ],
    ids=["help", "check", "strokes"],
)
def test_commands_that_do_not_estimate_never_import_numba(argv: list[str], python_probe) -> None:
    assert python_probe(PROBE.format(argv=argv)) == []


def test_numba_loads_with_the_estimator_not_with_its_package(python_probe) -> None:
    code = """
import json, sys
import hapticdesk.estimator, hapticdesk.estimator.contacts, hapticdesk.gestures.engine
before = [m for m in ("numba", "scipy.signal") if m in sys.modules]
from hapticdesk.estimator import ContactEstimator
from hapticdesk.files.profile_reader import load_profile
ContactEstimator(load_profile("kitamura2017"))
print(json.dumps([before, "numba" in sys.modules, "scipy.signal" in sys.modules]))
"""
    # (an estimator's filters are designed without scipy.signal: over a second of start-up)
    assert python_probe(code, timeout=600) == [[], True, False]


ESTIMATE = """
import sys, time
import numpy as np
import hapticdesk
assert hapticdesk.__file__.startswith(sys.argv[1]), hapticdesk.__file__
from hapticdesk.estimator import ContactEstimator
from hapticdesk.files.profile_reader import load_profile
start = time.perf_counter()
est = ContactEstimator(load_profile(sys.argv[2]))
block = est.push(np.arange(10) / 1200.0, np.zeros((10, 4, 6)))
print(len(block), time.perf_counter() - start)
"""


@pytest.mark.slow
def test_a_read_only_package_caches_its_kernels_in_the_user_cache(tmp_path: Path) -> None:
    """A copy of the package whose folder cannot be written (its ``__pycache__`` a file, as
    root can write anywhere): numba's in-tree cache fails over to the user's cache directory
    (XDG_CACHE_HOME), where the second run finds the kernels: only the first compiles, and
    says so once."""
    package = tmp_path / "site" / "hapticdesk"
    shutil.copytree(
        ROOT / "core", package, ignore=shutil.ignore_patterns("__pycache__", "*.pyc", "*.nb*")
    )
    (package / "estimator" / "__pycache__").write_text("not a folder")
    for folder in (package / "estimator", package):
        folder.chmod(0o555)
    env = {
        **os.environ,
        "PYTHONPATH": str(tmp_path / "site"),
        "XDG_CACHE_HOME": str(tmp_path / "cache"),
    }
    env.pop("NUMBA_CACHE_DIR", None)
    profile = str(ROOT / "profiles" / "kitamura2017.yaml")

    def run() -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            [sys.executable, "-c", ESTIMATE, str(package), profile],
            capture_output=True,
            text=True,
            timeout=1200,
            env=env,
            check=True,
        )

    try:
        first, second = run(), run()
    finally:
        for folder in (package, package / "estimator"):
            folder.chmod(0o755)
    assert first.stderr.count(MESSAGE) == 1, first.stderr
    assert MESSAGE not in second.stderr, second.stderr
    cached = list((tmp_path / "cache" / "numba").rglob("kernel.run_block-*.nbi"))
    assert cached, "no kernel cached in the user's cache directory"
    assert first.stdout.split()[0] == second.stdout.split()[0] == "10"
    assert float(second.stdout.split()[1]) < float(first.stdout.split()[1])


WARM = """
import sys
import hapticdesk
assert hapticdesk.__file__.startswith(sys.argv[1]), hapticdesk.__file__
from hapticdesk.estimator import kernel
kernel.warm()
"""


@pytest.mark.slow
def test_a_change_in_any_kernel_module_compiles_the_kernels_anew(tmp_path: Path) -> None:
    """numba stamps a cache by its own function's file only, while an entry (kernel.py)
    holds the code and the frozen constants of the other kernel modules: a change in one of
    them (here kernel_slots.py, then a stage's module, kernel_multitouch.py) must not load
    the entries' stale cache."""
    package = tmp_path / "site" / "hapticdesk"
    shutil.copytree(
        ROOT / "core", package, ignore=shutil.ignore_patterns("__pycache__", "*.pyc", "*.nb*")
    )
    env = {**os.environ, "PYTHONPATH": str(tmp_path / "site")}
    env.pop("NUMBA_CACHE_DIR", None)

    def warm() -> str:
        return subprocess.run(
            [sys.executable, "-c", WARM, str(package)],
            capture_output=True,
            text=True,
            timeout=1200,
            env=env,
            check=True,
        ).stderr

    assert warm().count(MESSAGE) == 1
    assert MESSAGE not in warm()
    for module in ("kernel_slots.py", "kernel_multitouch.py"):
        source = package / "estimator" / module
        source.write_text(source.read_text() + "# changed\n")
        assert warm().count(MESSAGE) == 1, module
        assert MESSAGE not in warm(), module


def _twice(x: float) -> float:
    return 2.0 * x


def test_the_kernels_cache_is_stamped_with_every_kernel_module() -> None:
    """On the numba versions pyproject.toml allows, every kernel's cache index carries the
    digest of all kernel*.py files beside numba's own stamp (a numba without that private
    attribute fails here first)."""
    from hapticdesk.estimator import kernel, kernel_compile, kernel_geometry

    for dispatcher in (kernel.run_block, kernel.intersect_block, kernel_geometry.contains):
        stamp = dispatcher._cache._cache_file._source_stamp
        assert stamp[1] == kernel_compile.KERNEL_SOURCES
    # the digest covers the files named kernel*.py: every module compiled through
    # kernel_compile must be one of them
    compiling = [
        path.name
        for path in Path(kernel_compile.__file__).parent.glob("*.py")
        if "kernel_compile import" in path.read_text(encoding="utf-8")
    ]
    assert len(compiling) >= 9
    assert all(name.startswith("kernel") for name in compiling), compiling


def test_a_numba_without_the_cache_stamp_compiles_the_kernels_uncached(
    monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """Another numba whose cache index has no ``_source_stamp``: the kernels still compile,
    without a cache (never one that could outlive a change of their code), and the log says
    so once."""
    from numba.core import caching

    from hapticdesk.estimator import kernel_compile

    made = caching.IndexDataCacheFile.__init__

    def without_stamp(self: object, *args: object, **kwargs: object) -> None:
        made(self, *args, **kwargs)
        del self._source_stamp  # type: ignore[attr-defined]

    monkeypatch.setattr(caching.IndexDataCacheFile, "__init__", without_stamp)
    kernel_compile._no_stamp.cache_clear()
    with caplog.at_level(logging.WARNING, logger="hapticdesk.estimator"):
        compiled = kernel_compile.compiled(_twice)
        inlined = kernel_compile.inlined_entry(_twice)
    kernel_compile._no_stamp.cache_clear()
    assert compiled(2.5) == inlined(2.5) == 5.0
    for dispatcher in (compiled, inlined):
        assert isinstance(dispatcher._cache, caching.NullCache)
    told = [r for r in caplog.records if "not cached" in r.getMessage()]
    assert len(told) == 1, caplog.text


def test_indices_go_unchecked_only_while_the_kernels_compile() -> None:
    """kernel_compile.unchecked_indices: numba's wraparound of a negative index is off for what
    compiles inside the block (the kernel's indices are never negative) and back for what
    compiles after it, in the same process."""
    import numpy as np
    from numba import njit

    from hapticdesk.estimator.kernel_compile import unchecked_indices

    def at(a: np.ndarray, i: int) -> float:
        return a[i]

    whole = np.arange(5.0)
    view = whole[1:]  # (so that the element before the view's first one is the array's)
    with unchecked_indices():
        inside = njit(at)
        assert inside(view, 2) == 3.0
        assert inside(view, -1) == 0.0  # not wrapped: the element before the view
    after = njit(lambda a, i: a[i])
    assert after(view, -1) == 4.0  # wrapped again: the view's last element
