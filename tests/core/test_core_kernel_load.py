"""The cached kernels load without numba's compiler readied (issue 29, start-up): what that
leaves out, that the estimates are those of a process whose compiler was readied, and that
a compile afterwards readies it as always. Each in fresh interpreters, the kernels' cache
made warm first."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

LOAD = """
import json, sys
import numpy as np
from hapticdesk.cli import load_blas_with_one_thread
load_blas_with_one_thread()  # (as every command runs: scipy then loads its BLAS as needed)
if sys.argv[1] == "readied":
    from numba.core.registry import cpu_target
    cpu_target.target_context.refresh()
from hapticdesk.estimator import ContactEstimator
from hapticdesk.files.profile_reader import load_profile
profile = load_profile("kitamura2017")
est = ContactEstimator(profile)
loaded = [m for m in ("numba.np.linalg", "numba.np.arraymath", "scipy.linalg") if m in sys.modules]
from hapticdesk.sim import Scene, Tap, simulate  # (the simulator's own imports come after)
rec = simulate(profile, Scene([Tap(point=(0.2, 0.1), peak_n=5.0)]), seed=3)
k = len(rec.t) - 3  # a block, then the last samples one by one (the one-sample record)
block = est.push(rec.t[:k], rec.wrench[:k])
one = [est.push(rec.t[i : i + 1], rec.wrench[i : i + 1]) for i in range(k, k + 3)]
np.savez(sys.argv[2], x=block.x, y=block.y, force=block.force_n, flags=block.flags,
         contact=block.in_contact, one=np.array([o.force_n[0] for o in one]))
print(json.dumps(loaded))
"""


def _run(code: str, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-c", code, *args],
        capture_output=True,
        text=True,
        timeout=1200,
        check=True,
    )


@pytest.fixture(scope="module")
def warm_cache(tmp_path_factory: pytest.TempPathFactory) -> None:
    """The kernels compiled once into the cache these tests load from (a no-op when warm)."""
    _run(LOAD, "readied", str(tmp_path_factory.mktemp("warm") / "out.npz"))


def test_a_cached_load_leaves_the_compiler_and_scipy_linalg_out(warm_cache, tmp_path) -> None:
    done = _run(LOAD, "cached", str(tmp_path / "cached.npz"))
    # (numba's lowering rules and, through them, scipy.linalg: 0.3 s of CPU at start-up)
    assert json.loads(done.stdout.splitlines()[-1]) == []


def test_the_estimates_equal_those_of_a_readied_compiler(warm_cache, tmp_path) -> None:
    readied = _run(LOAD, "readied", str(tmp_path / "readied.npz"))
    assert "numba.np.arraymath" in json.loads(readied.stdout.splitlines()[-1])
    _run(LOAD, "cached", str(tmp_path / "cached.npz"))
    a, b = np.load(tmp_path / "readied.npz"), np.load(tmp_path / "cached.npz")
    assert a["contact"].any(), "the tap was not seen: the comparison would say little"
    for name in a.files:
        np.testing.assert_array_equal(a[name], b[name], err_msg=name)


COMPILE_AFTER = """
import json
import numpy as np
from numba import njit
from hapticdesk.estimator import kernel
kernel.warm()
# a compile in the same process, after the cached load: it needs the lowering rules (and
# np.dot its BLAS), which numba's compiler readies itself
print(json.dumps(float(njit(lambda a: np.dot(a, a))(np.arange(4.0)))))
"""


def test_a_compile_after_the_cached_load_readies_the_compiler(warm_cache) -> None:
    done = _run(COMPILE_AFTER)
    assert json.loads(done.stdout.splitlines()[-1]) == 14.0


LINK_AFTER = """
import json
from numba import njit
from hapticdesk.estimator import kernel, kernel_geometry
from hapticdesk.estimator.params import params_of
from hapticdesk.estimator.settings import EstimatorSettings
from hapticdesk.files.profile_reader import load_profile
kernel.warm()  # (contains among the entries loaded without their bitcode for linking)
profile = load_profile("kitamura2017")
params = params_of(EstimatorSettings.of(profile, profile.estimation, False), None)

@njit
def calls(pf, pi, surface, u, v):  # (the types contains was loaded for: it is linked in)
    return kernel_geometry.contains(pf, pi, surface, u, v)

points = [(0.1, 0.1), (5.0, 5.0)]
print(json.dumps([
    [calls(params.pf, params.pi, 0, u, v), kernel_geometry.contains(params.pf, params.pi, 0, u, v)]
    for u, v in points
]))
print(json.dumps([str(s) for s in kernel_geometry.contains.signatures]))
"""


def test_a_compile_that_calls_a_loaded_kernel_links_it_in(warm_cache) -> None:
    """A kernel loaded without its bitcode for linking (cached_load) is linked into a later
    compile that calls it: the bitcode is parsed when that compile starts."""
    done = _run(LINK_AFTER)
    results, signatures = (json.loads(line) for line in done.stdout.splitlines()[-2:])
    assert results == [[True, True], [False, False]]
    assert len(signatures) == 1, signatures  # (the loaded one was called, not a new one)
