"""Accuracy against ground truth: contact error at touch, hold and release, and delays.

Every method is judged on the same samples, chosen from the truth alone (never from what a
method reports), so a method cannot look better by reporting less:

- a *press* is a run of samples with the true normal force ≥ ``contact_force_n`` (2 N);
- its *touch* part runs from that crossing until the true force first reaches half its peak,
  its *release* part from the last time it is above half its peak until the estimator ends
  the contact (its fast path, the same for every method; at most 0.5 s after the true fall)
  — what a user sees after lift-off counts too, judged against the last point touched; its
  *hold* part lies in between;
- the error of a sample is the distance between the reported point and the true point (in
  3-D when the truth has ``true_z``, so a point on an upright panel is judged in its height
  too), over the samples a method locates; ``coverage`` says which share of the press it located;
- methods that locate different samples are compared twice more, at equal coverage: on the
  samples every compared method locates (``common``), and at fixed times after the true
  touch-down and before the true release (:data:`AT_MS`), where a point a method does not
  report counts as a miss (an infinite error), so reporting less never looks better.

Delays: touch-down is the first sample the estimator says "in contact" after the true force
crosses 2 N upward; release the first sample it says "not in contact" after the true force
falls below 2 N. Both in ms, per press.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from hapticdesk.estimator.contacts import ContactBlock

#: times after the true touch-down and before the true release at which every method is judged
AT_MS = (10, 20, 50, 100)
MISS_MM = 1e9  # the error a point not reported counts as


@dataclass(frozen=True)
class Press:
    """Sample indices of one true press: [start, stop) with its touch/hold/release split."""

    start: int
    half_up: int  # first sample at ≥ half the peak
    half_down: int  # first sample after the last one at ≥ half the peak
    stop: int
    peak_n: float


@dataclass
class PhaseErrors:
    """Errors (m) of the located samples of one phase, and the share located."""

    errors_m: np.ndarray
    coverage: float

    def stats_mm(self) -> dict[str, float | None]:
        e = self.errors_m * 1e3
        if len(e) == 0:
            return {
                "median_mm": None,
                "p95_mm": None,
                "max_mm": None,
                "mean_mm": None,
                "std_mm": None,
            }
        return {
            "median_mm": float(np.median(e)),
            "p95_mm": float(np.percentile(e, 95)),
            "max_mm": float(e.max()),
            "mean_mm": float(e.mean()),
            "std_mm": float(e.std()),
        }


@dataclass
class Accuracy:
    """Per-phase errors and per-press delays of one estimator run against the truth."""

    touch: PhaseErrors
    hold: PhaseErrors
    release: PhaseErrors
    touch_delay_ms: np.ndarray  # per press; NaN-free (missed presses are counted instead)
    release_delay_ms: np.ndarray
    first_point_delay_ms: np.ndarray  # first located sample after the true crossing
    presses: int
    missed: int  # presses the estimator never called a contact
    false_touches: int  # contacts reported where no press was
    #: per phase, the errors on the samples every compared method locates (``common``)
    common: dict[str, np.ndarray] = field(default_factory=dict)
    #: "touch+20" / "release-20" -> per press, the error at that time (inf: not located)
    at_times: dict[str, np.ndarray] = field(default_factory=dict)
    extra: dict[str, float] = field(default_factory=dict)

    def summary(self) -> dict[str, float | int | None]:
        def med(a: np.ndarray) -> float | None:
            return float(np.median(a)) if len(a) else None

        def p95(a: np.ndarray) -> float | None:
            return float(np.percentile(a, 95)) if len(a) else None

        out: dict[str, float | int | None] = {}
        for name in ("touch", "hold", "release"):
            phase: PhaseErrors = getattr(self, name)
            for key, value in phase.stats_mm().items():
                out[f"{name}_{key}"] = value
            out[f"{name}_coverage"] = round(phase.coverage, 4)
        for name, errors in self.common.items():
            out[f"{name}_p95_common_mm"] = p95(errors * 1e3)
        for name, errors in self.at_times.items():
            # a miss is an error larger than any: when over 5 % are missed the p95 is a miss
            value = p95(np.where(np.isfinite(errors), errors * 1e3, MISS_MM))
            out[f"{name}ms_p95_mm"] = value if value is None or value < MISS_MM else None
            out[f"{name}ms_located"] = float(np.mean(np.isfinite(errors))) if len(errors) else None
        out.update(
            touch_delay_ms=med(self.touch_delay_ms),
            touch_delay_p95_ms=p95(self.touch_delay_ms),
            release_delay_ms=med(self.release_delay_ms),
            release_delay_p95_ms=p95(self.release_delay_ms),
            first_point_delay_ms=med(self.first_point_delay_ms),
            presses=self.presses,
            missed=self.missed,
            false_touches=self.false_touches,
        )
        return out


def find_presses(true_fn: np.ndarray, contact_force_n: float = 2.0) -> list[Press]:
    """Runs of the true normal force at or above ``contact_force_n``."""
    on = np.nan_to_num(true_fn, nan=0.0) >= contact_force_n
    edges = np.diff(on.astype(np.int8), prepend=0, append=0)
    starts = np.flatnonzero(edges == 1)
    stops = np.flatnonzero(edges == -1)
    presses = []
    for a, b in zip(starts.tolist(), stops.tolist(), strict=True):
        f = true_fn[a:b]
        peak = float(np.max(f))
        high = np.flatnonzero(f >= 0.5 * peak)
        presses.append(Press(a, a + int(high[0]), a + int(high[-1]) + 1, b, peak))
    return presses


def measure_accuracy(
    block: ContactBlock,
    truth: dict[str, np.ndarray],
    contact_force_n: float = 2.0,
    common: np.ndarray | None = None,
) -> Accuracy:
    """Compare an estimator's output with the simulator's ground truth columns.

    ``common``: a mask of the samples every compared method locates (see
    :func:`common_located`), for the errors at equal coverage.
    """
    t = block.t
    true_fn = np.asarray(truth["true_fn"], dtype=float)
    presses = find_presses(true_fn, contact_force_n)
    held = truth_with_release(block, truth, presses)
    err = np.hypot(block.x - np.nan_to_num(held.x), block.y - np.nan_to_num(held.y))
    if held.z is not None:  # on one horizontal board z is the same for both: err unchanged
        err = np.hypot(err, block.z - np.nan_to_num(held.z))
    tally = _PhaseTally()
    delays = _PressDelays()
    at_times: dict[str, list[float]] = {
        f"{phase}{sign}{ms}": []
        for phase, sign in (("touch", "+"), ("release", "-"))
        for ms in AT_MS
    }
    for p, end in zip(presses, held.ends, strict=True):
        tally.add(p, end, err, block.located, common)
        _add_errors_at_times(at_times, t, true_fn, p, err, block.located, contact_force_n)
        delays.add(p, t, true_fn, block, contact_force_n)
    return Accuracy(
        tally.phase("touch"),
        tally.phase("hold"),
        tally.phase("release"),
        np.array(delays.touch),
        np.array(delays.release),
        np.array(delays.first_point),
        len(presses),
        delays.missed,
        _false_touches(block.in_contact, presses),
        common=tally.common_errors() if common is not None else {},
        at_times={k: np.array(v) for k, v in at_times.items()},
    )


PHASES = ("touch", "hold", "release")


@dataclass
class _PhaseTally:
    """Per phase, the errors of the located samples (and of the ``common`` ones, those
    every compared method locates) and how many samples it had and located."""

    parts: dict[str, list[np.ndarray]] = field(default_factory=lambda: {n: [] for n in PHASES})
    common: dict[str, list[np.ndarray]] = field(default_factory=lambda: {n: [] for n in PHASES})
    located: dict[str, int] = field(default_factory=lambda: dict.fromkeys(PHASES, 0))
    total: dict[str, int] = field(default_factory=lambda: dict.fromkeys(PHASES, 0))

    def add(
        self,
        p: Press,
        end: int,
        err: np.ndarray,
        located: np.ndarray,
        common: np.ndarray | None,
    ) -> None:
        """Press ``p``'s samples, its release running until ``end`` (or its true stop)."""
        for name, a, b in (
            ("touch", p.start, p.half_up),
            ("hold", p.half_up, p.half_down),
            ("release", p.half_down, max(end, p.stop)),
        ):
            here = located[a:b]
            self.parts[name].append(err[a:b][here])
            if common is not None:
                self.common[name].append(err[a:b][common[a:b]])
            self.located[name] += int(here.sum())
            self.total[name] += b - a

    def phase(self, name: str) -> PhaseErrors:
        """One phase's errors and the share of its samples located."""
        total = self.total[name]
        errors = np.concatenate(self.parts[name]) if self.parts[name] else np.zeros(0)
        return PhaseErrors(errors, self.located[name] / total if total else 0.0)

    def common_errors(self) -> dict[str, np.ndarray]:
        """Per phase, the errors on the samples every compared method locates."""
        return {k: np.concatenate(v) for k, v in self.common.items()}


