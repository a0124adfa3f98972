"""The estimator's per-sample work, compiled (numba): one function over flat arrays, one loop.

Every sample goes through :func:`~hapticdesk.estimator.kernel_sample._sample` once, whether it
came in a block of a million or alone, through the one compiled loop :func:`run_block`
(here): a push of many samples writes into preallocated output columns, a push of one sample
into a reused one-sample record (the estimator's two ways in, ``ContactEstimator._run`` and
``_step``). So streaming equals batch by construction: the same machine code runs both. (A
second compiled entry for one sample cost a sixth of the first compile, 6.6 s of CPU, and
its load at every process's start-up, to save 0.2 µs of a single push's 3:
docs/performance.md.) This module holds the entry, the argument types it is compiled for
and :func:`warm`; the stages are in the ``kernel_*`` modules of this folder.

The arrays (built once per estimator by :mod:`hapticdesk.estimator.params`):

- ``pf`` (float64) and ``pi`` (int64), the **parameters**: the desk's settings flattened once
  (the channels→wrench matrix, the channels' limits, the filters' sections, the surfaces, the
  thresholds). The ``P_*`` and ``I_*`` names (:mod:`.kernel_slots`) are their fixed slots;
  desk-sized parts sit at offsets stored in ``pi`` (``I_PO_*`` into ``pf``,
  ``I_SO_*``/``I_JO_*`` into the state).
- ``sf`` (float64) and ``si`` (int64), the **state**: filter memories, delay rings, the
  current zero, the window being filled, the detector's and the second-finger stage's
  state. ``S_*`` and ``J_*`` name the fixed slots. A snapshot is a copy of both; a re-tare
  resets slices of them.
- ``out_f`` (float64, rows ``OUT_*``), ``out_b`` (int8, rows ``OUT_B_*``: the booleans and
  small codes) and ``out_s`` (int16, the surface): the output columns, one per sample.

What happens rarely leaves the loop as an **event**: ``_sample`` returns the ``EV_*``
bits it raised, the entry returns them with the sample's index in ``si[J_EVENT_AT]``, and
Python (:class:`hapticdesk.estimator.contact_estimator.ContactEstimator`) handles them — a
notice, a zero window's end before the tare (the tare is taken there; after it the kernel
judges every window itself and leaves only an object absorbed or lifted, to be told), the
covariances made anew, the second finger's fit, the stray it learns at a
contact's end, the gain of partial accelerometer readings — then calls the entry again from
where ``si[J_RESUME]`` says: the next sample, the second half of the same one (new
covariances are used by the sample whose reading brought them), or the same one again
(the gain of its pattern of usable readings is ready, and kept for the next sample alike).

The stages, in the order a sample meets them (:mod:`.kernel_sample` runs them; each module
cites the paper's equations it follows), one module each: bad samples and the
channels→wrench matrix (eqs. 1–4) with the resolution steps learned (:mod:`.kernel_channels`);
the accelerometers' inertial wrench (:mod:`.kernel_inertia`); the filter bank, second-order
sections, the n-sample pseudo-difference of eq. 8, the fast 30 Hz path and the sway
(:mod:`.kernel_filters`); the window of the zero (:mod:`.kernel_zero`); the detector
(:mod:`.kernel_detector`); the candidates with their covariances (eqs. 5, 11, 12, on the
surfaces of :mod:`.kernel_geometry`) and the methods (force, diff, switched = Fig. 3, fused:
:mod:`.kernel_methods`); the second finger (:mod:`.kernel_multitouch`). Each stage's Python
side (its settings, its notices, what it decides at an event) is in the module of its name
without the ``kernel_`` (``detector.py``, ``multitouch.py``…).

The desk-sized regions are read through views taken once per call (``pf[at : at + n]``):
indexed from zero, their loops compile to plain array walks, where an offset index would keep
LLVM from proving it non-negative (measured: the channel checks took 107 ns a sample with
offsets, 20 with views). Compiled without numba's reference counting and with its helpers inlined
into the entries (:mod:`.kernel_compile`).

The fixed slots and codes (``P_*``, ``I_*``, ``S_*``, ``J_*``, ``OUT_*``, ``EV_*``…) are in
:mod:`.kernel_slots`; how the kernel is compiled and its cache stamped (with every
``kernel*.py`` file, so a cache never outlives a change of the code it was made from) in
:mod:`.kernel_compile`. (The ``FLAG_*``, ``SOURCE_*`` and ``PHASE_*`` codes come from
:mod:`.contacts`: they are contracts and never change.)
"""

from __future__ import annotations

import logging
import sys
import time
from typing import Any

import numpy as np
from numba import types
from numba.core import event

from hapticdesk.cached_load import cache_loads
from hapticdesk.estimator.kernel_channels import keep_row, steps_changed, wrench_of
from hapticdesk.estimator.kernel_compile import compiled, unchecked_indices, vectorized
from hapticdesk.estimator.kernel_geometry import contains, intersect
from hapticdesk.estimator.kernel_rounding import likeliest_noise
from hapticdesk.estimator.kernel_sample import _sample
from hapticdesk.estimator.kernel_slots import EV_PARTIAL_ACCEL, I_C, I_SO_PREV_ROW, J_EVENT_AT
from hapticdesk.estimator.kernel_yardsticks import tare_yardsticks

