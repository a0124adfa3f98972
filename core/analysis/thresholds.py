"""Deriving the switching thresholds F_tth and F_rth from recorded presses (paper §5.2).

For each press the distance from the top board's centre (the first surface's origin) to the
force-based point P_er is D_er, and to the point from the differentiated force P_ed is D_ed
(paper Fig. 7). Then, per press:

- **F_tth** (touching): |F_o| at the instant D_er has converged, |dD_er/dt| ≤ 0.2 m/s.
  "Has converged" is read as: from that sample to the end of the touching phase the
  criterion holds, so a momentary slow sample in a still-moving D_er does not count. The
  slope is the least-squares line through D_er over a centred window of ``slope_window_s``
  (50 ms by default: short against a touch of about half a second, long enough that the
  white noise left after the low-pass does not dominate the derivative).
- **F_rth** (releasing): |F_o| at the instant D_er starts to diverge, |D_er − D_ed| ≥ 0.01 m.
  "Starts to diverge" is read as: the first diverged sample after the last one where the two
  agreed, so D_er stays diverged from there until the force falls below 2 N. A press where
  D_ed never agreed with D_er while releasing has no reference and gives no value.

The motion (touching or releasing) is the sign of the differentiated force magnitude (paper
Fig. 3): the touching phase runs from touch-down to the first sample where it turns
negative, the releasing phase is the final run of negative samples. Only samples with
|F_o| ≥ ``contact_force_n`` count (paper: "the force whose magnitude is smaller than 2 N is
not considered"). Presses where a criterion never triggers are reported with the reason,
never given an invented value.

Presses are found without ground truth, so real recordings work: a press is a run of samples
in contact. The estimator runs with its contact gate on the conventional low-passed |F_o|
(the paper's condition for computing a point, §4) instead of its fast detection path, which
ends a contact while the low-passed force is still several newtons and would cut off the
releasing phase the criterion needs.

Summary (paper §5.2, Fig. 11): mean, standard deviation, minimum and maximum over the presses
that triggered; the candidates are the mean and mean ± one standard deviation, leaving out
those below ``contact_force_n``; the paper found the upper candidate best for both
thresholds (F_tth = 5.67 N, F_rth = 11.8 N), so that is the suggested value.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace
from typing import Any, NamedTuple

import numpy as np

from hapticdesk.errors import ConfigError
from hapticdesk.estimator import BAD_SAMPLE, CandidateTrace, ContactEstimator
from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.recording import Recording

CONVERGED_M_S = 0.2  # paper §5.2: |dD_er/dt| ≤ 0.2 m/s
DIVERGED_M = 0.01  # paper §5.2: |D_er − D_ed| ≥ 0.01 m
SLOPE_WINDOW_S = 0.05
#: the longest slope window: a touch lasts about half a second, so a window of seconds
#: would fit a line through the whole press and more
MAX_SLOPE_WINDOW_S = 10.0
GATE_HYSTERESIS_N = 0.1  # contact ends below contact_force_n − this (no chatter at 2 N)


@dataclass(frozen=True)
class PressThresholds:
    """What one press gave. A threshold is None when its criterion never triggered; the
    matching ``*_reason`` then says why."""

    index: int
    t_start: float
    t_end: float
    peak_n: float
    x: float  # the force-based point at the peak force (desk frame, m)
    y: float
    touch_n: float | None
    touch_t: float | None
    touch_reason: str
    release_n: float | None
    release_t: float | None
    release_reason: str


@dataclass(frozen=True)
class ThresholdSummary:
    """Statistics of one threshold over the presses where it triggered (paper Fig. 11)."""

    triggered: int
    presses: int
    mean_n: float | None = None
    std_n: float | None = None
    min_n: float | None = None
    max_n: float | None = None
    low_n: float | None = None  # mean − std
    high_n: float | None = None  # mean + std
    candidates_n: list[float] = field(default_factory=list)
    suggested_n: float | None = None

    @classmethod
    def of(cls, values: list[float], presses: int, floor_n: float) -> ThresholdSummary:
        """Summarise ``values``; candidates below ``floor_n`` are left out (paper §5.2)."""
        if not values:
            return cls(0, presses)
        v = np.asarray(values, dtype=float)
        mean = float(v.mean())
        std = float(v.std(ddof=1)) if len(v) > 1 else 0.0
        low, high = mean - std, mean + std
        candidates = sorted({round(c, 2) for c in (low, mean, high) if c >= floor_n})
        return cls(
            triggered=len(v),
            presses=presses,
            mean_n=mean,
            std_n=std,
            min_n=float(v.min()),
            max_n=float(v.max()),
            low_n=low,
            high_n=high,
            candidates_n=candidates,
            suggested_n=candidates[-1] if candidates else None,
        )


@dataclass(frozen=True)
class ThresholdReport:
    """Per-press results, the two summaries and the settings used."""

    presses: list[PressThresholds]
    touch: ThresholdSummary
    release: ThresholdSummary
    settings: dict[str, float]
    notices: list[dict[str, Any]]

    def snippet(self) -> str | None:
        """The profile lines to paste, or None when neither threshold could be derived."""
        parts = []
        if self.touch.suggested_n is not None:
            parts.append(f"touch_threshold_n: {self.touch.suggested_n:g}")
        if self.release.suggested_n is not None:
            parts.append(f"release_threshold_n: {self.release.suggested_n:g}")
        return f"estimation: {{{', '.join(parts)}}}" if parts else None

    def to_dict(self) -> dict[str, Any]:
        """Everything as plain JSON-ready values (no NaN: missing values are None)."""
        return {
            "presses": [asdict(p) for p in self.presses],
            "touch": asdict(self.touch),
            "release": asdict(self.release),
            "snippet": self.snippet(),
            "settings": dict(self.settings),
            "notices": list(self.notices),
        }


@dataclass(frozen=True)
class PressTrace:
    """One press's traced samples: times, |F_o|, its rate (the motion's sign), the
    force-based point (3, n), and the distances D_er and D_ed (NaN where no point)."""

    t: np.ndarray
    force_n: np.ndarray
    rate_n_s: np.ndarray
    force_point: np.ndarray
    d_er: np.ndarray
    d_ed: np.ndarray


class _Crossing(NamedTuple):
    """Where a criterion triggered (the force and time; None when it never did) and why."""

    force_n: float | None
    t: float | None
    reason: str


def derive_thresholds(
    profile: DeskProfile,
    recording: Recording,
    *,
    converged_m_s: float = CONVERGED_M_S,
    diverged_m: float = DIVERGED_M,
    slope_window_s: float = SLOPE_WINDOW_S,
) -> ThresholdReport:
    """Find the presses in ``recording`` and derive F_tth and F_rth from each (module doc).

    Raises :class:`ConfigError` when the desk has no surface to measure distances on, and
    ValueError for a ``slope_window_s`` outside (0, :data:`MAX_SLOPE_WINDOW_S`].
    """
    if not 0.0 < slope_window_s <= MAX_SLOPE_WINDOW_S:
        raise ValueError(
            f"slope_window_s must be over 0 and at most {MAX_SLOPE_WINDOW_S:g} s, "
            f"found {slope_window_s}"
        )
    if not profile.surfaces:
        raise ConfigError(
            str(profile.path or profile.name),
            "the desk has no surfaces: thresholds need a surface to locate presses on",
        )
    floor_n = profile.estimation.contact_force_n
    estimator = _gated_estimator(profile)
    presses = _press_traces(profile, estimator, recording)
    half = max(1, round(slope_window_s * profile.sample_rate_hz / 2))
    results = [
        _one_press(number + 1, press, half, floor_n, converged_m_s, diverged_m)
        for number, press in enumerate(presses)
    ]
    n = len(results)
    touch = [p.touch_n for p in results if p.touch_n is not None]
    release = [p.release_n for p in results if p.release_n is not None]
    return ThresholdReport(
        presses=results,
        touch=ThresholdSummary.of(touch, n, floor_n),
        release=ThresholdSummary.of(release, n, floor_n),
        settings={
            "converged_m_s": converged_m_s,
            "diverged_m": diverged_m,
            "slope_window_s": 2 * half / profile.sample_rate_hz,
            "contact_force_n": floor_n,
        },
        notices=[
            {"t": x.t, "kind": x.kind, "message": x.message}
            for x in estimator.notices
            if x.kind in ("tare", "tare_refused", "absorbed", "gap")
        ],
    )


def _gated_estimator(profile: DeskProfile) -> ContactEstimator:
    """The switched estimator with its contact gate on the conventional low-passed |F_o|
    (module doc), tracing its candidates."""
    base = profile.estimation
    settings = replace(
        base,
        detect_lowpass_hz=base.force_lowpass_hz,
        release_hysteresis_n=min(GATE_HYSTERESIS_N, base.release_hysteresis_n),
        release_slope_n_s=0.0,  # gated on the low-passed force itself, not a prediction
    )
    return ContactEstimator(profile, method="switched", settings=settings, trace=True)


def _press_traces(
    profile: DeskProfile, estimator: ContactEstimator, recording: Recording
) -> list[PressTrace]:
    """Run ``estimator`` over ``recording`` and cut its trace into presses: runs of samples
    in contact."""
    block = estimator.push(recording.t, recording.wrench)
    trace = CandidateTrace.concat(estimator.traces)
    traced = np.flatnonzero(block.in_contact & ((block.flags & BAD_SAMPLE) == 0))
    if len(traced) != len(trace.t):  # the estimator's trace contract; never expected
        raise RuntimeError("the estimator's trace does not match its samples in contact")
    # each traced sample gets its run's number
    inc = block.in_contact
    run_starts = inc & ~np.concatenate([[False], inc[:-1]])
    run_of = np.cumsum(run_starts)[traced]
    cuts = (np.flatnonzero(np.diff(run_of)) + 1).tolist()
    bounds = [0, *cuts, len(run_of)] if len(run_of) else [0]
    centre = profile.surfaces[0].origin
    d_er = np.linalg.norm(trace.force_point - centre[:, None], axis=0)
    d_ed = np.linalg.norm(trace.diff_point - centre[:, None], axis=0)
    d_er[~trace.force_valid] = np.nan
    d_ed[~trace.diff_valid] = np.nan
    return [
        PressTrace(
            trace.t[a:b],
            trace.force_n[a:b],
            trace.rate_n_s[a:b],
            trace.force_point[:, a:b],
            d_er[a:b],
            d_ed[a:b],
        )
        for a, b in zip(bounds[:-1], bounds[1:], strict=True)
    ]


def _one_press(
    number: int,
    press: PressTrace,
    half: int,
    floor_n: float,
    converged_m_s: float,
    diverged_m: float,
) -> PressThresholds:
    """Both criteria on one press's traced samples."""
    force = press.force_n
    peak = int(np.argmax(force))
    touch = _touch_crossing(press, half, floor_n, converged_m_s)
    release = _release_crossing(press, floor_n, diverged_m)
    return PressThresholds(
        index=number,
        t_start=float(press.t[0]),
        t_end=float(press.t[-1]),
        peak_n=float(force[peak]),
        x=float(press.force_point[0, peak]),
        y=float(press.force_point[1, peak]),
        touch_n=touch.force_n,
        touch_t=touch.t,
        touch_reason=touch.reason,
        release_n=release.force_n,
        release_t=release.t,
        release_reason=release.reason,
    )