@dataclass
class _PressDelays:
    """Per press the estimator called a contact: its touch-down, first-point and release
    delays (ms); and how many presses it missed."""

    touch: list[float] = field(default_factory=list)
    release: list[float] = field(default_factory=list)
    first_point: list[float] = field(default_factory=list)
    missed: int = 0

    def add(
        self, p: Press, t: np.ndarray, true_fn: np.ndarray, block: ContactBlock, level: float
    ) -> None:
        """Press ``p``'s delays against the true crossings of ``level``."""
        in_contact = block.in_contact
        on = np.flatnonzero(in_contact[p.start : p.stop])
        if len(on) == 0:
            self.missed += 1
            return
        self.touch.append((t[p.start + on[0]] - _crossing(t, true_fn, p.start, level)) * 1e3)
        loc = np.flatnonzero(block.located[p.start : p.stop])
        if len(loc):
            self.first_point.append((t[p.start + loc[0]] - t[p.start]) * 1e3)
        off = np.flatnonzero(~in_contact[p.stop :])
        if len(off):
            self.release.append((t[p.stop + off[0]] - _crossing(t, true_fn, p.stop, level)) * 1e3)


def _add_errors_at_times(
    at_times: dict[str, list[float]],
    t: np.ndarray,
    true_fn: np.ndarray,
    p: Press,
    err: np.ndarray,
    located: np.ndarray,
    level: float,
) -> None:
    """Press ``p``'s error :data:`AT_MS` after the true touch-down and before the true
    release (inf where not located; none where the press is shorter than the offset)."""
    down = _crossing(t, true_fn, p.start, level)
    up = _crossing(t, true_fn, p.stop, level)
    for ms in AT_MS:
        for key, when in ((f"touch+{ms}", down + ms / 1e3), (f"release-{ms}", up - ms / 1e3)):
            i = int(np.searchsorted(t, when))
            if p.start <= i < p.stop:  # a tap shorter than the offset has no such point
                at_times[key].append(float(err[i]) if located[i] else np.inf)


