"""The estimator's settings as the kernel's flat arrays: parameters once, state per run.

:func:`params_of` turns one desk's :class:`~hapticdesk.estimator.settings.EstimatorSettings`
(and its accelerometers' settings) into the parameter arrays ``pf`` (float64) and ``pi``
(int64) of :mod:`hapticdesk.estimator.kernel`: the fixed slots it names, then the desk-sized
parts (the channels→wrench matrix, the filters' sections, the surfaces…) at offsets kept in
``pi``; the sizes of the state's desk-sized parts are laid out the same way, and
:func:`new_state` makes a run's state arrays ``sf`` (float64) and ``si`` (int64) from them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from hapticdesk.estimator import kernel_slots as slots
from hapticdesk.estimator.contacts import SHEAR_CAP, UNCERTAINTY_CAP_M
from hapticdesk.estimator.detector import RING_MEMORY_S, upright_surfaces
from hapticdesk.estimator.filters import butter_lowpass_sos, sosfilt_zi
from hapticdesk.estimator.geometry import EDGE_TOLERANCE_M, VAR_CAP, SurfaceFrame
from hapticdesk.estimator.inertia import InertiaSettings
from hapticdesk.estimator.methods import DET_FLOOR, DIFF_INFO_RATIO
from hapticdesk.estimator.multitouch import (
    LAG_S,
    LANDING_S,
    LOWPASS_HZ,
    MAX_FIRST_MOVE_M,
    MIN_APART_M,
    MIN_NORMAL_SHARE,
    MIN_STEP_N,
    MIN_STEP_SHARE,
)
from hapticdesk.estimator.resolution import CONFIRM_CHANGES, REST_NOISE_S, STEP_CHANGE
from hapticdesk.estimator.samples import LIVE_AGAIN_S, NOISE_CHECK_S, NOISE_FREE_REPEATS, STUCK_RUN
from hapticdesk.estimator.settings import EstimatorSettings
from hapticdesk.estimator.still_objects import (
    HEAVY_SPREAD_SHARE,
    HEAVY_WANDER_SHARE,
    LIFT_TOLERANCE,
    LIGHT_LOAD_N,
    NOISY_EXTRA_WINDOWS,
    NOISY_STILL_SHARE,
    NOISY_WANDER_SHARE,
    OBJECT_NOISE_FLOOR_N,
    OBJECT_RESTING_KEEP,
    OBJECT_SPIKE,
    OBJECT_STILL_FACTOR,
    OBJECT_WANDER_FACTOR,
    STEP_SPREAD_SHARE,
    STEP_WANDER_SHARE,
)
from hapticdesk.estimator.yardsticks import IDLE_QUANTILE, IDLE_WINDOWS, STILL_NOISE_FACTOR
from hapticdesk.files.profile import METHODS


class State(NamedTuple):
    """A run's state: the kernel's ``sf`` and ``si`` (a snapshot is a copy of both)."""

    sf: np.ndarray
    si: np.ndarray


class _Packer:
    """Lays desk-sized parts out after an array's fixed slots."""

    def __init__(self, fixed: int) -> None:
        self.size = fixed
        self.parts: list[tuple[int, np.ndarray]] = []

    def put(self, values: np.ndarray | list[float] | list[int]) -> int:
        """Place ``values`` (flattened, row-major); returns their offset."""
        flat = np.ravel(np.asarray(values))
        at = self.size
        self.parts.append((at, flat))
        self.size += len(flat)
        return at

    def room(self, size: int) -> int:
        """Reserve ``size`` slots (zeros); returns their offset."""
        return self.put(np.zeros(size))

    def array(self, dtype: type, fixed: Mapping[int, float]) -> np.ndarray:
        out: np.ndarray = np.zeros(self.size, dtype)
        for slot, value in fixed.items():
            out[slot] = value
        for at, flat in self.parts:
            out[at : at + len(flat)] = flat
        return out


@dataclass(frozen=True, eq=False)
class Params:
    """One desk's parameter arrays, and how to make its state."""

    pf: np.ndarray
    pi: np.ndarray
    sf_size: int
    si_size: int
    sf_fixed: dict[int, float]  # the state's initial values, where not zero
    si_fixed: dict[int, int]
    out_rows: int  # float rows of the output columns (more in trace mode)

    def slot(self, name: int) -> int:
        """An offset the parameters keep (``kernel_slots.I_*O_*``)."""
        return int(self.pi[name])