def _touch_crossing(
    press: PressTrace, half: int, floor_n: float, converged_m_s: float
) -> _Crossing:
    """F_tth: |F_o| where D_er has converged for the rest of the touching phase, from
    touch-down to the first sample where the motion turns to releasing."""
    force, t = press.force_n, press.t
    slope = local_slope(t, press.d_er, half)
    falling = np.flatnonzero(press.rate_n_s < 0)
    touch_end = int(falling[0]) if len(falling) else len(t)
    touching = np.flatnonzero(force[:touch_end] >= floor_n)
    if len(touching) == 0:
        return _Crossing(None, None, f"no touching phase at or above {floor_n:g} N")
    converged = np.abs(slope[touching]) <= converged_m_s  # NaN (no point) is not
    if not converged[-1]:
        return _Crossing(
            None,
            None,
            f"D_er still moving at the end of touching (|dD_er/dt| > {converged_m_s:g} m/s)",
        )
    unsettled = np.flatnonzero(~converged)
    at = touching[int(unsettled[-1]) + 1 if len(unsettled) else 0]
    # at once: D_er was settled at the first sample that counts, so F_tth is only
    # bounded by the contact force
    reason = "converged" if len(unsettled) else "converged at once"
    return _Crossing(float(force[at]), float(t[at]), reason)


