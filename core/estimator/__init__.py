"""The contact estimator: sensor wrenches in, contact samples out (paper §2–3, Fig. 3).

One pass per block, the same code for a single sample or a million (``push``), so streaming
and batch give the same output for any split of the input. Each stage is a module, its
settings (:mod:`.settings`, derived once from the profile) apart from its state; a stage's
single-sample twin sits beside its block path and shares its formulas:

1. :mod:`.samples` — bad samples (NaN/inf, a saturated channel, time not increasing, a
   stuck input that repeats its last sample) are flagged and replaced by the last good
   sample, so no filter state is poisoned; a gap in time restarts the filters. The 6·S
   channels become the resultant wrench [F_o; M_o] about P_o by one linear map (paper
   eqs. 1–4; :meth:`DeskProfile.wrench_map`). With an accelerometer on the desk
   (:mod:`.inertia`), the desk's own inertial force and moment are removed from it.
2. :mod:`.filter_bank` — filters on that wrench: the conventional second-order low-pass;
   the pseudo-differentiated wrench (paper eq. 8: an n-sample difference, then the
   low-pass); and a fast (30 Hz) low-pass for touch-down/release detection that does not
   wait for the position filters.
3. :mod:`.zero` — an automatic tare over the first ``tare_s`` of a quiet desk (refused with
   a warning and retried while the desk is not quiet); the zero then follows sensor drift
   whenever the idle desk rests for ``drift_settle_s``, and a load held perfectly still for
   ``settle_s`` (an object put down) becomes part of it, with a notice.
4. :mod:`.detector` — contact from the tared fast force with hysteresis, and its phase.
5. :mod:`.candidates` — P_er from the force and P_ed from the differentiated force (and,
   for ``fused``, one from the fast wrench), each the intersection of its line of action
   with the surfaces (paper eqs. 5, 12; :mod:`.geometry`), each with a covariance propagated
   from the noise measured at the tare, plus the rounding of channels quieter than their
   resolution step (:mod:`.resolution`, the steps learned by stage 1), the zero's drift
   since it was set and, for P_ed, the term eq. (11) drops.
6. :mod:`.methods` — ``force`` (the conventional), ``diff``, ``switched`` (paper Fig. 3
   with F_tth, F_rth) or ``fused`` (inverse-covariance combination of the candidates, no
   threshold; a point is reported when its 1-σ is below ``max_sigma_m``).
7. :mod:`.multitouch` — optional (``second_finger``, or a layout binding ``two_finger_tap``):
   a second finger that lands while the first holds, flagged ``FLAG_MULTI`` and placed.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace

import numpy as np

from hapticdesk.estimator.candidates import Candidates, CandidateStage, Covariances, unpacked_at
from hapticdesk.estimator.contacts import FLAG_NOT_TARED, UNCERTAINTY_CAP_M, ContactBlock
from hapticdesk.estimator.detector import TouchDetector, phase_of, phases_of, slope_along
from hapticdesk.estimator.filter_bank import FilterBank
from hapticdesk.estimator.geometry import shear_ratio, shear_ratio_one
from hapticdesk.estimator.inertia import InertiaSettings, InertiaStage, accelerometer_readings
from hapticdesk.estimator.methods import emit_one, select, select_one
from hapticdesk.estimator.multitouch import SecondFingerStage
from hapticdesk.estimator.notices import Notice, NoticeList, add_notice
from hapticdesk.estimator.samples import BAD_SAMPLE, SampleStage
from hapticdesk.estimator.settings import EstimatorSettings
from hapticdesk.estimator.zero import ZeroSegments, ZeroStage, subtract_zero
from hapticdesk.files.profile import METHODS, DeskProfile, EstimationSettings
from hapticdesk.files.recording import Recording

__all__ = ["BAD_SAMPLE", "CandidateTrace", "ContactEstimator", "Notice", "estimate"]

# samples per piece of a long push: pieces keep the stages' working arrays small (cache, and
# no memory for a whole recording's temporaries) while the per-piece Python overhead stays
# small. Measured on a quiet machine, `force` over 432,000 samples: 4096: 147 ms; 8192:
# 112 ms; 16384: 192 ms, because there glibc returns the freed temporaries to the kernel
# after each piece and takes them back with a page fault per 4 kB (47,000 faults against
# 4,100); one minute of the paper scene (scripts/bench_estimator.py, `fused`): 28-34 ms at
# 4096, 23-25 ms at 8192 and 16384
BATCH_CHUNK = 8192


@dataclass(frozen=True)
class CandidateTrace:
    """Both candidates for the samples in contact of one push (``trace=True``).

    ``force_n``: |F_o| after the conventional low-pass; ``rate_n_s``: the differentiated force
    magnitude (paper Fig. 3, its sign is the motion); points (3, n) in the desk frame with
    their validity and 1-σ uncertainty: P_er from the force, P_ed from its derivative.
    """

    t: np.ndarray
    force_n: np.ndarray
    rate_n_s: np.ndarray
    force_point: np.ndarray
    force_valid: np.ndarray
    force_sigma_m: np.ndarray
    diff_point: np.ndarray
    diff_valid: np.ndarray
    diff_sigma_m: np.ndarray
    fast_point: np.ndarray  # from the fast (detection) low-pass: the third `fused` candidate
    fast_valid: np.ndarray
    fast_sigma_m: np.ndarray

    @classmethod
    def concat(cls, traces: list[CandidateTrace]) -> CandidateTrace:
        """Join the traces of several pushes."""
        names = [f for f in cls.__dataclass_fields__]
        if not traces:
            z = np.zeros(0)
            none = np.zeros((3, 0))
            return cls(
                z, z, z, none, z.astype(bool), z, none, z.astype(bool), z, none, z.astype(bool), z
            )
        return cls(**{n: np.concatenate([getattr(tr, n) for tr in traces], axis=-1) for n in names})


class ContactEstimator:
    """Streaming contact estimator for one desk: the stages of the module docstring, wired.

    ``push(t, wrench)`` takes k samples (k ≥ 0): ``t`` (k,) seconds, ``wrench`` (k, S, 6) in
    each sensor's own frame, and returns a :class:`ContactBlock` for exactly those samples.
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
        self.sample_rate_hz = profile.sample_rate_hz
        #: how far the located points run behind a moving finger: the force low-pass's
        #: delay (the gesture engine carries a swipe's end on by it)
        self.position_delay_s = self.stage_settings.position_delay_s
        self.notices = NoticeList()  # bounded: see NoticeList
        # each surface's normal, for the shear of a located sample (ContactBlock.shear)
        self._normals = np.array([f.surface.normal for f in self.stage_settings.frames])
        self._normal_lists: list[list[float]] = self._normals.tolist()
        # (by surface index; -1, not located, reads the last: masked where used)
        self._desk_xy = np.array([f.desk_xy for f in self.stage_settings.frames])
        self._second_finger_on = settings.second_finger
        self.reset()

    def reset(self) -> None:
        """Forget everything: filters, zero and contact state (a new run)."""
        s = self.stage_settings
        self.samples = SampleStage(s, self.notices)
        self.inertia = (
            None if self.inertia_settings is None else InertiaStage(self.inertia_settings)
        )
        self.filters = FilterBank(s, self.notices)
        self.zeroing = ZeroStage(s, self.notices)
        self.detector = TouchDetector(s)
        self.candidates = CandidateStage(s)
        self._accel_missing = False  # in a spell of samples without accelerometer readings
        self.second_finger = SecondFingerStage(self.profile) if self._second_finger_on else None

    def use_second_finger(self, on: bool) -> None:
        """Run the second-finger stage (:mod:`.multitouch`) from the next sample on, or stop
        it: on when a layout binds a gesture that reads a second finger, whatever the
        profile's ``second_finger`` says. Turned on, it starts afresh; asked for what it
        already does, nothing changes."""
        if on != self._second_finger_on:
            self._second_finger_on = on
            self.second_finger = SecondFingerStage(self.profile) if on else None

    def retare(self) -> None:
        """Forget the zero and take it again over the next ``tare_s`` of a still desk (as at
        the start); the filters keep their state, so no transient follows. Contacts are
        reported again once the new zero is set."""
        s = self.stage_settings
        self.zeroing = ZeroStage(s, self.notices)
        self.detector = TouchDetector(s)
        self.candidates = CandidateStage(s)  # its covariances come from the new tare's noise

    @property
    def tared(self) -> bool:
        return self.zeroing.state.zero is not None

    @property
    def zero(self) -> np.ndarray | None:
        """The current zero of [F_o; M_o] (6,), or None before the tare."""
        zero = self.zeroing.state.zero
        return None if zero is None else zero.copy()

    def push(
        self, t: np.ndarray, wrench: np.ndarray, accel: np.ndarray | None = None
    ) -> ContactBlock:
        """Estimate contacts for k more samples. See the class docstring.

        ``accel`` (k, A): the desk's accelerometer readings (its profile's columns, m/s²),
        used only when the profile has an accelerometer; without them such a desk's samples
        are estimated uncompensated and flagged ``FLAG_NO_ACCEL``."""
        t = np.asarray(t, dtype=float).reshape(-1)
        # (k, C) raw channels; (k, S, 6) for a desk of six-axis sensors
        wrench = self.profile.flat_channels(wrench)
        if len(wrench) != len(t):
            raise ValueError(
                f"{len(t)} sample times but {len(wrench)} samples for desk {self.profile.name!r}"
            )
        k = len(t)
        if self.inertia is not None:
            accel = self.inertia.check(accel, k)
        else:
            accel = None  # a desk without an accelerometer: nothing changes
        if k == 0:
            return ContactBlock.empty()
        if k == 1:
            one = self._push_one(float(t[0]), wrench, accel)
            if one is not None:
                return one
        block = ContactBlock.blank(t)
        noticed = self.notices.total
        # a long block goes through in pieces: the same output (streaming equals batch), but
        # each piece's arrays stay in the CPU caches between the stages
        for a in range(0, k, BATCH_CHUNK):
            piece = slice(a, a + BATCH_CHUNK)
            self._push(
                t[piece],
                wrench[piece],
                None if accel is None else accel[piece],
                block.take(piece) if k > BATCH_CHUNK else block,
            )
        if self.notices.total - noticed > 1:  # in time order, however the stages found them
            new = self.notices.since(noticed)
            self.notices[len(self.notices) - len(new) :] = sorted(new, key=lambda n: n.t)
        return block

    def _push(
        self, t: np.ndarray, wrench: np.ndarray, accel: np.ndarray | None, block: ContactBlock
    ) -> None:
        """The stages for one block, written into ``block`` (blank, see ContactBlock.blank)."""
        flags, raw = self.samples.process(t, wrench)
        if self.inertia is not None:
            flags |= self.inertia.process(raw, accel)
            self._note_accelerometer(float(t[0]), accel is not None)
        block.flags[:] = flags
        started = self.samples.state.last_good is not None
        lp, det, diff, det_slope, release = self.filters.process(t, raw, flags, started)
        segments = self.zeroing.process(t, lp.real, raw, flags)
        self._update_covariances()
        self._contacts(block, t, flags, lp, det, diff, det_slope, release, segments)
        if self.second_finger is not None:
            self.second_finger.process(raw, block)

    def _note_accelerometer(self, t: float, given: bool) -> None:
        """A warning when a desk with an accelerometer gets samples without its readings (a
        recording without its columns, a source that does not pass them): they are estimated
        uncompensated, and only the ``no_accel`` flag would say so. Once per spell."""
        if given or self._accel_missing:
            self._accel_missing = not given
            return
        self._accel_missing = True
        assert self.inertia_settings is not None
        add_notice(
            self.notices,
            t,
            "no_accel",
            f"no accelerometer readings ({', '.join(self.inertia_settings.columns)}) come with "
            f"the samples of desk {self.profile.name!r}: its sway is not compensated (the "
            "samples are flagged no_accel)",
            logging.WARNING,
        )

    def _update_covariances(self) -> None:
        """The candidates' covariances: made at the tare, and made again when a channel's
        resolution step learned from the readings is new or has shrunk (resolution.py)."""
        noise = self.zeroing.state.noise
        resolution = self.samples.resolution
        if noise is not None and (resolution.changed() or self.candidates.covs is None):
            self.candidates.covs = Covariances.of(self.stage_settings, noise, resolution.used)

    def _push_one(
        self, t: float, wrench: np.ndarray, accel: np.ndarray | None
    ) -> ContactBlock | None:
        """One sample on the common path through each stage's single-sample twin, with plain
        floats where numpy's per-call cost would dominate. None where the sample needs the
        general path: before the tare, in trace mode, with a separate low-pass for the
        differentiated force, and for a bad sample, a gap or an unusable accelerometer
        reading."""
        s = self.stage_settings
        zero = self.zeroing
        if self.trace or zero.state.zero is None or not s.shared_lp:
            return None
        inertial = None
        if self.inertia is not None:  # before any stage's state moves on
            inertial = self.inertia.wrench_one(None if accel is None else accel[0])
            if inertial is None:
                return None
        raw_a = self.samples.process_one(t, wrench)
        if raw_a is None:
            return None
        if inertial is not None:
            raw_a = raw_a - inertial
        self._update_covariances()
        raw = raw_a.tolist()
        lp, det, diff, det_slope, release = self.filters.process_one(raw)
        # the zero before this sample: one set where it ends a window applies from the next on
        z, zero_t, resting = zero.state.zero_list, zero.state.zero_t, zero.state.resting
        zero.process_one(t, [v.real for v in lp], raw)
        if s.det_full:
            fast = [det[i].real - z[i] for i in range(3)] + [
                det[i].imag - z[i + 3] for i in range(3)
            ]
        else:
            fast = [det[i] - z[i] for i in range(3)]
        in_contact, mag, slope = self.detector.process_one(fast, det_slope, release)
        block = _single_block(t, in_contact, mag, self.second_finger is not None)
        if in_contact:
            block.resting[0] = resting
            wrench6 = [lp[i].real - z[i] for i in range(3)] + [
                lp[i].imag - z[i + 3] for i in range(3)
            ]
            d6 = [d.real for d in diff] + [d.imag for d in diff]
            inv = 1.0 / mag if mag > 0 else 1.0
            block.phase[0] = phase_of(slope, s)
            cf, cd, cq, f_mag, motion = self.candidates.process_one(
                wrench6, d6, fast, inv, t - zero_t
            )
            chosen, source = select_one(cf, cd, cq, f_mag, motion, s)
            if chosen is not None:
                emit_one(block, chosen, source, s.frames)
                n = self._normal_lists[chosen[0]]
                into = fast[0] * n[0] + fast[1] * n[1] + fast[2] * n[2]
                block.shear[0] = shear_ratio_one(into, mag)
                if self._desk_xy[chosen[0]]:
                    block.drag_x[0] = into * n[0] - fast[0]
                    block.drag_y[0] = into * n[1] - fast[1]
        if self.second_finger is not None:
            self.second_finger.push_one(raw_a, block)
        return block

    def _contacts(
        self,
        block: ContactBlock,
        t: np.ndarray,
        flags: np.ndarray,
        lp: np.ndarray,
        det: np.ndarray,
        diff: np.ndarray,
        det_slope: np.ndarray,
        release: np.ndarray,
        segments: ZeroSegments,
    ) -> None:
        """Contact, phase and position of each sample, from the filtered wrenches."""
        s = self.stage_settings
        tared_zero = ~np.isnan(segments[1][0])
        if not tared_zero.any():
            block.flags |= FLAG_NOT_TARED
            return
        # (wrenches packed: force + 1j·moment; the low-passed one is tared in place)
        fast, age, tared, resting = subtract_zero(t, det, lp, segments, s.det_full)
        f_det = fast.real if s.det_full else fast
        block.flags[~tared] |= FLAG_NOT_TARED
        f_det_mag = np.sqrt(np.einsum("ik,ik->k", f_det, f_det))
        all_tared = bool(tared.all())
        if all_tared:
            block.force_n[:] = f_det_mag
        else:
            np.copyto(block.force_n, f_det_mag, where=tared)
        slope = slope_along(f_det, det_slope, f_det_mag)
        block.in_contact[:] = self.detector.process(
            f_det, f_det_mag, slope_along(f_det, release, f_det_mag), None if all_tared else tared
        )
        np.logical_and(resting, block.in_contact, out=block.resting)
        # candidates only for good samples in contact (a bad one keeps the contact state but
        # has no position of its own); they are the costly part
        idx = np.flatnonzero(block.in_contact & ((flags & BAD_SAMPLE) == 0))
        if len(idx) == 0:
            return
        f_det_at = np.take(f_det, idx, axis=1)
        f_det_mag_at = f_det_mag[idx]
        inv_mag = 1.0 / np.where(f_det_mag_at > 0, f_det_mag_at, 1.0)
        # the phase from the fast path's slope, which does not wait for the 166 ms window
        block.phase[idx] = phases_of(slope[idx], s)
        cands = self.candidates.process(
            unpacked_at(lp, idx),
            np.take(diff, idx, axis=1),
            unpacked_at(fast, idx) if s.method == "fused" or s.trace else None,
            f_det_at,
            inv_mag,
            f_det_mag_at,
            age[idx] ** 2,
        )
        if self.trace:
            self.traces.append(_trace(t[idx], cands, s))
        select(block, idx, cands, s)
        # the shear of each located sample, from the fast force and its surface's normal
        located = block.located[idx]
        if located.any():
            if len(self._normals) == 1:
                normal = self._normals[0][:, None]
            else:  # (a sample not located has surface -1: any normal, left out below)
                normal = self._normals[block.surface[idx]].T
            into = np.einsum("ik,ik->k", f_det_at, normal)
            shear = shear_ratio(into, f_det_mag_at)
            block.shear[idx] = shear if located.all() else np.where(located, shear, 0.0)
            # the drag along a horizontal board: the force along it, the finger's way (F is
            # the desk's reaction); its x and y are the desk's
            on_board = located & self._desk_xy[block.surface[idx]]
            if on_board.any():
                block.drag_x[idx] = np.where(on_board, into * normal[0] - f_det_at[0], 0.0)
                block.drag_y[idx] = np.where(on_board, into * normal[1] - f_det_at[1], 0.0)