def _surface_parts(frames: list[SurfaceFrame], pf: _Packer, pi: _Packer) -> tuple[int, int]:
    """Each surface's record in ``pf`` (SURF_F floats) and ``pi`` (SURF_I ints)."""
    floats, ints, polygons = [], [], []
    for frame in frames:
        s = frame.surface
        record = np.zeros(slots.SURF_F)
        record[slots.SURF_ROWS : slots.SURF_ROWS + 18] = np.ravel(frame.transform[2:5])
        record[slots.SURF_ORIGIN : slots.SURF_ORIGIN + 3] = s.origin
        record[slots.SURF_U : slots.SURF_U + 3] = s.u_axis
        record[slots.SURF_V : slots.SURF_V + 3] = s.v_axis
        record[slots.SURF_NORMAL : slots.SURF_NORMAL + 3] = s.normal
        record[slots.SURF_BOUNDS : slots.SURF_BOUNDS + 4] = frame.bounds
        floats.append(record)
        polygons.append(np.ravel(frame.polygon))
        ints.append([int(frame.is_rectangle), int(frame.desk_xy), 0, len(frame.polygon)])
    surf_f = pf.put(np.concatenate(floats) if floats else np.zeros(0))
    for j, polygon in enumerate(polygons):
        ints[j][slots.SURF_POLY] = pf.put(polygon)
    surf_i = pi.put(np.ravel(np.array(ints, dtype=np.int64)) if ints else np.zeros(0, np.int64))
    return surf_f, surf_i


def geometry_params(
    frames: list[SurfaceFrame], min_normal_cos: float
) -> tuple[np.ndarray, np.ndarray]:
    """The parameters :func:`kernel.intersect` reads, for ``frames`` alone."""
    pf, pi = _Packer(slots.N_PF_FIXED), _Packer(slots.N_PI)
    surf_f, surf_i = _surface_parts(frames, pf, pi)
    fixed_f = {
        slots.P_MIN_COS: min_normal_cos,
        slots.P_VAR_CAP: VAR_CAP,
        slots.P_EDGE_TOLERANCE: EDGE_TOLERANCE_M,
    }
    fixed_i = {slots.I_N_SURF: len(frames), slots.I_PO_SURF: surf_f, slots.I_IO_SURF: surf_i}
    return pf.array(np.float64, fixed_f), pi.array(np.int64, fixed_i)


class _Sizes(NamedTuple):
    """The desk-sized parts' lengths the kernel's arrays are laid out with."""

    channels: int  # C, the raw channels
    axes: int  # A, the accelerometers' axes (0: none)
    sections: int  # second-order sections of each filter
    lag: int  # the second-finger stage's lag, in samples
    landing: int  # ... and its landing window
    span: int  # the sway stage's span (0: off)
    still_ring: (
        int  # the still run's means the zero stage reads back (the drift's, an object's wait)
    )
    wander_windows: int  # the idle windows in a row a yardstick wander is taken over
    live_n: int  # samples an input is live again after being stuck


def params_of(s: EstimatorSettings, inertia: InertiaSettings | None) -> Params:
    """The kernel's parameters for the desk of ``s`` (and its accelerometers, ``inertia``)."""
    fs = s.sample_rate_hz
    sizes = _Sizes(
        channels=s.wrench_map.shape[1],
        axes=0 if inertia is None else inertia.n_axes,
        sections=len(s.lp_sos),
        lag=max(1, round(LAG_S * fs)),
        landing=max(1, round(LANDING_S * fs)),
        span=s.sway.span if s.sway is not None else 0,
        still_ring=max(s.n_drift, s.n_object + 1 + NOISY_EXTRA_WINDOWS),
        # the idle desk's wander is measured over as many windows as an object waits
        wander_windows=max(2, s.n_object),
        live_n=max(1, round(LIVE_AGAIN_S * fs)),
    )
    pf, pi = _Packer(slots.N_PF_FIXED), _Packer(slots.N_PI)
    sf, si = _Packer(slots.N_SF_FIXED), _Packer(slots.N_SI_FIXED)
    fixed_i = {
        **_counts(s, inertia, sizes),
        **_filter_parts(s, pf),
        **_desk_parts(s, inertia, pf, pi),
        **_state_parts(s, sizes, sf, si),
    }
    state_f = {
        slots.S_LAST_T: -math.inf,
        slots.S_MAX_T: -math.inf,
        slots.S_BACK_LAST: math.inf,
        slots.S_STUCK_SINCE: math.nan,
        slots.S_LAST_STUCK_T: math.nan,
        slots.S_MT_MIN_APART: MIN_APART_M,
    }
    state_i = {
        slots.J_STUCK_CHECK: -1,
        slots.J_LIVE: sizes.live_n,
        slots.J_N_LEARNING: sizes.channels,
    }
    return Params(
        pf=pf.array(np.float64, _fixed_floats(s)),
        pi=pi.array(np.int64, fixed_i),
        sf_size=sf.size,
        si_size=si.size,
        sf_fixed=state_f,
        # the state's desk-sized parts' initial values (the learning flags)
        si_fixed={
            **state_i,
            **{at + j: int(v) for at, flat in si.parts for j, v in enumerate(flat) if v},
        },
        out_rows=slots.N_OUT_F + (slots.TRACE_ROWS if s.trace else 0),
    )