def _release_crossing(press: PressTrace, floor_n: float, diverged_m: float) -> _Crossing:
    """F_rth: |F_o| at the first diverged sample after D_er and D_ed last agreed, in the
    final run of samples with the motion negative."""
    force, t = press.force_n, press.t
    rising = np.flatnonzero(press.rate_n_s >= 0)
    release_start = int(rising[-1]) + 1 if len(rising) else 0
    releasing = release_start + np.flatnonzero(force[release_start:] >= floor_n)
    if len(releasing) == 0:
        return _Crossing(None, None, f"no releasing phase at or above {floor_n:g} N")
    er, ed = press.d_er[releasing], press.d_ed[releasing]
    with np.errstate(invalid="ignore"):
        gap = np.abs(er - ed)
        agreed = gap < diverged_m  # both points exist and lie close
        # no force-based point at all has diverged too (its line left the surface)
        diverged = np.isnan(er) | (gap >= diverged_m)
    last_agreed = np.flatnonzero(agreed)
    if len(last_agreed) == 0:
        return _Crossing(None, None, "D_ed never agreed with D_er while releasing (no reference)")
    after = int(last_agreed[-1]) + 1
    onset = np.flatnonzero(diverged[after:])
    if len(onset) == 0:
        return _Crossing(
            None, None, f"D_er did not diverge before the force fell below {floor_n:g} N"
        )
    at = releasing[after + int(onset[0])]
    return _Crossing(float(force[at]), float(t[at]), "diverged")


def local_slope(t: np.ndarray, y: np.ndarray, half: int) -> np.ndarray:
    """Least-squares slope dy/dt over the samples ``i − half … i + half`` (clipped at the
    ends), vectorised with running sums; NaN where the window holds a NaN or one sample."""
    n = len(y)
    if n == 0:
        return np.zeros(0)
    bad = ~np.isfinite(y)
    tt = t - t[0]  # small numbers: the running sums stay exact enough
    yy = np.where(bad, 0.0, y)

    def running(x: np.ndarray) -> np.ndarray:
        return np.concatenate([[0.0], np.cumsum(x)])

    i = np.arange(n)
    lo = np.maximum(i - half, 0)
    hi = np.minimum(i + half, n - 1) + 1
    sums = [running(x) for x in (np.ones(n), tt, tt * tt, yy, tt * yy, bad.astype(float))]
    count, st, stt, sy, sty, nbad = (c[hi] - c[lo] for c in sums)
    den = count * stt - st * st
    with np.errstate(invalid="ignore", divide="ignore"):
        slope = (count * sty - st * sy) / den
    return np.where((nbad > 0) | (count < 2) | ~(den > 0), np.nan, slope)
