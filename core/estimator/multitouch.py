"""A second finger: detected from the change of wrench when it lands while the first holds.

One resultant force gives one point: two fingers pressing straight down are, to the sensors,
one finger at their centre of pressure (a vertical force's wrench has no free moment, so the
residual of the single-point model cannot tell them apart). What does tell: when the second
finger lands while the first holds, the *change* of the wrench over the landing is itself the
wrench of a single point force, the second finger's (the differentiated wrench, paper eqs.
8/12: ΔM = P₂ × ΔF). Located like any wrench (eqs. 1–2 on the surface's plane), it lies
centimetres away from where the first finger is; a finger pressing harder gives a change
located where it already is, and a finger starting to swipe one that is mostly sideways (its
drag), not pressing down.

Where the second finger is: the change located as it stands mixes in the first finger's own
change of force (two vertical forces fix only the line through both fingers: any point on it
explains one change with some split of the force). Taken about the first finger's point P₁,
though, the first finger's force has no moment at all, so n × (ΔM − P₁ × ΔF) = (P₂ − P₁)·f₂
follows the second finger's force alone, while the normal force n·ΔF = Δf₁ + f₂ holds both.
Over a window from before the landing to after it, the first finger's part is fitted as a
quadratic in time (its drift; a finger still pressing in bends it: a straight line left the
second finger 28 mm off at the median there, 12 mm with the bend) and the second's as
1/|P₂ − P₁| times the first quantity (:func:`fit_second_point`): a linear least-squares fit
of four numbers.

:class:`SecondFingerStage` is the estimator's stage (run by :class:`ContactEstimator` when
``second_finger`` is on): it sets ``FLAG_MULTI`` on the contact samples from the landing to the
contact's end and reports the second finger's point (``x2``, ``y2``, ``z2``, ``located2``) once
its fit window is over. It carries its state between pushes, so any split of the input gives
the same output.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np
from scipy.signal import sosfilt, sosfilt_zi

from hapticdesk.estimator.contacts import FLAG_GAP, FLAG_MULTI, MULTI_LAG_S, ContactBlock
from hapticdesk.estimator.filters import butter_lowpass_sos
from hapticdesk.estimator.geometry import SurfaceFrame
from hapticdesk.files.profile import DeskProfile

LOWPASS_HZ = 12.0  # the wrench is smoothed this much before differencing (noise vs lag)
LAG_S = MULTI_LAG_S  # the change of wrench is taken over this long (a finger lands in ≈0.1 s)
LANDING_S = 0.18  # the second finger's place is fitted over this long after its landing
MIN_STEP_N = 2.0  # the force must rise at least this much over LAG_S ...
MIN_STEP_SHARE = 0.1  # ... and at least this share of the force before it
# ... pressing down: its normal part at least this share of it (a swipe's drag is sideways)
MIN_NORMAL_SHARE = 0.8
# How far from the first finger the change must be located. A single press's own change
# strays from it as the press rocks the desk: by at most 2.8 cm on the paper desk and 3.0 cm
# on the unseen 6-sensor desk of scripts/tap_accuracy.py, but 6.7 cm on its tall, soft
# 4-sensor desk (300 single touches each), where a fixed 3 cm took 26 % of single touches for
# two fingers. So the desk's own stray is measured: each press without a second finger gives
# the farthest its changes landed (its stray); the minimum is STRAY_MARGIN times the upper
# quartile of the last STRAY_PRESSES presses' strays (the quartile leaves out the few pairs
# missed as single), within [MIN_APART_FLOOR_M, MIN_APART_CAP_M]; until STRAY_MIN_PRESSES
# presses are in, MIN_APART_M (enough on all three desks). Only presses under the minimum
# are measured, so a minimum learnt low would never rise if presses later strayed further
# (a heavier hand, a monitor put on the desk): when more than MAX_FLAGGED_SHARE of the last
# STRAY_PRESSES contacts with a change were flagged, the stage starts learning afresh
# from MIN_APART_M (a missed pair is better than a made-up one)
MIN_APART_M = 0.07
MIN_APART_FLOOR_M = 0.03  # a finger's own width and the fit's spread
MIN_APART_CAP_M = 0.15
STRAY_MARGIN = 1.7  # the quartile to the largest stray: 1.56, 1.43, 1.63 on the three desks
STRAY_PRESSES = 32
STRAY_MIN_PRESSES = 8
MAX_FLAGGED_SHARE = 0.5
MAX_FIRST_MOVE_M = 0.005  # the first finger held this still over the lag before (no swipe)
#: single samples that cannot end a landing wait in a queue of up to this many for one
#: vectorised pass (SecondFingerStage.push_one)
QUEUE_MAX = 256


def locate_change(
    d_wrench: np.ndarray, origin: np.ndarray, normal: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Where the line of action of each wrench (k, 6) [F; M] meets the plane (origin, normal):
    the point P with M = P × F on it (paper eqs. 1–2). Returns points (k, 3) and whether the
    force crosses the plane at all (not parallel to it)."""
    f, m = d_wrench[:, :3], d_wrench[:, 3:]
    f2 = np.einsum("ij,ij->i", f, f)
    ok = f2 > 0
    safe_f2 = np.where(ok, f2, 1.0)
    foot = np.cross(f, m) / safe_f2[:, None]  # the line's point closest to the moment centre
    across = f @ normal
    ok &= np.abs(across) > 1e-3 * np.sqrt(safe_f2)
    lam = ((origin - foot) @ normal) / np.where(ok, across, 1.0)
    return foot + lam[:, None] * f, ok