def _fixed_floats(s: EstimatorSettings) -> dict[int, float]:
    """The float parameters' fixed slots (``P_*``): the user's thresholds, the derived
    scales, the stages' constants."""
    user, fs = s.user, s.sample_rate_hz
    return {
        slots.P_MAX_GAP: user.max_gap_s,
        slots.P_CONTACT: user.contact_force_n,
        slots.P_HYSTERESIS: user.release_hysteresis_n,
        slots.P_RELEASE_SLOPE: user.release_slope_n_s,
        slots.P_DET_DELAY: s.det_delay_s,
        slots.P_PHASE_RATE: user.phase_rate_n_s,
        slots.P_MIN_COS: user.min_normal_cos,
        slots.P_MAX_SIGMA: user.max_sigma_m,
        slots.P_SPEED: user.contact_speed_m_s,
        slots.P_TOUCH_THRESHOLD: user.touch_threshold_n,
        slots.P_RELEASE_THRESHOLD: user.release_threshold_n,
        slots.P_DIFF_SCALE: s.diff_scale,
        slots.P_RATE_SCALE: s.rate_scale,
        slots.P_RELEASE_SCALE: s.release_scale,
        slots.P_RING_DECAY: math.exp(-1.0 / (RING_MEMORY_S * fs)),
        slots.P_SWAY_SCALE: s.sway.scale if s.sway is not None else 0.0,
        slots.P_DIFF_INFO_RATIO: DIFF_INFO_RATIO,
        slots.P_VAR_CAP: VAR_CAP,
        slots.P_DET_FLOOR: DET_FLOOR,
        slots.P_EDGE_TOLERANCE: EDGE_TOLERANCE_M,
        slots.P_SHEAR_CAP: SHEAR_CAP,
        slots.P_SHEAR_CAP_INV: 1.0 / SHEAR_CAP,
        slots.P_UNCERTAINTY_CAP: UNCERTAINTY_CAP_M,
        slots.P_STEP_CHANGE: STEP_CHANGE,
        slots.P_MT_MIN_STEP: MIN_STEP_N,
        slots.P_MT_MIN_STEP_SHARE: MIN_STEP_SHARE,
        slots.P_MT_MIN_NORMAL_SHARE: MIN_NORMAL_SHARE,
        slots.P_MT_MAX_FIRST_MOVE: MAX_FIRST_MOVE_M,
        slots.P_STILL_N: user.still_n,
        slots.P_DRIFT_MAX: user.drift_max_n,
        slots.P_OBJECT_STILL_FACTOR: OBJECT_STILL_FACTOR,
        slots.P_OBJECT_WANDER_FACTOR: OBJECT_WANDER_FACTOR,
        slots.P_HEAVY_WANDER_SHARE: HEAVY_WANDER_SHARE,
        slots.P_HEAVY_SPREAD_SHARE: HEAVY_SPREAD_SHARE,
        slots.P_OBJECT_SPIKE: OBJECT_SPIKE,
        slots.P_OBJECT_RESTING_KEEP: OBJECT_RESTING_KEEP,
        slots.P_LIGHT_LOAD: LIGHT_LOAD_N,
        slots.P_OBJECT_NOISE_FLOOR: OBJECT_NOISE_FLOOR_N,
        slots.P_STEP_SPREAD_SHARE: STEP_SPREAD_SHARE,
        slots.P_STEP_WANDER_SHARE: STEP_WANDER_SHARE,
        slots.P_LIFT_TOLERANCE: LIFT_TOLERANCE,
        slots.P_IDLE_QUANTILE: IDLE_QUANTILE,
        slots.P_JUMP_SQ: s.jump_n**2,
        slots.P_JUMP_ARM_INV_SQ: 1.0 / s.jump_arm_m**2,
        slots.P_STILL_NOISE_FACTOR: STILL_NOISE_FACTOR,
        slots.P_NOISY_WANDER_SHARE: NOISY_WANDER_SHARE,
        slots.P_NOISY_STILL_SHARE: NOISY_STILL_SHARE,
    }


