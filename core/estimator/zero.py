"""Stage 3, the zero: tare, drift and objects (none of them for readings that come zeroed,
``estimation.zeroed``: the zero is 0 from the first sample on).

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

The kernel (:func:`hapticdesk.estimator.kernel_zero.window_add`) fills each window and, at
its end, measures it — the spread of its low-passed force, its mean wrench, its share of bad
samples. Once tared, a window that is not still only ends a still run and the resting, and
a still window of the idle desk (nothing absorbed, a load under ``drift_max_n``) goes on with
the still run and follows the drift: the kernel judges both itself (logging the idle ones for
the yardsticks, :meth:`ZeroStage.read_idle_windows`); any other leaves the loop
(``EV_WINDOW``) and :meth:`ZeroStage.window` judges it here, on plain floats.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence

import numpy as np

from hapticdesk.estimator import kernel_slots as slots
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
    """The current zero and the tare / stillness state machine.

    What the kernel shares — the zero, when it was set, the window count, the still run and
    its means, whether the load is resting, how many objects are absorbed — lives in the
    kernel's state arrays (``kernel_slots.S_*``, ``kernel_slots.J_*``: the kernel judges the
    idle desk's windows itself); the properties here read and write them there. The rest is
    Python's: the tare's windows, the idle desk's yardsticks (from the windows the kernel logs), the
    object rule's windows and the objects absorbed."""

    def __init__(self, sf: np.ndarray, si: np.ndarray, pi: np.ndarray) -> None:
        self._sf, self._si = sf, si
        self._ring_at, self._ring = int(pi[slots.I_SO_STILL_MEANS]), int(pi[slots.I_STILL_RING])
        self.noise: np.ndarray | None = None  # (6, 6) measured at the tare
        self.tare_raw: list[np.ndarray] = []
        self.tare_means: list[list[float]] = []
        self.tare_spreads: list[float] = []
        # the idle desk's unsteadiness: the IDLE_QUANTILE of its recent window spreads, and of
        # how far its window means strayed over an object's wait (``n_object`` windows) in a row
        self.quiet_spread = 0.0
        self.quiet_wander = 0.0
        self.idle_spreads: list[float] = []  # the last IDLE_WINDOWS of each
        self.idle_wanders: list[float] = []
        self.idle_tail: list[tuple[int, list[float]]] = []  # (window index, force mean) of the last
        # the last windows of an object run (spread, force mean less the zero), and whether
        # their means stayed within the allowed wander
        self.object_windows: list[tuple[float, tuple[float, float, float]]] = []
        self.object_resting = False
        # objects absorbed into the zero, last on top: (the zero before it, its weight |F|)
        self.objects: list[tuple[list[float], float]] = []

    @property
    def tared(self) -> bool:
        return bool(self._si[slots.J_TARED])

    @property
    def zero(self) -> np.ndarray | None:
        """The zero (6,), None before the tare."""
        return self._sf[slots.S_ZERO : slots.S_ZERO + 6].copy() if self.tared else None

    @property
    def zero_list(self) -> list[float]:
        return list(self._sf[slots.S_ZERO : slots.S_ZERO + 6].tolist())

    @property
    def zero_t(self) -> float:
        """When the zero was last set, for the drift since then."""
        return float(self._sf[slots.S_ZERO_T])

    @property
    def zero_version(self) -> int:
        """How many times the zero was set."""
        return int(self._si[slots.J_ZERO_VERSION])

    def set_zero(self, zero: np.ndarray | list[float], t: float) -> None:
        self._sf[slots.S_ZERO : slots.S_ZERO + 6] = [float(z) for z in zero]
        self._sf[slots.S_ZERO_T] = t
        self._si[slots.J_TARED] = 1
        self._si[slots.J_ZERO_VERSION] += 1

    def _int(name: int) -> property:  # type: ignore[misc]  # (a slot of the kernel's si)
        return property(
            lambda self: int(self._si[name]),
            lambda self, value: self._si.__setitem__(name, int(value)),
        )

    #: windows judged on (each before the tare, the still ones after); windows ended so far,
    #: still or not (which are in a row); still windows in a row with the load not moved; windows
    #: the load has been as still as the idle desk
    windows_seen = _int(slots.J_WINDOWS_SEEN)
    window_index = _int(slots.J_WINDOW_INDEX)
    still_run = _int(slots.J_STILL_RUN)
    object_run = _int(slots.J_OBJECT_RUN)
    del _int

    @property
    def resting(self) -> bool:
        """The load has been as still as an object put down since the last window judged
        (``object_pending``): recognizers wait for the verdict before a hold fires."""
        return bool(self._si[slots.J_RESTING])

    @resting.setter
    def resting(self, value: bool) -> None:
        self._si[slots.J_RESTING] = int(value)

    @property
    def still_lo(self) -> list[float]:
        """The still run's lowest window mean of the force less the zero (3)."""
        return list(self._sf[slots.S_STILL_LO : slots.S_STILL_LO + 3].tolist())

    @still_lo.setter
    def still_lo(self, values: list[float]) -> None:
        self._sf[slots.S_STILL_LO : slots.S_STILL_LO + 3] = values

    @property
    def still_hi(self) -> list[float]:
        return list(self._sf[slots.S_STILL_HI : slots.S_STILL_HI + 3].tolist())

    @still_hi.setter
    def still_hi(self, values: list[float]) -> None:
        self._sf[slots.S_STILL_HI : slots.S_STILL_HI + 3] = values

    def clear_still_means(self) -> None:
        self._si[slots.J_STILL_COUNT] = 0

    def push_still_mean(self, mean: list[float]) -> None:
        """The mean wrench (6) of one more still window of the run."""
        si, pos = self._si, int(self._si[slots.J_STILL_POS])
        at = self._ring_at + 6 * pos
        self._sf[at : at + 6] = mean
        si[slots.J_STILL_POS] = pos + 1 if pos + 1 < self._ring else 0
        si[slots.J_STILL_COUNT] = min(int(si[slots.J_STILL_COUNT]) + 1, self._ring)

    def last_still_means(self, n: int) -> list[list[float]]:
        """The means of the run's last ``n`` still windows (fewer if the run is shorter)."""
        n = min(n, int(self._si[slots.J_STILL_COUNT]))
        pos = int(self._si[slots.J_STILL_POS])
        rows = []
        for j in range(n):
            at = self._ring_at + 6 * ((pos - n + j) % self._ring)
            rows.append(self._sf[at : at + 6].tolist())
        return rows

    def count_objects(self) -> None:
        """How many objects are absorbed, for the kernel (it judges no window while any is:
        their lift is Python's)."""
        self._si[slots.J_OBJECTS] = len(self.objects)

    @property
    def object_pending(self) -> bool:
        """After a window: an object run is under way and its windows stay within the allowed
        wander, so the load is resting until the verdict."""
        return self.tared and self.object_run > 0 and self.object_resting