def _trace(t: np.ndarray, cands: Candidates, s: EstimatorSettings) -> CandidateTrace:
    """Every candidate of the samples in contact (before `fused` narrows them)."""
    cf, cd, cq = cands.force, cands.diff, cands.fast
    assert cf is not None and cd is not None and cq is not None and cands.rate is not None
    return CandidateTrace(
        t=t,
        force_n=cands.f_mag,
        rate_n_s=cands.rate,
        force_point=cf.points(s.frames),
        force_valid=cf.valid.copy(),
        force_sigma_m=cf.sigma(),
        diff_point=cd.points(s.frames),
        diff_valid=cd.valid.copy(),
        diff_sigma_m=cd.sigma(),
        fast_point=cq.points(s.frames),
        fast_valid=cq.valid.copy(),
        fast_sigma_m=cq.sigma(),
    )


def _single_block(t: float, in_contact: bool, force_n: float, second: bool) -> ContactBlock:
    """A one-sample block, not yet located: copies of a blank one (a copy of a one-element
    array costs a fraction of making one with ``np.full``). Without the second-finger stage
    (``second`` False) nothing writes its fields: they share read-only zeros."""
    own = _BLANK_ONE if second else _BLANK_ONE[:_FIRST_SECOND]
    block = ContactBlock(
        *(a.copy() for a in own),
        *(() if second else _NO_SECOND),
        resting=_NOT_RESTING.copy(),
        shear=_NO_SHEAR.copy(),
        drag_x=_NO_SHEAR.copy(),
        drag_y=_NO_SHEAR.copy(),
    )
    block.t[0] = t
    block.in_contact[0] = in_contact
    block.force_n[0] = force_n
    return block