def _counts(s: EstimatorSettings, inertia: InertiaSettings | None, n: _Sizes) -> dict[int, int]:
    """The int parameters' fixed slots that are counts, switches and lengths (``I_*``)."""
    return {
        slots.I_C: n.channels,
        slots.I_A: n.axes,
        slots.I_MULTI_ACCEL: int(inertia is not None and inertia.rows is not None),
        slots.I_N_SURF: len(s.frames),
        slots.I_N_UP: len(upright_surfaces(s.normals)),
        slots.I_METHOD: METHODS.index(s.method),
        slots.I_DET_FULL: int(s.det_full),
        slots.I_SHARED_LP: int(s.shared_lp),
        slots.I_TRACE: int(s.trace),
        slots.I_NS: n.sections,
        slots.I_N_DIFF: s.n_diff,
        slots.I_N_RATE: s.n_rate,
        slots.I_N_RELEASE: s.n_release,
        slots.I_SPAN: n.span,
        slots.I_WINDOW: s.window,
        slots.I_STILL_BLOCK: s.still_block,
        slots.I_STUCK_RUN: STUCK_RUN,
        slots.I_CHECK_N: max(STUCK_RUN + 1, round(NOISE_CHECK_S * s.sample_rate_hz)),
        slots.I_NOISE_FREE_REPEATS: NOISE_FREE_REPEATS,
        slots.I_LIVE_N: n.live_n,
        slots.I_CONFIRM: CONFIRM_CHANGES,
        slots.I_MT_LAG: n.lag,
        slots.I_MT_LANDING: n.landing,
        slots.I_MT_BOARD: 0 if s.frames else -1,
        slots.I_N_DRIFT: s.n_drift if s.user.drift_settle_s > 0 else 0,
        slots.I_STILL_RING: n.still_ring,
        slots.I_N_SETTLE: s.n_settle,
        slots.I_N_OBJECT: s.n_object,
        slots.I_N_NOISY_EXTRA: NOISY_EXTRA_WINDOWS,
        slots.I_JUMP_HOLD_N: s.jump_hold_n,
        slots.I_WANDER_WINDOWS: n.wander_windows,
        slots.I_IDLE_WINDOWS: IDLE_WINDOWS,
        slots.I_ZEROED: int(s.user.zeroed),
        slots.I_REST_N: round(REST_NOISE_S * s.sample_rate_hz),
    }


def _filter_parts(s: EstimatorSettings, pf: _Packer) -> dict[int, int]:
    """The filters' sections and their initial conditions into ``pf``; their offsets."""
    fs = s.sample_rate_hz
    mt_sos = butter_lowpass_sos(min(LOWPASS_HZ, 0.45 * fs), fs)  # (as the fast path's)
    filters = {"lp": s.lp_sos, "diff": s.diff_sos, "det": s.det_sos, "mt": mt_sos}
    if any(len(sos) != len(s.lp_sos) for sos in filters.values()):
        raise ValueError("the estimator's filters must have as many sections each")
    sos_at = {name: pf.put(sos) for name, sos in filters.items()}
    zi_at = {name: pf.put(sosfilt_zi(sos)) for name, sos in filters.items()}
    return {
        slots.I_PO_LP_SOS: sos_at["lp"],
        slots.I_PO_DIFF_SOS: sos_at["diff"],
        slots.I_PO_DET_SOS: sos_at["det"],
        slots.I_PO_MT_SOS: sos_at["mt"],
        slots.I_PO_LP_ZI: zi_at["lp"],
        slots.I_PO_DIFF_ZI: zi_at["diff"],
        slots.I_PO_DET_ZI: zi_at["det"],
        slots.I_PO_MT_ZI: zi_at["mt"],
    }