# --- the loop, and the intersection over arrays ---------------------------------------------


@compiled
def run_block(
    t: np.ndarray,
    x: np.ndarray,
    accel: np.ndarray,
    given: bool,
    pf: np.ndarray,
    pi: np.ndarray,
    sf: np.ndarray,
    si: np.ndarray,
    out_f: np.ndarray,
    out_b: np.ndarray,
    out_s: np.ndarray,
    start: int,
    stop: int,
) -> int:
    """Samples ``start`` to ``stop`` of a push (``t`` (k,), ``x`` (k, C), ``accel`` (k, A),
    used if ``given``) into the output columns of the same index; stops at the first
    sample that raises an event, its index in si[J_EVENT_AT]. Returns the events (0: the
    push is done). Releases the GIL."""
    kept = sf[pi[I_SO_PREV_ROW] : pi[I_SO_PREV_ROW] + pi[I_C]]
    # each sample's wrench made one sample ahead: the map depends on nothing before it, so
    # its chain of sums runs beside the sample before instead of ahead of this one's filters
    ahead = wrench_of(x[start], pf, pi) if start < stop else (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    for i in range(start, stop):
        mapped = ahead
        if i + 1 < stop:
            ahead = wrench_of(x[i + 1], pf, pi)
        a = accel[i if given else 0]
        before = x[i - 1] if i > start else kept  # (the sample before: keep_row)
        events = _sample(
            t[i], x[i], before, mapped, a, given, pf, pi, sf, si, out_f, out_b, out_s, i
        )
        if events:
            si[J_EVENT_AT] = i
            # (a sample that asks for its accelerometers' gain is not checked yet)
            keep_row(x, i - 1 if events & EV_PARTIAL_ACCEL else i, start, pi, sf)
            return events
    keep_row(x, stop - 1, start, pi, sf)
    return 0


@compiled
def intersect_block(
    pf: np.ndarray,
    pi: np.ndarray,
    wrench: np.ndarray,
    sign: np.ndarray,
    covs: np.ndarray,
    cov_at: int,
    drift_at: int,
    age2: np.ndarray,
    extra_var: np.ndarray,
    norm: np.ndarray,
    out: np.ndarray,
) -> None:
    """:func:`intersect` for the wrenches (n, 6) one by one, into ``out`` (n, 6): surface,
    u, v, var_u, var_v, cov_uv (for intersection.intersect, the same code the kernel runs)."""
    for i in range(wrench.shape[0]):
        c = intersect(
            pf, pi, wrench[i], 0, sign[i], covs, cov_at, drift_at, age2[i], extra_var[i], norm[i]
        )
        out[i, 0], out[i, 1], out[i, 2], out[i, 3], out[i, 4], out[i, 5] = c[:6]


# --- compiled once --------------------------------------------------------------------------

#: how long the first compile took on the machine of docs/performance.md (a cached load:
#: well under a second); said once on stderr while it runs
FIRST_COMPILE_S = 30
log = logging.getLogger("hapticdesk.estimator")
_warm = False


def _signatures() -> list[tuple[Any, tuple[Any, ...]]]:
    """The entries and the argument types the estimator calls them with (C-contiguous
    float64 inputs, the state and output arrays as params.py and the estimator make them)."""
    f1, f2 = types.float64[::1], types.float64[:, ::1]
    i1 = types.int64[::1]
    state = (f1, i1, f1, i1)
    outputs = (f2, types.int8[:, ::1], types.int16[::1])
    flag, index = types.boolean, types.int64
    return [
        (run_block, (f1, f2, f2, flag, *state, *outputs, index, index)),
        (steps_changed, state),
        (contains, (f1, i1, index, types.float64, types.float64)),
        (tare_yardsticks, (f2, *state)),
        (likeliest_noise, (f1, f2, f2, f2, f2)),  # (at a tare, from resolution.py)
    ]


class _FirstCompile(event.Listener):
    """Says once on stderr that the kernels are being compiled (numba raises a compile event
    only on a cache miss)."""

    told = False

    def on_start(self, event: event.Event) -> None:
        if not _FirstCompile.told:
            _FirstCompile.told = True
            print(
                f"hapticdesk: compiling the estimator's kernels, once: ~{FIRST_COMPILE_S} s",
                file=sys.stderr,
                flush=True,
            )

    def on_end(self, event: event.Event) -> None:
        pass


def warm() -> None:
    """Compile the entries for the estimator's argument types, or load them from numba's
    cache (beside this file, or the user's cache directory where this folder cannot be
    written: numba's own choice); once per process. A cached load leaves numba's compiler
    unreadied (:func:`hapticdesk.cached_load.cache_loads`: 0.3 s of CPU at start-up)."""
    global _warm
    if _warm:
        return
    start = time.perf_counter()
    with (
        event.install_listener("numba:compile", _FirstCompile()),
        vectorized(),
        unchecked_indices(),
        cache_loads(),
    ):
        for dispatcher, signature in _signatures():
            dispatcher.compile(signature)
    _warm = True
    log.debug("the estimator's kernels ready in %.2f s", time.perf_counter() - start)