class ZeroStage:
    """Judges the windows of the zero (the tare, drift, objects), one at a time."""

    def __init__(
        self,
        settings: EstimatorSettings,
        notices: list[Notice],
        sf: np.ndarray,
        si: np.ndarray,
        pi: np.ndarray,
    ) -> None:
        """``sf``, ``si``, ``pi``: the kernel's state and parameters (see ZeroState)."""
        self.settings = settings
        self.notices = notices
        self.state = ZeroState(sf, si, pi)
        self._log_at, self._log = int(pi[slots.I_SO_IDLE_LOG]), int(pi[slots.I_IDLE_LOG])
        self.window_s = settings.window / settings.sample_rate_hz
        # the idle desk's wander is measured over as many windows as an object waits
        self.wander_windows = max(2, settings.n_object)
        if settings.user.zeroed:
            # the readings come zeroed: the kernel sets the zero to 0 at the first good sample
            # and judges no window; the noise is the profile's (Covariances.of)
            self.state.noise = np.zeros((6, 6))

    def window(
        self, spread: float, bad: bool, mean: list[float], raw: np.ndarray, t_end: float
    ) -> None:
        """Judge one window the kernel leaves to Python (every one before the tare; after,
        a still one whose load is no idle desk's, or with an object absorbed): the spread of
        its low-passed force (its largest axis, over means of ``still_block`` samples),
        whether over a tenth of it was held over (bad samples, a gap), its mean wrench (6),
        its wrench (6, w) (read only before the tare; kept then) and its last sample's time.
        The kernel counted it (``window_index``)."""
        st = self.state
        self.read_idle_windows()
        self._window_done(spread, bad, mean, raw, t_end)
        st.resting = st.object_pending
        st.count_objects()

    def read_idle_windows(self) -> None:
        """The idle windows the kernel judged since the last call join the yardsticks, in
        order (the last ``IDLE_WINDOWS`` and a wander's tail are all that count: the kernel
        keeps that many)."""
        si, sf = self.state._si, self.state._sf
        n = int(si[slots.J_IDLE_LOG_N])
        if n == 0:
            return
        st = self.state
        if n == self._log:  # (maybe more were logged: those the log kept are the ones that count)
            st.idle_spreads, st.idle_wanders = [], []
        pos = int(si[slots.J_IDLE_LOG_POS])
        for j in range(n):
            at = self._log_at + 5 * ((pos - n + j) % self._log)
            spread, fx, fy, fz, index = sf[at : at + 5].tolist()
            self._idle_window(spread, [fx, fy, fz], int(index), yardsticks=False)
        self._yardsticks()  # (once for the lot: only the last windows' count)
        si[slots.J_IDLE_LOG_N] = 0

    def _window_done(
        self, spread: float, bad: bool, mean: list[float], raw: np.ndarray, t_end: float
    ) -> None:
        """Advance the tare / stillness state machine by one window (plain floats: it is hot)."""
        st, s = self.state, self.settings.user
        st.windows_seen += 1
        if not st.tared:
            self._tare_window(spread, bad, mean, raw, t_end)
            return
        # (a tared window the kernel leaves to Python is still: see ZeroStage.window)
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
            st.clear_still_means()
        st.still_lo, st.still_hi = lo, hi
        st.still_run += 1
        st.push_still_mean(mean)
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
            held = st.last_still_means(len(st.object_windows))
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

    def _idle_window(
        self, spread: float, mean: list[float], index: int, yardsticks: bool = True
    ) -> None:
        """One more window of the idle desk (``index``: its number, see ``window_index``):
        its spread, and how far the force means of the last ``wander_windows`` in a row
        strayed, update the yardsticks of stillness (``yardsticks`` False: the caller
        updates them once after several windows)."""
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
        if yardsticks:
            self._yardsticks()

    def _yardsticks(self) -> None:
        """The quiet spread and wander: quantiles of the idle desk's last windows."""
        st = self.state
        if st.idle_spreads:
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
            recent = st.last_still_means(n_drift)
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