def _desk_parts(
    s: EstimatorSettings, inertia: InertiaSettings | None, pf: _Packer, pi: _Packer
) -> dict[int, int]:
    """The desk's own parts into ``pf`` and ``pi`` (the channels→wrench matrix, the limits,
    the surfaces, the sway's lever, the accelerometers'); their offsets."""
    surf_f, surf_i = _surface_parts(s.frames, pf, pi)
    return {
        slots.I_PO_MAP: pf.put(s.wrench_map.T),  # (by channel: see kernel_slots.I_PO_MAP)
        slots.I_PO_LIMIT: pf.put(s.range_flat),
        slots.I_PO_SURF: surf_f,
        slots.I_PO_LEVER: pf.put(s.sway.moment_lever if s.sway is not None else np.zeros(6)),
        slots.I_PO_GAIN: pf.put(inertia.gain if inertia is not None else np.zeros(0)),
        slots.I_PO_REST: pf.put(inertia.rest if inertia is not None else np.zeros(0)),
        slots.I_PO_ALIMIT: pf.put(inertia.limit if inertia is not None else np.zeros(0)),
        slots.I_IO_UP: pi.put(np.asarray(upright_surfaces(s.normals), np.int64)),
        slots.I_IO_SURF: surf_i,
    }


def _state_parts(s: EstimatorSettings, n: _Sizes, sf: _Packer, si: _Packer) -> dict[int, int]:
    """Room for the state's desk-sized parts in ``sf`` and ``si``; their offsets."""
    window, c_n, ring = s.window, n.channels, 2 * n.lag + 1
    return {
        slots.I_SO_LP_ZI: sf.room(6 * n.sections * 2),
        slots.I_SO_DIFF_ZI: sf.room(6 * n.sections * 2),
        slots.I_SO_DET_ZI: sf.room(6 * n.sections * 2),
        slots.I_SO_MT_ZI: sf.room(6 * n.sections * 2),
        slots.I_SO_DELAY: sf.room(s.n_diff * 6),
        slots.I_SO_DET_RING: sf.room(s.n_rate * 3),
        slots.I_SO_SWAY: sf.room(2 * n.span * 2),
        slots.I_SO_SWAY_DIFF: sf.room(2 * n.span * 2),
        slots.I_SO_WIN_LP: sf.room(3 * window),
        slots.I_SO_WIN_RAW: sf.room(6 * window),
        slots.I_SO_GUARD: sf.room(len(upright_surfaces(s.normals))),
        slots.I_SO_COVS: sf.room(max(1, len(s.frames)) * 4 * 6),
        slots.I_SO_STEP: sf.room(c_n),
        slots.I_SO_USED: sf.room(c_n),
        slots.I_SO_LAST_ROW: sf.room(c_n),
        slots.I_SO_PREV_ROW: sf.room(c_n),
        slots.I_SO_MT_HIST: sf.room(ring * slots.MT_F),
        slots.I_SO_LANDING: sf.room((ring + n.landing) * 6),
        slots.I_SO_PARTIAL_GAIN: sf.room(6 * n.axes),
        slots.I_SO_TRACE: sf.room(slots.TRACE_ROWS),
        slots.I_SO_STILL_MEANS: sf.room(6 * n.still_ring),
        slots.I_SO_IDLE_SPREADS: sf.room(IDLE_WINDOWS),
        slots.I_SO_IDLE_WANDERS: sf.room(IDLE_WINDOWS),
        slots.I_SO_IDLE_TAIL: sf.room(4 * n.wander_windows),
        slots.I_SO_OBJ_WINDOWS: sf.room(4 * (s.n_object + 1 + NOISY_EXTRA_WINDOWS)),
        slots.I_SO_SCRATCH: sf.room(IDLE_WINDOWS + s.n_object + 1 + NOISY_EXTRA_WINDOWS),
        slots.I_SO_ROUND: sf.room(slots.ROUND_SPREAD + 7 * c_n + 5 * c_n * max(1, len(s.frames))),
        slots.I_SO_REST_SQ: sf.room(c_n),
        slots.I_JO_CHANGES: si.room(c_n),
        slots.I_JO_LEARNING: si.put(np.ones(c_n, np.int64)),
        slots.I_JO_WIN_BAD: si.room(window),
        slots.I_JO_MT_HIST: si.room(ring * slots.MT_I),
    }


def new_state(params: Params) -> State:
    """A run's state as it starts: nothing seen, nothing tared."""
    sf = np.zeros(params.sf_size)
    si = np.zeros(params.si_size, np.int64)
    for slot, value in params.sf_fixed.items():
        sf[slot] = value
    for slot, value in params.si_fixed.items():
        si[slot] = value
    return State(sf, si)