def fit_second_point(
    first: np.ndarray, normal: np.ndarray, wrench: np.ndarray
) -> np.ndarray | None:
    """The second finger's point from the smoothed wrench (m, 6) over a window that starts
    before its landing (evenly sampled), the first finger at ``first`` (3,) on the plane with
    ``normal`` (see the module docstring). None when the window does not pin it down."""
    d = wrench - wrench[0]
    d_force, d_moment = d[:, :3], d[:, 3:]
    lever = np.cross(normal, d_moment - np.cross(first, d_force))  # (P₂ − P₁)·f₂
    size = np.linalg.norm(lever, axis=1)
    j = int(np.argmax(size))
    if size[j] <= 0:
        return None
    toward = lever[j] / size[j]
    along = lever @ toward  # |P₂ − P₁|·f₂
    normal_force = d_force @ normal  # Δf₁ + f₂
    tau = np.arange(len(d), dtype=float)  # samples, not the times: they may be bad
    design = np.stack([along, np.ones_like(tau), tau, tau * tau], axis=1)
    (inv_distance, *_), *_ = np.linalg.lstsq(design, normal_force, rcond=None)
    if not inv_distance > 0:
        return None
    return first + toward / inv_distance


@dataclass
class _Track:
    """The contact fields the detection looks back on (the last 2·lag samples are kept)."""

    x: np.ndarray
    y: np.ndarray
    z: np.ndarray
    located: np.ndarray
    surface: np.ndarray
    in_contact: np.ndarray
    force_n: np.ndarray

    @classmethod
    def of(cls, block: ContactBlock) -> _Track:
        return cls(*(getattr(block, name) for name in cls.__dataclass_fields__))

    def then(self, block: ContactBlock) -> _Track:
        """This track followed by ``block``'s samples."""
        return _Track(
            *(
                np.concatenate([getattr(self, n), getattr(block, n)])
                for n in self.__dataclass_fields__
            )
        )

    def last(self, count: int) -> _Track:
        """A copy of the last ``count`` samples."""
        return _Track(*(getattr(self, n)[-count:].copy() for n in self.__dataclass_fields__))


@dataclass
class _Landing:
    """A second finger's landing in the open contact, while its fit window fills."""

    first: np.ndarray  # (3,) the first finger's point before the landing
    wrench: list[np.ndarray]  # pieces (m, 6) of the smoothed wrench since the window's start
    need: int  # samples still to come before the fit


