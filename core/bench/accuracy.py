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
    true_x, true_y, true_z, ends = truth_with_release(block, truth, presses)
    err = np.hypot(block.x - np.nan_to_num(true_x), block.y - np.nan_to_num(true_y))
    if true_z is not None:  # on one horizontal board z is the same for both: err unchanged
        err = np.hypot(err, block.z - np.nan_to_num(true_z))
    parts: dict[str, list[np.ndarray]] = {"touch": [], "hold": [], "release": []}
    common_parts: dict[str, list[np.ndarray]] = {"touch": [], "hold": [], "release": []}
    counts = {"touch": [0, 0], "hold": [0, 0], "release": [0, 0]}  # located, total
    touch_delay, release_delay, first_point = [], [], []
    at_times: dict[str, list[float]] = {
        f"{phase}{sign}{ms}": []
        for phase, sign in (("touch", "+"), ("release", "-"))
        for ms in AT_MS
    }
    missed = 0
    in_contact = block.in_contact
    for p, end in zip(presses, ends, strict=True):
        for name, a, b in (
            ("touch", p.start, p.half_up),
            ("hold", p.half_up, p.half_down),
            ("release", p.half_down, max(end, p.stop)),
        ):
            located = block.located[a:b]
            parts[name].append(err[a:b][located])
            if common is not None:
                common_parts[name].append(err[a:b][common[a:b]])
            counts[name][0] += int(located.sum())
            counts[name][1] += b - a
        down = _crossing(t, true_fn, p.start, contact_force_n)
        up = _crossing(t, true_fn, p.stop, contact_force_n)
        for ms in AT_MS:
            for key, when, lo, hi in (
                (f"touch+{ms}", down + ms / 1e3, p.start, p.stop),
                (f"release-{ms}", up - ms / 1e3, p.start, p.stop),
            ):
                i = int(np.searchsorted(t, when))
                if lo <= i < hi:  # a tap shorter than the offset has no such point
                    at_times[key].append(float(err[i]) if block.located[i] else np.inf)
        on = np.flatnonzero(in_contact[p.start : p.stop])
        if len(on) == 0:
            missed += 1
            continue
        touch_delay.append(
            (t[p.start + on[0]] - _crossing(t, true_fn, p.start, contact_force_n)) * 1e3
        )
        loc = np.flatnonzero(block.located[p.start : p.stop])
        if len(loc):
            first_point.append((t[p.start + loc[0]] - t[p.start]) * 1e3)
        off = np.flatnonzero(~in_contact[p.stop :])
        if len(off):
            release_delay.append(
                (t[p.stop + off[0]] - _crossing(t, true_fn, p.stop, contact_force_n)) * 1e3
            )
    truth_on = np.zeros(len(t), bool)
    for p in presses:  # a reported contact within 0.3 s of a true press belongs to it
        truth_on[max(0, p.start - 360) : p.stop + 360] = True
    starts = np.flatnonzero(in_contact & ~np.concatenate([[False], in_contact[:-1]]))
    false_touches = int(np.count_nonzero(~truth_on[starts]))

    def phase(name: str) -> PhaseErrors:
        located, total = counts[name]
        errors = np.concatenate(parts[name]) if parts[name] else np.zeros(0)
        return PhaseErrors(errors, located / total if total else 0.0)

    return Accuracy(
        phase("touch"),
        phase("hold"),
        phase("release"),
        np.array(touch_delay),
        np.array(release_delay),
        np.array(first_point),
        len(presses),
        missed,
        false_touches,
        common={k: np.concatenate(v) for k, v in common_parts.items()}
        if common is not None
        else {},
        at_times={k: np.array(v) for k, v in at_times.items()},
    )


def common_located(blocks: list[ContactBlock]) -> np.ndarray:
    """The samples every one of ``blocks`` (the same input, different methods) locates."""
    mask = np.ones(len(blocks[0]), bool)
    for block in blocks:
        mask &= block.located
    return mask


def truth_with_release(
    block: ContactBlock, truth: dict[str, np.ndarray], presses: list[Press]
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, list[int]]:
    """The true point per sample (x, y, and z when the truth has it), held at the last point
    touched until the estimator ends the contact (at most 0.5 s); and where each press's
    release ends."""
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
    return true_x, true_y, true_z, ends


def _crossing(t: np.ndarray, f: np.ndarray, index: int, level: float) -> float:
    """The time the true force crossed ``level`` between samples index−1 and index."""
    if index <= 0 or index >= len(t):
        return float(t[min(index, len(t) - 1)])
    f0, f1 = f[index - 1], f[index]
    if not np.isfinite(f0) or not np.isfinite(f1) or f1 == f0:
        return float(t[index])
    frac = (level - f0) / (f1 - f0)
    return float(t[index - 1] + np.clip(frac, 0.0, 1.0) * (t[index] - t[index - 1]))
