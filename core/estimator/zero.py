"""Stage 3, the zero: tare, drift and objects (none of them for readings that come zeroed,
``estimation.zeroed``: the zero is 0 from the first sample on).

An automatic tare over the first ``tare_s`` of a quiet desk (:mod:`.tare`; refused with a
notice and retried while the desk is not quiet); the zero then follows sensor drift whenever
the idle desk rests for ``drift_settle_s``, and a load held perfectly still for ``settle_s``
(an object put down) becomes part of it, with a notice. A load as still as the idle desk
(:mod:`.yardsticks`: no finger holds that still, fingers tremble and wander) joins it
already after ``object_settle_s`` (:mod:`.still_objects`), the zero then the mean over the
windows that showed it still; when the load later steps back to the zero from before an
object joined it (the object lifted), that zero is restored at once. The desk is judged on
windows of ``WINDOW_S``; a zero decided at the end of a window applies from the next sample
on.

The kernel (:func:`hapticdesk.estimator.kernel_zero.window_add`) fills each window and, at
its end, measures it — the spread of its low-passed force, its mean wrench, its share of bad
samples. Once tared, a window that is not still only ends a still run and the resting, and
a still window of the idle desk (nothing absorbed, a load under ``drift_max_n``) goes on with
the still run and follows the drift: the kernel judges both itself (logging the idle ones for
the yardsticks, :meth:`ZeroStage.read_idle_windows`); any other leaves the loop
(``EV_WINDOW``) and :meth:`ZeroStage.window` judges it here. It runs a few times a minute,
so its code and data are out of the CPU's caches each time (a line of Python then costs
about as much as a numpy call does warm): it reads the kernel's fixed state slots once as
lists, judges on them, and writes them back in one go.
"""

from __future__ import annotations

import logging
import math

import numpy as np

from hapticdesk.estimator.kernel_slots import (
    I_IDLE_LOG,
    I_SO_IDLE_LOG,
    I_SO_STILL_MEANS,
    I_SO_WIN_RAW,
    I_STILL_RING,
    I_WINDOW,
    J_IDLE_LOG_N,
    J_IDLE_LOG_POS,
    J_OBJECT_RUN,
    J_OBJECTS,
    J_RESTING,
    J_STILL_COUNT,
    J_STILL_POS,
    J_STILL_RUN,
    J_TARED,
    J_WIN_BADS,
    J_WINDOW_INDEX,
    J_WINDOWS_SEEN,
    J_ZERO_VERSION,
    N_SF_FIXED,
    N_SI_FIXED,
    S_STILL_HI,
    S_STILL_LO,
    S_WIN_MEAN,
    S_WIN_SPREAD,
    S_WIN_T_END,
    S_ZERO,
    S_ZERO_T,
)
from hapticdesk.estimator.notices import Notice, add_notice, log
from hapticdesk.estimator.settings import EstimatorSettings
from hapticdesk.estimator.still_objects import AbsorbedObject, ObjectRun, lifted
from hapticdesk.estimator.tare import Tare
from hapticdesk.estimator.yardsticks import Yardsticks
from hapticdesk.estimator.zero_state import ZeroState