class SecondFingerStage:
    """Flags a second finger on the contact samples and locates it (module docstring)."""

    def __init__(self, profile: DeskProfile) -> None:
        fs = profile.sample_rate_hz
        self.sos = butter_lowpass_sos(LOWPASS_HZ, fs)
        self.lag = max(1, round(LAG_S * fs))
        self.landing_n = max(1, round(LANDING_S * fs))
        self.surface = profile.surfaces[0] if profile.surfaces else None
        if self.surface is not None:
            self.origin = np.asarray(self.surface.origin, float)
            self.normal = np.asarray(self.surface.normal, float)
            self.frame = SurfaceFrame.of(self.surface)
        self.zi: np.ndarray | None = None
        # the last 2·lag samples (smoothed wrench, the contacts), for the next push's lags
        self.history: tuple[np.ndarray, _Track] | None = None
        self.in_contact = False  # the last sample was in contact ...
        self.flagged = False  # ... with a second finger found in it
        self.landing: _Landing | None = None  # its fit window, while it fills
        self.second: np.ndarray | None = None  # its fitted point
        # single samples waiting for one pass: their blocks, raw wrenches and (t, x, y, z,
        # force_n, located, in_contact, surface, gap)
        self.queue: list[ContactBlock] = []
        self.queued_raw = np.empty((QUEUE_MAX, 6))
        self.queued = np.empty((9, QUEUE_MAX))
        # the last 2·lag + 1 samples' (force, x, y, located) for push_one's cheap test
        self.recent: deque[tuple[float, float, float, bool]] = deque(maxlen=2 * self.lag + 1)
        # the contact of the last processed sample is still open (for push_one's queue)
        self.same_contact = False
        # the desk's own stray (see MIN_APART_M): the last presses' and the open contact's
        self.strays: deque[float] = deque(maxlen=STRAY_PRESSES)
        self.flagged_contacts: deque[bool] = deque(maxlen=STRAY_PRESSES)
        self.contact_stray = 0.0
        self.min_apart_m = MIN_APART_M

    def push_one(self, raw: np.ndarray, block: ContactBlock) -> None:
        """:meth:`process` for one sample (``raw`` (6,)), the same output for any split.

        Most samples cannot change anything but the smoothing and the history: out of
        contact, in a contact whose second finger is already found (its flag and place are
        set here at once), or where no landing can end because the force did not rise by
        ``MIN_STEP_N`` over the lag after a still, located first finger. They wait in a queue
        for one vectorised pass (at most QUEUE_MAX of them); a sample that may end a landing
        (which a pressing finger's own rise also passes), the last of a landing's fit window,
        or one after a gap runs it at once, with the queue."""
        inside = bool(block.in_contact[0])
        force, x, y = float(block.force_n[0]), float(block.x[0]), float(block.y[0])
        located = bool(block.located[0])
        # out of contact counts as infinite force: no rise is measured from it
        self.recent.append((force if inside else math.inf, x, y, located))
        self.same_contact = self.same_contact and inside
        waits = self._waits(inside, block)
        j = len(self.queue)
        self.queued_raw[j] = raw
        queued = self.queued
        queued[0, j], queued[1, j], queued[2, j], queued[3, j] = block.t[0], x, y, block.z[0]
        queued[4, j], queued[5, j], queued[6, j] = force, located, inside
        queued[7, j] = block.surface[0]
        queued[8, j] = block.flags[0] & FLAG_GAP
        self.queue.append(block)
        if not waits or j + 1 >= QUEUE_MAX:
            self.flush()

    def _waits(self, inside: bool, block: ContactBlock) -> bool:
        """Whether this single sample may wait in the queue (see :meth:`push_one`); sets its
        flag and second place when the open contact already has them."""
        if block.flags[0] & FLAG_GAP:
            return False  # the stage restarts there (process)
        if not inside:
            return True
        if self.flagged and self.same_contact:  # the contact processed last is still open
            block.flags[0] |= FLAG_MULTI
            if self.landing is not None:  # each queued sample is one more of its window
                return self.landing.need > len(self.queue) + 1
            if self.second is not None:
                block.x2[0], block.y2[0], block.z2[0] = self.second
                block.located2[0] = True
            return True
        # the landing test's cheap conditions (see _landings), a little looser than it
        recent, n = self.recent, self.lag
        if len(recent) <= 2 * n:
            return True
        f_now = recent[-1][0]
        f_before, x_before, y_before, located_before = recent[n]
        _, x_earlier, y_earlier, located_earlier = recent[0]
        return not (
            located_before
            and located_earlier
            and f_now - f_before >= MIN_STEP_N
            and math.hypot(x_before - x_earlier, y_before - y_earlier)
            <= MAX_FIRST_MOVE_M * (1 + 1e-9)
        )

    def flush(self) -> None:
        """Run the queued single samples through :meth:`process` as one block; the last one's
        output is written back to its block (the others' was set by :meth:`_waits`)."""
        if not self.queue:
            return
        queue, self.queue = self.queue, []
        k = len(queue)
        t, x, y, z, force, located, inside, surface, gap = self.queued[:, :k]
        piece = ContactBlock.blank(t.copy())
        piece.x[:], piece.y[:], piece.z[:], piece.force_n[:] = x, y, z, force
        piece.located[:], piece.in_contact[:], piece.surface[:] = located, inside, surface
        piece.flags[:] = gap
        self.process(self.queued_raw[:k].T, piece)
        last = queue[-1]
        last.flags[0] |= piece.flags[-1] & FLAG_MULTI
        if piece.located2[-1]:
            last.x2[0], last.y2[0], last.z2[0] = piece.x2[-1], piece.y2[-1], piece.z2[-1]
            last.located2[0] = True

    def process(self, raw: np.ndarray, block: ContactBlock) -> None:
        """Flag and locate second fingers in ``block`` (in place) from the resultant wrench
        ``raw`` (6, k) of the same samples. At a gap in time (``FLAG_GAP``) the stage starts
        afresh, as the estimator's filters do: a change across it is no landing."""
        self.flush()
        if len(block) == 0:
            return
        gaps = np.flatnonzero(block.flags & FLAG_GAP).tolist()
        bounds = [0, *(g for g in gaps if g > 0), len(block)]
        for a, b in zip(bounds[:-1], bounds[1:], strict=True):
            if block.flags[a] & FLAG_GAP:
                self._restart()
            self._process(raw[:, a:b], block.take(slice(a, b)) if len(bounds) > 2 else block)

    def _restart(self) -> None:
        self.zi = None
        self.history = None
        self.in_contact = False
        self._end_contact()

    def _process(self, raw: np.ndarray, block: ContactBlock) -> None:
        k = len(block)
        rows = np.nan_to_num(raw.T)
        if self.zi is None:
            self.zi = sosfilt_zi(self.sos)[:, :, None] * rows[0][None, None, :]
        smooth, self.zi = sosfilt(self.sos, rows, axis=0, zi=self.zi)
        if self.history is None:
            ext_w, ext = smooth, _Track.of(block)
        else:
            ext_w = np.concatenate([self.history[0], smooth])
            ext = self.history[1].then(block)
        h = len(ext.x) - k  # the chunk's first sample in the extended arrays
        if self.surface is not None:
            change, apart = self._landings(ext_w, ext, h)
            self._runs(change, apart, ext_w, ext, h, block)
        keep = 2 * self.lag
        self.history = (ext_w[-keep:].copy(), ext.last(keep))
        self.in_contact = bool(block.in_contact[-1])
        # the single-sample push's view of the samples since: (force, x, y, located) over the
        # last 2·lag + 1 samples (force infinite out of contact) and whether this contact
        # stays open
        tail = slice(-(2 * self.lag + 1), None)
        force = np.where(ext.in_contact[tail], ext.force_n[tail], np.inf)
        self.recent = deque(
            zip(
                force.tolist(),
                ext.x[tail].tolist(),
                ext.y[tail].tolist(),
                ext.located[tail].tolist(),
                strict=True,
            ),
            2 * self.lag + 1,
        )
        self.same_contact = self.in_contact

    def _landings(self, w: np.ndarray, c: _Track, h: int) -> tuple[np.ndarray, np.ndarray]:
        """Per sample of the chunk (k,): whether the change of wrench over the lag before it
        is a single force on the board, rising and pressing down, while the first finger was
        in contact, located and still over the lag before that; and how far from the first
        finger that change lies (0 where it is no such change). A landing needs it far enough
        (:meth:`_runs`, by the desk's measured stray)."""
        assert self.surface is not None  # (the caller checks)
        n = self.lag
        k = len(c.x) - h
        out = np.zeros(k, bool)
        distance = np.zeros(k)
        now = np.arange(max(h, 2 * n), len(c.x))
        before, earlier = now - n, now - 2 * n
        force_then = c.force_n[before]
        moved = np.hypot(c.x[before] - c.x[earlier], c.y[before] - c.y[earlier])
        # the cheap conditions first: the change is located only where they hold
        maybe = (
            c.in_contact[before]
            & c.located[before]
            & c.located[earlier]
            & (c.surface[before] == 0)  # the first finger on the board, as the second
            & (c.surface[earlier] == 0)
            & (moved <= MAX_FIRST_MOVE_M)
            & c.in_contact[now]
            & (c.force_n[now] - force_then >= MIN_STEP_N)
        )
        at = np.flatnonzero(maybe)
        if len(at) == 0:
            return out, distance
        now, before, force_then = now[at], before[at], force_then[at]
        d_wrench = w[now] - w[before]
        step = np.linalg.norm(d_wrench[:, :3], axis=1)
        points, ok = locate_change(d_wrench, self.origin, self.normal)
        first = np.stack([c.x[before], c.y[before], c.z[before]], axis=1)
        apart = np.linalg.norm(points - first, axis=1)
        rel = points - self.origin  # the second finger must be on the board
        on_board = self.frame.contains(rel @ self.surface.u_axis, rel @ self.surface.v_axis)
        pressing = np.abs(d_wrench[:, :3] @ self.normal) >= MIN_NORMAL_SHARE * step
        change = ok & (step >= MIN_STEP_SHARE * force_then) & pressing & on_board
        out[now - h] = change
        distance[now - h] = np.where(change, apart, 0.0)
        return out, distance

    def _runs(
        self,
        change: np.ndarray,
        apart: np.ndarray,
        w: np.ndarray,
        c: _Track,
        h: int,
        block: ContactBlock,
    ) -> None:
        """Per contact in the chunk (few; not per sample): flag it from its first landing
        (a ``change`` at least ``min_apart_m`` ``apart``) on, fit the second finger's point
        once the window after the landing is in, and measure the stray of a press without
        one. Contact by contact, so the minimum learnt at one contact's end holds for the
        next whatever the split."""
        inside = block.in_contact.astype(np.int8)
        edges = np.diff(np.concatenate([[0], inside, [0]]))
        starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
        if not (self.in_contact and inside[0]):
            self._end_contact()  # the contact open before the chunk (if any) ended
        for a, b in zip(starts.tolist(), ends.tolist(), strict=True):
            if a > 0:
                self._end_contact()  # a new contact
            if not self.flagged:
                landing = change[a:b] & (apart[a:b] >= self.min_apart_m)
                hits = np.flatnonzero(landing)
                if len(hits) == 0:
                    if b > a:  # (fmax: a NaN never wins, whatever the split)
                        self.contact_stray = float(
                            np.fmax(self.contact_stray, np.fmax.reduce(apart[a:b]))
                        )
                    continue
                first_hit = a + int(hits[0])
                self.flagged = True
                block.flags[first_hit:b] |= FLAG_MULTI
                j = h + first_hit  # the landing's end in the extended arrays
                lo = max(0, j - 2 * self.lag)
                first = np.array([c.x[j - self.lag], c.y[j - self.lag], c.z[j - self.lag]])
                self.landing = _Landing(first, [w[lo : j + 1]], self.landing_n)
                a = first_hit + 1
            else:
                block.flags[a:b] |= FLAG_MULTI
            if self.landing is not None:
                got = min(b - a, self.landing.need)
                self.landing.wrench.append(w[h + a : h + a + got])
                self.landing.need -= got
                a += got
                if self.landing.need > 0:
                    continue
                self.second = fit_second_point(
                    self.landing.first,
                    self.normal,
                    np.concatenate(self.landing.wrench),
                )
                self.landing = None
                if self.second is not None and not self._on_board(self.second):
                    self.second = None
                a -= 1  # the fit is known at the window's last sample
            if self.second is not None and a < b:
                block.x2[a:b], block.y2[a:b], block.z2[a:b] = self.second[:, None]
                block.located2[a:b] = True
        if not inside[-1]:
            self._end_contact()

    def _on_board(self, point: np.ndarray) -> bool:
        assert self.surface is not None
        rel = point - self.origin
        return self.frame.contains_one(
            float(rel @ self.surface.u_axis), float(rel @ self.surface.v_axis)
        )

    def _end_contact(self) -> None:
        """The open contact ended: a press without a second finger adds its stray."""
        if self.flagged or self.contact_stray > 0:
            recent = self.flagged_contacts
            recent.append(self.flagged)
            if len(recent) >= STRAY_MIN_PRESSES and sum(recent) > MAX_FLAGGED_SHARE * len(recent):
                self.strays.clear()  # see MAX_FLAGGED_SHARE: learn afresh
                recent.clear()
                self.min_apart_m = MIN_APART_M
        if not self.flagged and self.contact_stray > 0:
            self.strays.append(self.contact_stray)
            if len(self.strays) >= STRAY_MIN_PRESSES:
                quartile = float(np.percentile(np.fromiter(self.strays, float), 75))
                self.min_apart_m = min(
                    max(STRAY_MARGIN * quartile, MIN_APART_FLOOR_M), MIN_APART_CAP_M
                )
        self.contact_stray = 0.0
        self.flagged = False
        self.landing = None
        self.second = None