#: the fields of a blank one-sample ContactBlock, in order
_BLANK_ONE = (
    np.zeros(1),  # t
    np.zeros(1, bool),  # in_contact
    np.zeros(1, bool),  # located
    np.full(1, -1, np.int16),  # surface
    np.zeros(1),  # x
    np.zeros(1),  # y
    np.zeros(1),  # z
    np.zeros(1),  # force_n
    np.zeros(1, np.int8),  # source
    np.zeros(1, np.int8),  # phase
    np.full(1, UNCERTAINTY_CAP_M),  # sigma_m
    np.zeros(1, np.uint8),  # flags
    np.zeros(1, bool),  # located2
    np.zeros(1),  # x2
    np.zeros(1),  # y2
    np.zeros(1),  # z2
)
_FIRST_SECOND = 12  # where the second finger's fields begin
_NOT_RESTING = np.zeros(1, bool)  # the fields after the second finger's: resting, ...
_NO_SHEAR = np.zeros(1)  # ... shear, drag_x and drag_y
_NO_SECOND = tuple(a.copy() for a in _BLANK_ONE[_FIRST_SECOND:])
for _array in _NO_SECOND:
    _array.flags.writeable = False


def estimate(profile: DeskProfile, recording: Recording, method: str | None = None) -> ContactBlock:
    """Batch estimation of a whole recording (identical to streaming it in any blocks)."""
    if recording.sensor_names != profile.sensor_names:
        raise ValueError(
            f"the recording's sensors {recording.sensor_names} are not the desk's "
            f"{profile.sensor_names}"
        )
    accel = accelerometer_readings(profile, recording.extra)
    return ContactEstimator(profile, method=method).push(recording.t, recording.wrench, accel)