class ZeroStage:
    """Judges the windows of the zero (the tare, drift, objects), one at a time.

    Its methods read and write the kernel's fixed state slots as two lists, ``floats``
    (``sf``, ``S_*``) and ``ints`` (``si``, ``J_*``)."""

    def __init__(
        self,
        settings: EstimatorSettings,
        notices: list[Notice],
        sf: np.ndarray,
        si: np.ndarray,
        pi: np.ndarray,
    ) -> None:
        """``sf``, ``si``, ``pi``: the kernel's state and parameters."""
        self.settings = settings
        self.notices = notices
        self._sf, self._si = sf, si
        user = settings.user
        self.state = ZeroState(
            sf,
            si,
            Tare(settings.n_tare, user.tare_quiet_n),
            # the idle desk's wander is measured over as many windows as an object waits
            Yardsticks(max(2, settings.n_object)),
            ObjectRun(settings.n_object, user.drift_max_n),
        )
        # the kernel's layout and the settings a window's end reads, as plain values
        self._window = int(pi[I_WINDOW])
        self._raw_at = int(pi[I_SO_WIN_RAW])
        self._ring_at, self._ring = int(pi[I_SO_STILL_MEANS]), int(pi[I_STILL_RING])
        self._log_at, self._log = int(pi[I_SO_IDLE_LOG]), int(pi[I_IDLE_LOG])
        self.window_s = settings.window / settings.sample_rate_hz
        self._still_n = user.still_n
        self._drift_max_n = user.drift_max_n
        self._follows_drift = user.drift_settle_s > 0
        self._n_settle = settings.n_settle
        if user.zeroed:
            # the readings come zeroed: the kernel sets the zero to 0 at the first good sample
            # and judges no window; the noise is the profile's (Covariances.of)
            self.state.noise = np.zeros((6, 6))

    def window(self) -> bool:
        """Judge the window the kernel just ended and left to Python (``S_WIN_*``: every one
        before the tare; after, a still one whose load is no idle desk's, or with an object
        absorbed); True when it completed the tare. The kernel counted it
        (``window_index``)."""
        sf, si = self._sf, self._si
        floats, ints = sf[:N_SF_FIXED].tolist(), si[:N_SI_FIXED].tolist()
        if ints[J_IDLE_LOG_N]:
            self.read_idle_windows()
            ints[J_IDLE_LOG_N] = 0
        tared = ints[J_TARED]
        ints[J_WINDOWS_SEEN] += 1
        if tared:
            self._still_window(floats, ints)
        else:
            self._tare_window(floats, ints)
        st = self.state
        # the load rests, as an object put down would, until the verdict
        ints[J_RESTING] = int(ints[J_TARED] and ints[J_OBJECT_RUN] > 0 and st.object_run.resting)
        ints[J_OBJECTS] = len(st.objects)
        sf[:N_SF_FIXED] = floats
        si[:N_SI_FIXED] = ints
        return not tared and ints[J_TARED] == 1

    def read_idle_windows(self) -> None:
        """The idle windows the kernel judged since the last call join the yardsticks, in
        order (the last ``IDLE_WINDOWS`` and a wander's tail are all that count: the kernel
        keeps that many)."""
        si, sf = self._si, self._sf
        n = int(si[J_IDLE_LOG_N])
        if n == 0:
            return
        yardsticks = self.state.yardsticks
        if n == self._log:  # (maybe more were logged: those the log kept are the ones that count)
            yardsticks.forget()
        pos = int(si[J_IDLE_LOG_POS])
        for j in range(n):
            at = self._log_at + 5 * ((pos - n + j) % self._log)
            # (the kernel's log entry: kernel_zero._idle_window)
            spread, fx, fy, fz, index = sf[at : at + 5].tolist()
            yardsticks.add(spread, [fx, fy, fz], int(index))
        yardsticks.update()  # (once for the lot: only the last windows' count)
        si[J_IDLE_LOG_N] = 0

    def _still_window(self, floats: list[float], ints: list[int]) -> None:
        """Advance the stillness state machine by one still window of the tared desk (a
        tared window the kernel leaves to Python is still)."""
        st = self.state
        mean, t_end = floats[S_WIN_MEAN : S_WIN_MEAN + 6], floats[S_WIN_T_END]
        if st.objects and lifted(st.objects[-1], mean, self._still_n):
            self._lifted(floats, ints, t_end)
            return
        f = (
            mean[0] - floats[S_ZERO],
            mean[1] - floats[S_ZERO + 1],
            mean[2] - floats[S_ZERO + 2],
        )
        self._still_run_on(floats, ints, f, mean)
        load = math.sqrt(f[0] ** 2 + f[1] ** 2 + f[2] ** 2)
        spread = floats[S_WIN_SPREAD]
        if load < self._drift_max_n:  # the idle desk: a window of its own unsteadiness
            st.yardsticks.add(spread, mean[:3], ints[J_WINDOW_INDEX])
            st.yardsticks.update()
            if self._follows_drift:
                ints[J_OBJECT_RUN] = 0
                self._follow_drift(floats, ints, load, t_end)
                return
        verdict = st.object_run.still(ints[J_OBJECT_RUN], spread, f, load, st.yardsticks)
        ints[J_OBJECT_RUN] = verdict.run
        if not verdict.is_object and ints[J_STILL_RUN] % self._n_settle:
            return
        st.objects.append(AbsorbedObject(floats[S_ZERO : S_ZERO + 6], load))
        if verdict.is_object:
            # the new zero: the mean over the windows that showed it an object, not the last
            # one alone (a desk swaying at 4–5 Hz moves a 0.2 s window's mean moment enough
            # to put a press 2–3 mm off); their means are within the allowed wander
            held = self._last_still_means(ints, len(st.object_run.windows))
            zero = [math.fsum(c) / len(held) for c in zip(*held, strict=True)]
            _set_zero(floats, ints, zero, t_end)
            held_s = len(held) * self.window_s
        else:
            _set_zero(floats, ints, mean, t_end)
            held_s = self.settings.user.settle_s
        ints[J_STILL_RUN] = ints[J_OBJECT_RUN] = 0
        self._absorbed(f, load, held_s, t_end)

    def _still_run_on(
        self, floats: list[float], ints: list[int], f: tuple[float, float, float], mean: list[float]
    ) -> None:
        """The still run goes on with this window (its force less the zero ``f``; its mean
        wrench ``mean`` into the kernel's ring), or starts again here if the load moved."""
        if ints[J_STILL_RUN]:
            width = 0.0
            for lane in range(3):
                lo = floats[S_STILL_LO + lane] = min(floats[S_STILL_LO + lane], f[lane])
                hi = floats[S_STILL_HI + lane] = max(floats[S_STILL_HI + lane], f[lane])
                width = max(width, hi - lo)
            if width >= self._still_n:
                ints[J_STILL_RUN] = 0  # the load moved: a new still run starts here
        if ints[J_STILL_RUN] == 0:
            floats[S_STILL_LO : S_STILL_LO + 3] = floats[S_STILL_HI : S_STILL_HI + 3] = f
            ints[J_STILL_COUNT] = 0
        ints[J_STILL_RUN] += 1
        pos = ints[J_STILL_POS]
        at = self._ring_at + 6 * pos
        self._sf[at : at + 6] = mean
        ints[J_STILL_POS] = pos + 1 if pos + 1 < self._ring else 0
        ints[J_STILL_COUNT] = min(ints[J_STILL_COUNT] + 1, self._ring)

    def _last_still_means(self, ints: list[int], n: int) -> list[list[float]]:
        """The means of the run's last ``n`` still windows (fewer if the run is shorter)."""
        n = min(n, ints[J_STILL_COUNT])
        rows = []
        for j in range(n):
            at = self._ring_at + 6 * ((ints[J_STILL_POS] - n + j) % self._ring)
            rows.append(self._sf[at : at + 6].tolist())
        return rows

    def _lifted(self, floats: list[float], ints: list[int], t_end: float) -> None:
        """A still window back at the zero from before the last absorbed object: it was
        lifted; restore that zero at once (it does not wait for ``settle_s``)."""
        before, weight = self.state.objects.pop()
        _set_zero(floats, ints, before, t_end)
        ints[J_STILL_RUN] = ints[J_OBJECT_RUN] = 0
        add_notice(
            self.notices,
            t_end,
            "lifted",
            f"the {weight:.1f} N load absorbed earlier was lifted: the zero from before it "
            "is restored",
        )

    def _follow_drift(
        self, floats: list[float], ints: list[int], load: float, t_end: float
    ) -> None:
        """An idle, still desk: what is left is sensor drift; follow it (often, so a drifting
        zero never builds up between touches)."""
        n_drift = self.settings.n_drift
        if ints[J_STILL_RUN] >= n_drift:
            recent = self._last_still_means(ints, n_drift)
            columns = zip(*recent, strict=True)
            _set_zero(floats, ints, [math.fsum(c) / len(recent) for c in columns], t_end)
            ints[J_STILL_RUN] = 0
            log.debug("t=%.3f s: zero drift of %.3f N followed", t_end, load)

    def _absorbed(
        self, f: tuple[float, float, float], load: float, held_s: float, t_end: float
    ) -> None:
        """Tell what became part of the zero: an object, or a small drift."""
        s = self.settings.user
        if load >= s.contact_force_n:
            up = self.settings.up()
            sign = "put on" if f[0] * up[0] + f[1] * up[1] + f[2] * up[2] >= 0 else "taken off"
            add_notice(
                self.notices,
                t_end,
                "absorbed",
                f"a still load of {load:.1f} N (an object {sign} the desk?) held for "
                f"{held_s:g} s became part of the zero",
            )
        else:
            add_notice(
                self.notices,
                t_end,
                "drift",
                f"a still load of {load:.2f} N became part of the zero",
            )

    def _tare_window(self, floats: list[float], ints: list[int]) -> None:
        """Before the tare: collect quiet windows (:mod:`.tare`); tare over ``tare_s`` of
        them, and the tare's windows are the idle desk's first yardsticks."""
        st, s = self.state, self.settings.user
        t_end = floats[S_WIN_T_END]
        raw = self._sf[self._raw_at : self._raw_at + 6 * self._window].reshape(6, self._window)
        bad = ints[J_WIN_BADS] / self._window > 0.1
        taken = st.tare.add(floats[S_WIN_SPREAD], bad, floats[S_WIN_MEAN : S_WIN_MEAN + 6], raw)
        if taken is None:
            if ints[J_WINDOWS_SEEN] % st.tare.n_tare == 0:
                add_notice(
                    self.notices,
                    t_end,
                    "tare_refused",
                    f"tare refused: the desk was not quiet in the {s.tare_s:g} s before "
                    f"t = {t_end:.2f} s (is someone touching or leaning on it?); retrying",
                    logging.WARNING,
                )
            return
        _set_zero(floats, ints, taken.zero, t_end)
        st.noise = taken.noise
        st.yardsticks.restart()
        for i, window in enumerate(taken.windows):  # (in a row, this one the last)
            index = ints[J_WINDOW_INDEX] - (len(taken.windows) - 1 - i)
            st.yardsticks.add(float(window.spread), window.force, index)
        st.yardsticks.update()
        add_notice(self.notices, t_end, "tare", f"tared over {s.tare_s:g} s of a quiet desk")


def _set_zero(floats: list[float], ints: list[int], zero: list[float], t: float) -> None:
    """A new zero (6) from time ``t`` on, into the kernel's fixed slots as lists."""
    floats[S_ZERO : S_ZERO + 6] = zero
    floats[S_ZERO_T] = t
    ints[J_TARED] = 1
    ints[J_ZERO_VERSION] += 1
