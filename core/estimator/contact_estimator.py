"""The contact estimator: raw channels in, contact samples out, one compiled pass per sample.

:class:`ContactEstimator` holds one desk's parameters (its settings flattened once,
:mod:`.params`), a run's state arrays and the output columns, and runs the kernel
(:mod:`.kernel`) over each push: a block through its loop into the output columns, a single
sample through the same loop into a reused one-sample record. Between samples it handles
what the kernel leaves to Python — notices, the zero's windows before the tare and the
objects absorbed or lifted after it (:mod:`.zero`),
the covariances made at the tare and when a resolution step is learned (:mod:`.candidates`),
the accelerometers' gain for partial readings (:mod:`.inertia`), the second finger's fit and
stray (:mod:`.multitouch`) — and resumes.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from hapticdesk.estimator import kernel as k
from hapticdesk.estimator import kernel_geometry
from hapticdesk.estimator import kernel_slots as slots
from hapticdesk.estimator.candidate_trace import CandidateTrace
from hapticdesk.estimator.candidates import Covariances
from hapticdesk.estimator.contacts import ContactBlock
from hapticdesk.estimator.inertia import InertiaSettings, InertiaStage, accelerometer_readings
from hapticdesk.estimator.kernel_channels import steps_changed
from hapticdesk.estimator.multitouch import SecondFingerStage, fit_second_point
from hapticdesk.estimator.notices import NoticeList
from hapticdesk.estimator.output_columns import OutputColumns
from hapticdesk.estimator.params import Params, State, new_state, params_of
from hapticdesk.estimator.samples import tell_events
from hapticdesk.estimator.settings import EstimatorSettings
from hapticdesk.estimator.zero import ZeroStage
from hapticdesk.files.profile import METHODS, DeskProfile, EstimationSettings
from hapticdesk.files.recording import Recording

__all__ = ["ContactEstimator", "estimate"]

#: a push of up to this many samples is written into output columns the estimator keeps and
#: reuses (so a stream of pushes allocates nothing); a longer one gets columns of its own
KEPT_COLUMNS = 65536


class ContactEstimator:
    """Streaming contact estimator for one desk (the module docstring).

    ``push(t, wrench)`` takes k samples (k ≥ 0): ``t`` (k,) seconds and ``wrench`` the raw
    channels, (k, C), or (k, S, 6) for six-axis sensors in their own frames (the same
    memory); it returns a :class:`ContactBlock` for exactly those samples, a view of the
    estimator's output columns that holds until the next push (copy it to keep it).
    """

    def __init__(
        self,
        profile: DeskProfile,
        method: str | None = None,
        settings: EstimationSettings | None = None,
        trace: bool = False,
    ) -> None:
        """``trace``: also keep both candidates of every sample in contact in :attr:`traces`
        (for research: the paper's D_er and D_ed, threshold derivation, plots)."""
        settings = settings or profile.estimation
        self.trace = trace
        self.traces: list[CandidateTrace] = []
        if method is not None:
            if method not in METHODS:
                raise ValueError(f"method must be one of {', '.join(METHODS)}, found {method!r}")
            settings = replace(settings, method=method)
        self.profile = profile
        self.settings = settings
        self.method = settings.method
        self.stage_settings = EstimatorSettings.of(profile, settings, trace)
        #: the vibration compensation's settings; None for a desk without an accelerometer
        self.inertia_settings = InertiaSettings.of(profile)
        self._inertia = (
            None if self.inertia_settings is None else InertiaStage(self.inertia_settings)
        )
        self.params: Params = params_of(self.stage_settings, self.inertia_settings)
        self.sample_rate_hz = profile.sample_rate_hz
        #: how far the located points run behind a moving finger: the force low-pass's
        #: delay (the gesture engine carries a swipe's end on by it)
        self.position_delay_s = self.stage_settings.position_delay_s
        self.notices = NoticeList()  # bounded: see NoticeList
        self._n_channels = self.stage_settings.wrench_map.shape[1]
        # (k, S, 6) samples of a desk of six-axis sensors are its channels as they are
        self._sensor_shape = (len(profile.sensors), 6) if profile.six_axis_only else None
        n_axes = 0 if self.inertia_settings is None else self.inertia_settings.n_axes
        self._no_readings = np.zeros((1, n_axes))  # (the kernels' accel when there is none)
        self._record = OutputColumns(1, self.params.out_rows)  # the one-sample record
        self._one_t = np.empty(1)  # (its time, for the loop)
        self._columns = OutputColumns(0, self.params.out_rows)
        self._second_finger_on = settings.second_finger
        k.warm()
        self.reset()

    # --- state ----------------------------------------------------------------------------

    def reset(self) -> None:
        """Forget everything: filters, zero and contact state (a new run)."""
        self.state: State = new_state(self.params)
        self.zeroing = self._zero_stage()
        self.covariances: Covariances | None = None  # made at the tare
        self._accel_missing = False  # in a spell of samples without accelerometer readings
        self.second_finger: SecondFingerStage | None = None
        self._second_finger_afresh(self._second_finger_on)

    def use_second_finger(self, on: bool) -> None:
        """Run the second-finger stage (:mod:`.multitouch`) from the next sample on, or stop
        it: on when a layout binds a gesture that reads a second finger, whatever the
        profile's ``second_finger`` says. Turned on, it starts afresh; asked for what it
        already does, nothing changes."""
        if on != self._second_finger_on:
            self._second_finger_on = on
            self._second_finger_afresh(on)

    def _second_finger_afresh(self, on: bool) -> None:
        sf, si = self.state
        self.second_finger = SecondFingerStage() if on else None
        si[slots.J_MT_ON] = int(on)
        for slot in (
            slots.J_MT_STARTED,
            slots.J_MT_COUNT,
            slots.J_MT_POS,
            slots.J_MT_PREV_IN,
            slots.J_MT_FLAGGED,
        ):
            si[slot] = 0
        si[slots.J_MT_LANDING] = si[slots.J_MT_HAS_SECOND] = 0
        sf[slots.S_MT_STRAY] = 0.0
        if self.second_finger is not None:
            sf[slots.S_MT_MIN_APART] = self.second_finger.min_apart_m

    def retare(self) -> None:
        """Forget the zero and take it again over the next ``tare_s`` of a still desk (as at
        the start); the filters keep their state, so no transient follows. Contacts are
        reported again once the new zero is set."""
        sf, si = self.state
        for slot in (
            *(
                slots.J_TARED,
                slots.J_RESTING,
                slots.J_RESTING_OFF,
                slots.J_WIN_FILL,
                slots.J_IN_CONTACT,
                slots.J_BLOCKED,
            ),
            *(
                slots.J_WINDOW_INDEX,
                slots.J_WINDOWS_SEEN,
                slots.J_STILL_RUN,
                slots.J_STILL_POS,
                slots.J_STILL_COUNT,
            ),
            *(
                slots.J_OBJECT_RUN,
                slots.J_OBJECTS,
                slots.J_ZERO_VERSION,
                slots.J_RESTING_NEXT,
                slots.J_OBJ_RESTING,
                slots.J_OBJ_GRACED,
                slots.J_ZERO_NEXT,
            ),
        ):
            si[slot] = 0
        self.zeroing = self._zero_stage()
        self.covariances = None  # made again from the new tare's noise
        guard = self.params.slot(slots.I_SO_GUARD)
        sf[guard : guard + int(self.params.pi[slots.I_N_UP])] = 0.0

    def _zero_stage(self) -> ZeroStage:
        sf, si = self.state
        params = self.params
        return ZeroStage(self.stage_settings, self.notices, params.pf, params.pi, sf, si)

    @property
    def tared(self) -> bool:
        return bool(self.state.si[slots.J_TARED])

    @property
    def zero(self) -> np.ndarray | None:
        """The current zero of [F_o; M_o] (6,), or None before the tare."""
        return self.zeroing.state.zero

    @property
    def resolution_step(self) -> np.ndarray:
        """Each channel's resolution step learned so far (C,), 0 where none yet
        (resolution.py)."""
        at = self.params.slot(slots.I_SO_STEP)
        return self.state.sf[at : at + self._n_channels].copy()

    # --- a push ---------------------------------------------------------------------------

    def push(
        self, t: np.ndarray, wrench: np.ndarray, accel: np.ndarray | None = None
    ) -> ContactBlock:
        """Estimate contacts for k more samples. See the class docstring.

        ``accel`` (k, A): the desk's accelerometer readings (its profile's columns, m/s²),
        used only when the profile has an accelerometer; without them such a desk's samples
        are estimated uncompensated and flagged ``FLAG_NO_ACCEL``."""
        if not (type(t) is np.ndarray and t.dtype == np.float64 and t.ndim == 1):
            t = np.ascontiguousarray(t, dtype=np.float64).reshape(-1)
        elif not t.flags.c_contiguous:
            t = np.ascontiguousarray(t)
        n = len(t)
        x = self._channels(wrench, n)
        readings = self._readings(accel, n)
        if n == 0:
            return ContactBlock.empty()
        if self._inertia is not None:
            self._note_accelerometer(float(t[0]), readings is not None)
        noticed = self.notices.total
        given = readings is not None
        a = self._no_readings if readings is None else readings
        if n == 1:
            block = self._step(float(t[0]), x, a[:1], given)
        else:
            block = self._run(t, x, a, given, n)
        if self.notices.total - noticed > 1:  # in time order, however the stages found them
            new = self.notices.since(noticed)
            self.notices[len(self.notices) - len(new) :] = sorted(new, key=lambda notice: notice.t)
        return block

    def _channels(self, wrench: np.ndarray, n: int) -> np.ndarray:
        """The raw channels (n, C), C-contiguous float64 (a view where they already are):
        (k, C), or (k, S, 6) for a desk of six-axis sensors (``DeskProfile.flat_channels``,
        which names the shapes expected otherwise)."""
        w = wrench
        if not (type(w) is np.ndarray and w.dtype == np.float64 and w.flags.c_contiguous):
            w = np.ascontiguousarray(wrench, dtype=np.float64)
        if w.shape == (n, self._n_channels):
            return w
        if w.shape[1:] == self._sensor_shape and len(w) == n:
            # (k, S, 6) of a six-axis desk: its channels are a view (DeskProfile.flat_channels
            # costs more than a single sample's estimate)
            return w.reshape(n, self._n_channels)
        w = np.ascontiguousarray(self.profile.flat_channels(w))
        if len(w) != n:
            raise ValueError(
                f"{n} sample times but {len(w)} samples for desk {self.profile.name!r}"
            )
        return w

    def _readings(self, accel: np.ndarray | None, n: int) -> np.ndarray | None:
        """The accelerometer's readings (n, A), C-contiguous, or None (none, or a desk without
        an accelerometer: nothing changes)."""
        if self._inertia is None:
            return None
        checked = self._inertia.check(accel, n)
        return None if checked is None else np.ascontiguousarray(checked)

    def _step(self, t: float, x: np.ndarray, a: np.ndarray, given: bool) -> ContactBlock:
        """One sample (``x`` (1, C), ``a`` (1, A)) through the kernel's loop, into the reused
        one-sample record."""
        rec, one = self._record, self._one_t
        one[0] = t
        pf, pi = self.params.pf, self.params.pi
        sf, si = self.state
        while True:  # (the block loop over one sample: the machine code a block runs)
            events = k.run_block(one, x, a, given, pf, pi, sf, si, rec.f, rec.b, rec.s, 0, 1)
            if not events:
                break
            self._handle(events, rec, 0, a[0])
            if si[slots.J_RESUME] == slots.RESUME_NEXT:
                break
        if self.trace and rec.b[slots.OUT_B_TRACED, 0]:
            self.traces.append(CandidateTrace.of(rec.f, np.array([0])))
        return rec.block(1)

    def _run(
        self, t: np.ndarray, x: np.ndarray, a: np.ndarray, given: bool, n: int
    ) -> ContactBlock:
        """A block through the kernel's loop entry, into the output columns."""
        cols = self._columns
        if n > cols.capacity:
            cols = OutputColumns(n, self.params.out_rows)
            if n <= KEPT_COLUMNS:
                self._columns = cols
        pf, pi = self.params.pf, self.params.pi
        sf, si = self.state
        i = 0
        while True:
            events = k.run_block(t, x, a, given, pf, pi, sf, si, cols.f, cols.b, cols.s, i, n)
            if not events:
                break
            at = int(si[slots.J_EVENT_AT])
            self._handle(events, cols, at, a[at] if given else a[0])
            i = at + 1 if si[slots.J_RESUME] == slots.RESUME_NEXT else at
        if self.trace:
            traced = np.flatnonzero(cols.b[slots.OUT_B_TRACED, :n])
            if len(traced):
                self.traces.append(CandidateTrace.of(cols.f, traced))
        return cols.block(n)

    # --- what the kernel leaves to Python -------------------------------------------------

    def _handle(self, events: int, cols: OutputColumns, col: int, readings: np.ndarray) -> None:
        """The events one sample raised (kernel_slots.EV_*), in the order the stages meet them."""
        if events == slots.EV_WINDOW:  # (before the tare: five a second)
            self._window()
            return
        sf, si = self.state
        if events & slots.EV_PARTIAL_ACCEL:
            assert self._inertia is not None
            gain_at = self.params.slot(slots.I_SO_PARTIAL_GAIN)
            self._inertia.partial_gain_into(readings, sf, si, gain_at)
            return
        tell_events(self.notices, events, sf, si)
        if events & slots.EV_COVS:
            self._make_covariances()
        if events & slots.EV_WINDOW:
            self._window()
        if events & (slots.EV_ABSORBED | slots.EV_LIFTED):
            self.zeroing.objects_changed(events)
        if events & slots.EV_CONTACT_END:
            assert self.second_finger is not None
            self.second_finger.contact_ended(
                bool(si[slots.J_MT_END_FLAGGED]), float(sf[slots.S_MT_END_STRAY])
            )
            sf[slots.S_MT_MIN_APART] = self.second_finger.min_apart_m
        if events & slots.EV_FIT:
            self._fit_second(cols, col)

    def _window(self) -> None:
        """A zero window before the tare ended (zero.py; the kernel judges those after it);
        at the tare the covariances are made."""
        if self.zeroing.window():
            sf, si = self.state
            steps_changed(self.params.pf, self.params.pi, sf, si)  # (the steps they use)
            self._make_covariances()

    def _make_covariances(self) -> None:
        """The candidates' covariances from the tare's noise and the resolution steps the
        kernel uses now, into its state (candidates.py)."""
        noise = self.zeroing.state.noise
        if noise is None:
            return
        sf, si = self.state
        used, sq = self.params.slot(slots.I_SO_USED), self.params.slot(slots.I_SO_REST_SQ)
        compared = si[slots.J_REST_N]  # (the mean square change is twice the variance)
        rest_var = sf[sq : sq + self._n_channels] / (2 * compared) if compared else None
        step = sf[used : used + self._n_channels].copy()
        self.covariances = Covariances.of(self.stage_settings, noise, step, rest_var, int(compared))
        for slot, packed in (
            (slots.I_SO_COVS, self.covariances.packed().ravel()),
            (slots.I_SO_ROUND, self.covariances.packed_rounding(step)),
        ):
            at = self.params.slot(slot)
            sf[at : at + len(packed)] = packed

    def _fit_second(self, cols: OutputColumns, col: int) -> None:
        """The second finger's landing window is full: its point fitted (multitouch.py), on
        the board, from this sample on."""
        sf, si = self.state
        rows = int(si[slots.J_MT_ROWS])
        at = self.params.slot(slots.I_SO_LANDING)
        board = self.profile.surfaces[0]
        second = fit_second_point(
            sf[slots.S_MT_FIRST : slots.S_MT_FIRST + 3].copy(),
            np.asarray(board.normal, float),
            sf[at : at + 6 * rows].reshape(rows, 6),
        )
        if second is None:
            return
        rel = second - board.origin
        if not kernel_geometry.contains(
            self.params.pf, self.params.pi, 0, float(rel @ board.u_axis), float(rel @ board.v_axis)
        ):
            return
        sf[slots.S_MT_SECOND : slots.S_MT_SECOND + 3] = second
        si[slots.J_MT_HAS_SECOND] = 1
        cols.f[slots.OUT_X2, col], cols.f[slots.OUT_Y2, col], cols.f[slots.OUT_Z2, col] = second
        cols.b[slots.OUT_B_LOCATED2, col] = 1

    def _note_accelerometer(self, t: float, given: bool) -> None:
        """A warning when a desk with an accelerometer gets samples without its readings (a
        recording without its columns, a source that does not pass them): they are estimated
        uncompensated, and only the ``no_accel`` flag would say so. Once per spell."""
        if given or self._accel_missing:
            self._accel_missing = not given
            return
        self._accel_missing = True
        assert self._inertia is not None
        self._inertia.tell_missing(self.notices, t, self.profile.name)


def estimate(profile: DeskProfile, recording: Recording, method: str | None = None) -> ContactBlock:
    """Batch estimation of a whole recording (identical to streaming it in any blocks); the
    block is the caller's own."""
    if recording.sensor_names != profile.sensor_names:
        raise ValueError(
            f"the recording's sensors {recording.sensor_names} are not the desk's "
            f"{profile.sensor_names}"
        )
    accel = accelerometer_readings(profile, recording.extra)
    estimator = ContactEstimator(profile, method=method)
    return estimator.push(recording.t, recording.wrench, accel)