def _false_touches(in_contact: np.ndarray, presses: list[Press]) -> int:
    """Contacts reported where no press was (a contact starting within 0.3 s of a true press
    belongs to it)."""
    truth_on = np.zeros(len(in_contact), bool)
    for p in presses:
        truth_on[max(0, p.start - 360) : p.stop + 360] = True
    starts = np.flatnonzero(in_contact & ~np.concatenate([[False], in_contact[:-1]]))
    return int(np.count_nonzero(~truth_on[starts]))


def common_located(blocks: list[ContactBlock]) -> np.ndarray:
    """The samples every one of ``blocks`` (the same input, different methods) locates."""
    mask = np.ones(len(blocks[0]), bool)
    for block in blocks:
        mask &= block.located
    return mask


class TruthWithRelease(NamedTuple):
    """The true point per sample (``x``, ``y``, and ``z`` when the truth has it) held at the
    last point touched after each press, and where each press's release ends (``ends``)."""

    x: np.ndarray
    y: np.ndarray
    z: np.ndarray | None
    ends: list[int]


def truth_with_release(
    block: ContactBlock, truth: dict[str, np.ndarray], presses: list[Press]
) -> TruthWithRelease:
    """The true point per sample, held at the last point touched until the estimator ends
    the contact (at most 0.5 s); and where each press's release ends."""
    t = block.t
    true_x = np.asarray(truth["true_x"], dtype=float).copy()
    true_y = np.asarray(truth["true_y"], dtype=float).copy()
    true_z = np.asarray(truth["true_z"], dtype=float).copy() if "true_z" in truth else None
    longest = int(0.5 / max(float(np.median(np.diff(t))), 1e-9)) if len(t) > 1 else 0
    ends = []
    for p in presses:
        off = np.flatnonzero(~block.in_contact[p.stop :])
        end = min(p.stop + (int(off[0]) if len(off) else 0), p.stop + longest)
        true_x[p.stop : end] = true_x[p.stop - 1]
        true_y[p.stop : end] = true_y[p.stop - 1]
        if true_z is not None:
            true_z[p.stop : end] = true_z[p.stop - 1]
        ends.append(end)
    return TruthWithRelease(true_x, true_y, true_z, ends)


def _crossing(t: np.ndarray, f: np.ndarray, index: int, level: float) -> float:
    """The time the true force crossed ``level`` between samples index−1 and index."""
    if index <= 0 or index >= len(t):
        return float(t[min(index, len(t) - 1)])
    f0, f1 = f[index - 1], f[index]
    if not np.isfinite(f0) or not np.isfinite(f1) or f1 == f0:
        return float(t[index])
    frac = (level - f0) / (f1 - f0)
    return float(t[index - 1] + np.clip(frac, 0.0, 1.0) * (t[index] - t[index - 1]))
