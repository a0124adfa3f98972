"""Stage 3, the zero: tare, drift and objects.

An automatic tare over the first ``tare_s`` of a quiet desk (refused with a notice and
retried while the desk is not quiet); the zero then follows sensor drift whenever the idle
desk rests for ``drift_settle_s``, and a load held perfectly still for ``settle_s`` (an
object put down) becomes part of it, with a notice. A load as still as the idle desk (its
windows' spread and the wander of their means, measured on the idle desk since the tare: no
finger holds that still, fingers tremble and wander) joins it already after
``object_settle_s``, the zero then the mean over the windows that showed it still; when the
load later steps back to the zero from before an object joined it (the object lifted), that
zero is restored at once. The desk is judged on windows of ``WINDOW_S``; a zero decided at
the end of a window applies from the next sample on.

The kernel (:mod:`hapticdesk.estimator.kernel`, ``_window_add``) fills each window and, at
its end, measures it — the spread of its low-passed force, its mean wrench, its share of bad
samples. Once tared, a window that is not still only ends a still run and the resting: the
kernel judges it itself (and counts it for :meth:`ZeroStage.not_still`); any other leaves
the loop (``EV_WINDOW``) and :meth:`ZeroStage.window` judges it here, on plain floats, and
the estimator hands the zero and the resting flag back to the kernel.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence

import numpy as np

from hapticdesk.estimator.notices import Notice, add_notice, log
from hapticdesk.estimator.settings import EstimatorSettings

# A load still within these multiples of the idle desk's own unsteadiness is an object, not a
# finger (fingers tremble and wander), once held for ``object_settle_s``: the windows' spreads
# (of the low-passed force; their median, none over OBJECT_SPIKE times the limit) within
# OBJECT_STILL_FACTOR of the idle desk's, and the windows' means within OBJECT_WANDER_FACTOR
# of how far the idle desk's means stray over as many windows in a row. Each yardstick is the
# median (IDLE_QUANTILE) of the idle desk's own, over the tare's windows and then every idle
# still window (the last IDLE_WINDOWS): a median of a few windows is steady, a high quantile
# of them is not. The factors are about 1.2 times the idle desk's 90th percentile over its
# median (1.3–1.6 for the spread, 1.4–2.0 for the wander on seven simulated desks of 4–6
# sensors, 8–40 kg, 4–9 Hz, 500–1200 Hz; scripts/objects_eval.py). Relative to the yardsticks,
# over 0.6 s a still object's wander is 0.59 at the median, a finger held still at 2.6–8 N's
# 6.7 (2.3 at the 10th percentile): the wander tells them apart best, as a finger's 8–12 Hz
# tremor is mostly above the low-pass. Before, one yardstick for both, the median spread of
# the tare's five windows, was noisy (a later idle window's median spread was 0.56–0.99 of it
# from desk to desk) and the wrong scale for the wander (a 500 Hz desk's idle means stray
# about as far as its windows spread): 193 of 336 objects joined the zero within 1 s on those
# desks, now 306; fingers held still 3 s taken for one: 6 of 252, now 4.
OBJECT_STILL_FACTOR = 1.8
OBJECT_WANDER_FACTOR = 2.0
# ... or within this share of the load, whichever is more: a finger's force wanders by a few
# per cent of itself, so a heavy load that strays this little is no finger even on a desk
# whose own idle wander is larger (a tall desk swaying at 4.5 Hz: its 0.2 s means stray 0.05 N)
HEAVY_WANDER_SHARE = 0.004
# and a window's spread within this share of the load: a finger's 8–12 Hz tremor (1.5 % RMS)
# leaves about 1 % of its force in a window's spread after the 4.8 Hz low-pass
HEAVY_SPREAD_SHARE = 0.003
# one window of the run may spread up to this many times the limit (the desk's own noise now
# and then) while the run's median spread is within it
OBJECT_SPIKE = 1.3
# once a load rests (its means within the allowed wander), it rests on until they stray this
# many times the allowed wander (or a window is not still): on seven desks a 0.3 kg cup's
# means strayed up to 1.46 times it before the verdict (a long press fired on 5 of 42 cups),
# a finger's mostly far past it within a few windows
OBJECT_RESTING_KEEP = 1.6
# a load lighter than this (about half a kilogram) may be a finger resting lightly, which can
# be as still as a cup for 0.6 s: it waits one window more. On the seven desks (12 seeds):
# fingers held still at 2.6–4 N taken for an object 13 of 168 -> 4, objects of 0.15–0.3 kg
# within 1 s 158 of 168 -> 138 (touch_release_eval's light long presses on its unseen desk:
# 2 phantom releases -> 0)
LIGHT_LOAD_N = 5.0
IDLE_QUANTILE = 0.5
IDLE_WINDOWS = 64
# below this spread at the tare the readings are synthetic (no real sensor is that quiet):
# there is no yardstick for stillness, and objects wait for ``settle_s``
OBJECT_NOISE_FLOOR_N = 1e-4
# a lift restores the zero from before the object when the load is back within this share
# of the object's weight (or ``still_n``, whichever is larger) of that zero
LIFT_TOLERANCE = 0.2


class ZeroState:
    """The current zero and the tare / stillness state machine."""

    def __init__(self) -> None:
        self.zero: np.ndarray | None = None  # (6,), None before the tare
        self.zero_list: list[float] = []  # the same as plain floats
        self.zero_t = 0.0  # when the zero was last set, for the drift since then
        self.zero_version = 0  # how many times it was set (the kernel's copy follows it)
        # the load has been as still as an object put down since the last window judged
        # (``object_pending``): recognizers wait for the verdict before a hold fires
        self.resting = False
        self.noise: np.ndarray | None = None  # (6, 6) measured at the tare
        self.tare_raw: list[np.ndarray] = []
        self.tare_means: list[list[float]] = []
        self.windows_seen = 0
        self.still_run = 0
        self.still_lo: list[float] = [0.0, 0.0, 0.0]
        self.still_hi: list[float] = [0.0, 0.0, 0.0]
        self.still_means: list[list[float]] = []
        self.tare_spreads: list[float] = []
        # the idle desk's unsteadiness: the IDLE_QUANTILE of its recent window spreads, and of
        # how far its window means strayed over an object's wait (``n_object`` windows) in a row
        self.quiet_spread = 0.0
        self.quiet_wander = 0.0
        self.idle_spreads: list[float] = []  # the last IDLE_WINDOWS of each
        self.idle_wanders: list[float] = []
        self.idle_tail: list[tuple[int, list[float]]] = []  # (window index, force mean) of the last
        self.window_index = 0  # windows judged so far, still or not (which are in a row)
        self.object_run = 0  # windows the load has been as still as the idle desk
        # the last of them judged (spread, force mean less the zero), and whether their means
        # stayed within the allowed wander
        self.object_windows: list[tuple[float, tuple[float, float, float]]] = []
        self.object_resting = False
        # objects absorbed into the zero, last on top: (the zero before it, its weight |F|)
        self.objects: list[tuple[list[float], float]] = []

    @property
    def object_pending(self) -> bool:
        """After a window: an object run is under way and its windows stay within the allowed
        wander, so the load is resting until the verdict."""
        return self.zero is not None and self.object_run > 0 and self.object_resting

    def set_zero(self, zero: np.ndarray | list[float], t: float) -> None:
        self.zero_list = [float(z) for z in zero]
        self.zero = np.array(self.zero_list)
        self.zero_t = t
        self.zero_version += 1


class ZeroStage:
    """Judges the windows of the zero (the tare, drift, objects), one at a time."""

    def __init__(self, settings: EstimatorSettings, notices: list[Notice]) -> None:
        self.settings = settings
        self.notices = notices
        self.state = ZeroState()
        self.window_s = settings.window / settings.sample_rate_hz
        # the idle desk's wander is measured over as many windows as an object waits
        self.wander_windows = max(2, settings.n_object)

    def not_still(self, windows: int) -> None:
        """Once tared, ``windows`` more windows that were not still (the kernel judges those
        itself): each ends a still run and the resting."""
        st = self.state
        st.window_index += windows
        st.still_run = st.object_run = 0
        st.resting = False

    def window(
        self, spread: float, bad: bool, mean: list[float], raw: np.ndarray, t_end: float
    ) -> None:
        """Judge one window: the spread of its low-passed force (its largest axis, over means
        of ``still_block`` samples), whether over a tenth of it was held over (bad samples,
        a gap), its mean wrench (6), its wrench (6, w) (read only before the tare; kept
        then) and its last sample's time. Once tared, a window that is not still only ends
        a still run and the resting."""
        st, s = self.state, self.settings.user
        st.window_index += 1
        if st.zero is not None and (bad or spread >= s.still_n):
            self.not_still(0)  # (this one is counted above)
            return
        self._window_done(spread, bad, mean, raw, t_end)
        st.resting = st.object_pending

    def _window_done(
        self, spread: float, bad: bool, mean: list[float], raw: np.ndarray, t_end: float
    ) -> None:
        """Advance the tare / stillness state machine by one window (plain floats: it is hot)."""
        st, s = self.state, self.settings.user
        st.windows_seen += 1
        if st.zero is None:
            self._tare_window(spread, bad, mean, raw, t_end)
            return
        if bad or spread >= s.still_n:  # (only before the tare: see window)
            st.still_run = st.object_run = 0
            return
        if st.objects and self._lifted(mean, t_end):
            return
        z = st.zero_list
        f = (mean[0] - z[0], mean[1] - z[1], mean[2] - z[2])
        if st.still_run:
            lo = [min(a, b) for a, b in zip(st.still_lo, f, strict=True)]
            hi = [max(a, b) for a, b in zip(st.still_hi, f, strict=True)]
            if max(b - a for a, b in zip(lo, hi, strict=True)) >= s.still_n:
                st.still_run = 0  # the load moved: a new still run starts here
        if st.still_run == 0:
            lo, hi = list(f), list(f)
            st.still_means = []
        st.still_lo, st.still_hi = lo, hi
        st.still_run += 1
        st.still_means.append(mean)
        load = math.sqrt(f[0] ** 2 + f[1] ** 2 + f[2] ** 2)
        if load < s.drift_max_n:  # the idle desk: a window of its own unsteadiness
            self._idle_window(spread, mean[:3], st.window_index)
        if load < s.drift_max_n and s.drift_settle_s > 0:
            st.object_run = 0
            self._follow_drift(load, t_end)
            return
        fast = self._object_still(spread, f, load)
        if not fast and st.still_run % self.settings.n_settle:
            return
        st.objects.append((st.zero_list, load))
        if fast:
            # the new zero: the mean over the windows that showed it an object, not the last
            # one alone (a desk swaying at 4–5 Hz moves a 0.2 s window's mean moment enough
            # to put a press 2–3 mm off); their means are within the allowed wander
            held = st.still_means[-len(st.object_windows) :]
            st.set_zero([math.fsum(c) / len(held) for c in zip(*held, strict=True)], t_end)
            held_s = len(held) * self.window_s
        else:
            st.set_zero(mean, t_end)
            held_s = s.settle_s
        st.still_run = 0
        st.object_run = 0
        self._absorbed(f, load, held_s, t_end)

    def _object_still(self, spread: float, f: tuple[float, float, float], load: float) -> bool:
        """One more window of a load as still as the idle desk: is it held long enough to be
        an object? (A finger's tremor and slow wander move it more.) Judged on the last
        ``n_object`` windows (one more under LIGHT_LOAD_N): their means within the allowed
        wander of each other, their upper median spread within the limit, and none over
        OBJECT_SPIKE times it (one noisy window of the desk's own does not start the wait
        again). Also notes whether the load is resting: its windows so far as still as an
        object's."""
        st, n_object = self.state, self.settings.n_object
        limit = max(OBJECT_STILL_FACTOR * st.quiet_spread, HEAVY_SPREAD_SHARE * load)
        # (a load lighter than drift_max_n is drift, also when drift is not followed)
        light = load < self.settings.user.drift_max_n
        if (
            not n_object
            or light
            or st.quiet_spread < OBJECT_NOISE_FLOOR_N
            or spread >= OBJECT_SPIKE * limit
        ):
            st.object_run = 0
            return False
        if st.object_run == 0:
            st.object_windows = []
        st.object_run += 1
        wait = n_object + 1 if load < LIGHT_LOAD_N else n_object
        st.object_windows.append((spread, f))
        del st.object_windows[:-wait]
        wander = _wander([window for _, window in st.object_windows])
        allowed = max(OBJECT_WANDER_FACTOR * st.quiet_wander, HEAVY_WANDER_SHARE * load)
        still = wander < allowed  # (a load that strays is no object, for now)
        # the resting flag, once up in this run, drops only past OBJECT_RESTING_KEEP times the
        # allowed wander: a cup's means can stray just over it for a window or two while its
        # landing rings out, and a hold would fire on that one window
        keep = OBJECT_RESTING_KEEP if st.object_resting and st.object_run > 1 else 1.0
        st.object_resting = wander < keep * allowed
        spreads = sorted(window_spread for window_spread, _ in st.object_windows)
        return still and st.object_run >= wait and spreads[len(spreads) // 2] < limit

    def _idle_window(self, spread: float, mean: list[float], index: int) -> None:
        """One more window of the idle desk (``index``: its number, see ``window_index``):
        its spread, and how far the force means of the last ``wander_windows`` in a row
        strayed, update the yardsticks of stillness."""
        st = self.state
        st.idle_spreads.append(spread)
        tail = [(i, m) for i, m in st.idle_tail if index - i < self.wander_windows]
        tail.append((index, mean))
        st.idle_tail = tail
        if len(tail) == self.wander_windows:  # (that many in a row: none was left out)
            st.idle_wanders.append(_wander([m for _, m in tail]))
        for values in (st.idle_spreads, st.idle_wanders):
            if len(values) > IDLE_WINDOWS:
                del values[0]
        st.quiet_spread = _quantile(st.idle_spreads, IDLE_QUANTILE)
        if st.idle_wanders:
            st.quiet_wander = _quantile(st.idle_wanders, IDLE_QUANTILE)

    def _lifted(self, mean: list[float], t_end: float) -> bool:
        """A still window back at the zero from before the last absorbed object: it was lifted;
        restore that zero at once (it does not wait for ``settle_s``)."""
        st, s = self.state, self.settings.user
        before, weight = st.objects[-1]
        off = math.sqrt(sum((mean[i] - before[i]) ** 2 for i in range(3)))
        if off >= max(s.still_n, LIFT_TOLERANCE * weight):
            return False
        st.objects.pop()
        st.set_zero(before, t_end)
        st.still_run = 0
        st.object_run = 0
        add_notice(
            self.notices,
            t_end,
            "lifted",
            f"the {weight:.1f} N load absorbed earlier was lifted: the zero from before it "
            "is restored",
        )
        return True

    def _follow_drift(self, load: float, t_end: float) -> None:
        """An idle, still desk: what is left is sensor drift; follow it (often, so a drifting
        zero never builds up between touches)."""
        st, n_drift = self.state, self.settings.n_drift
        if st.still_run >= n_drift:
            recent = st.still_means[-n_drift:]
            columns = zip(*recent, strict=True)
            st.set_zero([math.fsum(c) / len(recent) for c in columns], t_end)
            st.still_run = 0
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

    def _tare_window(
        self, spread: float, bad: bool, mean: list[float], raw: np.ndarray, t_end: float
    ) -> None:
        """Before the tare: collect quiet windows; tare over ``tare_s`` of them."""
        st, s, n_tare = self.state, self.settings.user, self.settings.n_tare
        if not bad and spread < s.tare_quiet_n:
            st.tare_raw.append(raw.copy())
            st.tare_means.append(mean[:3])
            st.tare_spreads.append(spread)
            if len(st.tare_raw) > n_tare:
                st.tare_raw.pop(0)
                st.tare_means.pop(0)
                st.tare_spreads.pop(0)
            if np.ptp(np.array(st.tare_means), axis=0).max() >= s.tare_quiet_n:
                # each window was quiet, but the load moved between them: start again here
                st.tare_raw, st.tare_means, st.tare_spreads = (
                    [st.tare_raw[-1]],
                    [mean[:3]],
                    [spread],
                )
        else:
            st.tare_raw, st.tare_means, st.tare_spreads = [], [], []
        if len(st.tare_raw) >= n_tare:
            samples = np.concatenate(st.tare_raw, axis=1)
            st.set_zero(samples.mean(axis=1), t_end)
            st.noise = np.atleast_2d(np.cov(samples))
            st.idle_spreads, st.idle_wanders, st.idle_tail = [], [], []
            for i, (spread_i, mean_i) in enumerate(
                zip(st.tare_spreads, st.tare_means, strict=True)
            ):  # (the tare's windows are in a row, this one the last)
                index = st.window_index - (len(st.tare_spreads) - 1 - i)
                self._idle_window(float(spread_i), mean_i, index)
            st.tare_raw, st.tare_means, st.tare_spreads = [], [], []
            add_notice(self.notices, t_end, "tare", f"tared over {s.tare_s:g} s of a quiet desk")
        elif st.windows_seen % n_tare == 0:
            add_notice(
                self.notices,
                t_end,
                "tare_refused",
                f"tare refused: the desk was not quiet in the {s.tare_s:g} s before "
                f"t = {t_end:.2f} s (is someone touching or leaning on it?); retrying",
                logging.WARNING,
            )


def _wander(means: Sequence[Sequence[float]]) -> float:
    """How far window means strayed: the widest range of any component over ``means`` (one
    measure for an object's windows and the idle desk's yardstick, so they compare)."""
    return max(max(c) - min(c) for c in zip(*means, strict=True))


def _quantile(values: list[float], q: float) -> float:
    """The ``q`` quantile of ``values`` by nearest rank (plain floats: a window's end is hot)."""
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))]
