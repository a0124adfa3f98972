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

The kernel (:mod:`hapticdesk.estimator.kernel_zero`) fills each window, measures it at its
end and, once tared, judges it whole — the still run, the drift, the yardsticks, the object
rule, a lift — so a window's end never leaves the compiled loop then (issue 29: in Python
that cost 60–120 µs of a push, its code and data cold each time). Python keeps what is
rare or worded: the windows before the tare (:meth:`ZeroStage.window`), and the notices of
a zero changed for an object, with the objects absorbed (:meth:`ZeroStage.objects_changed`:
the kernel keeps the last one's zero and weight for its lift, Python the ones below it).
"""

from __future__ import annotations

import logging

import numpy as np

from hapticdesk.estimator.kernel_slots import (
    EV_LIFTED,
    I_SO_WIN_RAW,
    I_WINDOW,
    J_OBJ_HELD,
    J_TARED,
    J_WIN_BADS,
    J_WINDOW_INDEX,
    J_WINDOWS_SEEN,
    J_ZERO_VERSION,
    S_OBJ_F,
    S_OBJ_WEIGHT,
    S_OBJ_ZERO,
    S_WIN_MEAN,
    S_WIN_SPREAD,
    S_WIN_T_END,
    S_ZERO,
    S_ZERO_T,
)
from hapticdesk.estimator.kernel_yardsticks import tare_yardsticks
from hapticdesk.estimator.notices import Notice, add_notice
from hapticdesk.estimator.settings import EstimatorSettings
from hapticdesk.estimator.still_objects import AbsorbedObject
from hapticdesk.estimator.tare import Tare
from hapticdesk.estimator.zero_state import ZeroState


class ZeroStage:
    """The zero's Python side: the windows before the tare, and the notices of the objects
    the kernel absorbed into the zero or saw lifted (reading and writing the kernel's state
    ``sf``, ``si``)."""

    def __init__(
        self,
        settings: EstimatorSettings,
        notices: list[Notice],
        pf: np.ndarray,
        pi: np.ndarray,
        sf: np.ndarray,
        si: np.ndarray,
    ) -> None:
        """``pf``, ``pi``: the kernel's parameters; ``sf``, ``si``: its state."""
        self.settings = settings
        self.notices = notices
        self._pf, self._pi, self._sf, self._si = pf, pi, sf, si
        user = settings.user
        self.state = ZeroState(sf, si, Tare(settings.n_tare, user.tare_quiet_n))
        self._window = int(pi[I_WINDOW])
        self._raw_at = int(pi[I_SO_WIN_RAW])
        self.window_s = settings.window / settings.sample_rate_hz
        if user.zeroed:
            # the readings come zeroed: the kernel sets the zero to 0 at the first good sample
            # and judges no window; the noise is the profile's (Covariances.of)
            self.state.noise = np.zeros((6, 6))

    def window(self) -> bool:
        """Judge a window before the tare (the kernel leaves only those to Python: S_WIN_*,
        counted in ``window_index``): collect quiet windows (:mod:`.tare`); tare over
        ``tare_s`` of them, and the tare's windows are the idle desk's first yardsticks. True
        when it completed the tare."""
        st, s = self.state, self.settings.user
        sf, si = self._sf, self._si
        si[J_WINDOWS_SEEN] += 1
        t_end = float(sf[S_WIN_T_END])
        # (the kernel keeps a window's samples side by side: (w, 6); the tare copies them (6, w))
        raw = sf[self._raw_at : self._raw_at + 6 * self._window].reshape(self._window, 6).T
        bad = si[J_WIN_BADS] / self._window > 0.1
        mean = sf[S_WIN_MEAN : S_WIN_MEAN + 6].tolist()
        taken = st.tare.add(float(sf[S_WIN_SPREAD]), bad, mean, raw)
        if taken is None:
            if si[J_WINDOWS_SEEN] % st.tare.n_tare == 0:
                why = (
                    # (NaN, saturated, out of order or stuck: a desk that is still but whose
                    # readings are not whole was told to stop leaning on it)
                    "its readings were not usable (over a tenth of the last window's "
                    "samples NaN, saturated, out of order, stuck or after a gap)"
                    if bad
                    else "the desk was not quiet (is someone touching or leaning on it?)"
                )
                add_notice(
                    self.notices,
                    t_end,
                    "tare_refused",
                    f"tare refused in the {s.tare_s:g} s before t = {t_end:.2f} s: {why}; retrying",
                    logging.WARNING,
                )
            return False
        sf[S_ZERO : S_ZERO + 6] = taken.zero
        sf[S_ZERO_T] = t_end
        si[J_TARED] = 1
        si[J_ZERO_VERSION] += 1
        st.noise = taken.noise
        last = int(si[J_WINDOW_INDEX])  # (the tare's windows in a row, this one the last)
        rows = [
            [float(w.spread), *w.force, last - (len(taken.windows) - 1 - i)]
            for i, w in enumerate(taken.windows)
        ]
        tare_yardsticks(np.array(rows, dtype=np.float64), self._pf, self._pi, sf, si)
        add_notice(self.notices, t_end, "tare", f"tared over {s.tare_s:g} s of a quiet desk")
        return True

    def objects_changed(self, events: int) -> None:
        """The kernel absorbed a still load into the zero (``EV_ABSORBED``) or saw the last
        object lifted and restored the zero from before it (``EV_LIFTED``): keep the objects
        below the last (the kernel holds the last one's, S_OBJ_*) and tell it."""
        sf, si = self._sf, self._si
        t_end = float(sf[S_WIN_T_END])
        objects = self.state.objects
        if events & EV_LIFTED:
            weight = objects.pop().weight_n
            if objects:  # the one below is the last now: the kernel watches for its lift
                sf[S_OBJ_ZERO : S_OBJ_ZERO + 6] = objects[-1].zero_before
                sf[S_OBJ_WEIGHT] = objects[-1].weight_n
            add_notice(
                self.notices,
                t_end,
                "lifted",
                f"the {weight:.1f} N load absorbed earlier was lifted: the zero from before "
                "it is restored",
            )
            return
        load = float(sf[S_OBJ_WEIGHT])
        objects.append(AbsorbedObject(sf[S_OBJ_ZERO : S_OBJ_ZERO + 6].tolist(), load))
        held = int(si[J_OBJ_HELD])
        held_s = held * self.window_s if held else self.settings.user.settle_s
        self._absorbed(sf[S_OBJ_F : S_OBJ_F + 3].tolist(), load, held_s, t_end)

    def _absorbed(self, f: list[float], load: float, held_s: float, t_end: float) -> None:
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
