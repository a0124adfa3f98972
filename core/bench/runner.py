"""Error against run time: every method and every setting, measured the same way.

For each configuration (a method plus changes to the profile's estimation settings) the
benchmark simulates the paper's experiment with the paper's noise for each seed, estimates
contacts, and measures accuracy against the truth (:mod:`hapticdesk.bench.accuracy`, errors
pooled over the seeds) and cost (:mod:`hapticdesk.bench.timing`, on the first seed's run).

Cost is measured in rounds (:func:`measure_costs`): after a warm-up round that is not
counted, each round times every configuration once, in turn, so that a burst of load from
elsewhere on the machine falls on all of them alike instead of on the few timed during it;
each figure is the median of the rounds, shown with its range. (Each configuration timed in
one go, best of 2–3, had put two identical ones 2× apart and changed the Pareto front from
run to run.)
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from hapticdesk.bench.accuracy import Accuracy, PhaseErrors, common_located, measure_accuracy
from hapticdesk.bench.timing import measure_cost
from hapticdesk.estimator import ContactEstimator
from hapticdesk.files.profile import METHODS, DeskProfile
from hapticdesk.files.recording import Recording


@dataclass(frozen=True)
class Config:
    """A method and the settings it changes from the profile's."""

    method: str
    changes: dict[str, float] = field(default_factory=dict)

    @property
    def label(self) -> str:
        """Short, readable: "fused window 0.083 s", "switched tare once"."""
        words = [self.method]
        changes = dict(self.changes)
        if changes.pop("drift_settle_s", None) == 0.0:
            words.append("tare once")
        if (
            "force_lowpass_hz" in changes
            and changes.get("diff_lowpass_hz") == changes["force_lowpass_hz"]
        ):
            changes.pop("diff_lowpass_hz")
            words.append(f"low-pass {changes.pop('force_lowpass_hz'):g} Hz")
        if "diff_window_s" in changes:
            words.append(f"window {changes.pop('diff_window_s'):g} s")
        if "max_sigma_m" in changes:
            words.append(f"gate {1000 * changes.pop('max_sigma_m'):g} mm")
        words += [f"{k}={v:g}" for k, v in changes.items()]
        return " ".join(words)


def default_configs(quick: bool) -> list[Config]:
    """The four methods, then sweeps of what trades accuracy for delay or cost."""
    configs = [Config(m) for m in METHODS]
    configs += [Config(m, {"drift_settle_s": 0.0}) for m in ("force", "switched", "fused")]
    windows = (0.083, 0.25) if quick else (0.05, 0.083, 0.25, 0.33)
    cutoffs = (3.0, 8.0) if quick else (2.0, 3.0, 6.0, 8.0)
    for method in ("switched", "fused") if quick else ("diff", "switched", "fused"):
        configs += [Config(method, {"diff_window_s": w}) for w in windows]
    for method in ("force", "fused") if quick else ("force", "switched", "fused"):
        configs += [Config(method, {"force_lowpass_hz": c, "diff_lowpass_hz": c}) for c in cutoffs]
    if not quick:
        configs += [Config("fused", {"max_sigma_m": g}) for g in (0.003, 0.01, 0.02)]
    return configs


def pooled(results: list[Accuracy]) -> Accuracy:
    """One Accuracy from several runs (errors and delays pooled)."""

    def phase(name: str) -> PhaseErrors:
        parts: list[PhaseErrors] = [getattr(r, name) for r in results]
        return PhaseErrors(
            np.concatenate([p.errors_m for p in parts]),
            float(np.mean([p.coverage for p in parts])),
        )

    return Accuracy(
        phase("touch"),
        phase("hold"),
        phase("release"),
        np.concatenate([r.touch_delay_ms for r in results]),
        np.concatenate([r.release_delay_ms for r in results]),
        np.concatenate([r.first_point_delay_ms for r in results]),
        sum(r.presses for r in results),
        sum(r.missed for r in results),
        sum(r.false_touches for r in results),
        common={k: np.concatenate([r.common[k] for r in results]) for k in results[0].common},
        at_times={k: np.concatenate([r.at_times[k] for r in results]) for k in results[0].at_times},
    )


def common_masks(profile: DeskProfile, recordings: list[Recording]) -> list[np.ndarray]:
    """Per recording, the samples every one of the four methods locates with the profile's
    settings: the sample set on which all rows' ``*_p95_common_mm`` are computed."""
    masks = []
    for rec in recordings:
        blocks = [ContactEstimator(profile, method=m).push(rec.t, rec.wrench) for m in METHODS]
        masks.append(common_located(blocks))
    return masks


#: counted rounds of cost measurement, and rounds before them that are not counted
COST_ROUNDS = 5
WARMUP_ROUNDS = 1
#: the cost figures (:class:`hapticdesk.bench.timing.Cost`), each a row's median with its
#: ``_min`` and ``_max`` over the rounds, and the decimals each is shown with
COST_FIGURES = {"samples_per_s": 0, "us_per_sample_stream": 2, "us_per_sample_block12": 2}


def measure_costs(
    profile: DeskProfile,
    configs: list[Config],
    recording: Recording,
    *,
    rounds: int = COST_ROUNDS,
    warmup: int = WARMUP_ROUNDS,
    stream_samples: int = 6000,
    progress: Callable[[str], None] | None = None,
) -> list[dict[str, list[float]]]:
    """Per configuration, per cost figure, its value in each counted round.

    A round times every configuration once (:func:`~hapticdesk.bench.timing.measure_cost`,
    one repeat), forwards in one round and backwards in the next, so no configuration is
    always the first after another's garbage; the first ``warmup`` rounds (first calls,
    caches) are not counted."""
    values: list[dict[str, list[float]]] = [{f: [] for f in COST_FIGURES} for _ in configs]
    order = list(range(len(configs)))
    for n in range(warmup + rounds):
        if progress is not None:
            what = "warm-up" if n < warmup else f"round {n - warmup + 1} of {rounds}"
            progress(f"run time, {what}: every configuration in turn")
        for i in order if n % 2 == 0 else order[::-1]:
            config = configs[i]
            settings = replace(profile.estimation, method=config.method, **config.changes)
            cost = measure_cost(
                profile,
                recording.t,
                recording.wrench,
                config.method,
                settings,
                repeats=1,
                stream_samples=stream_samples,
            )
            if n >= warmup:
                for figure in COST_FIGURES:
                    values[i][figure].append(float(getattr(cost, figure)))
    return values


def cost_columns(values: dict[str, list[float]]) -> dict[str, float]:
    """A row's cost columns: each figure's median over the rounds, its min and its max."""
    out: dict[str, float] = {}
    for figure, decimals in COST_FIGURES.items():
        v = np.asarray(values[figure])
        for key, value in (
            (figure, np.median(v)),
            (f"{figure}_min", v.min()),
            (f"{figure}_max", v.max()),
        ):
            out[key] = round(float(value), decimals) if decimals else round(float(value))
    return out


def accuracy_row(
    profile: DeskProfile,
    config: Config,
    recordings: list[Recording],
    common: list[np.ndarray] | None = None,
) -> dict[str, Any]:
    """A row's accuracy, pooled over the recordings (no cost yet).

    ``common``: per recording, the samples every compared method locates
    (:func:`common_masks`); without it the row has no ``*_p95_common_mm``.
    """
    settings = replace(profile.estimation, method=config.method, **config.changes)
    results = []
    for i, rec in enumerate(recordings):
        block = ContactEstimator(profile, settings=settings).push(rec.t, rec.wrench)
        mask = None if common is None else common[i]
        results.append(measure_accuracy(block, rec.extra, settings.contact_force_n, mask))
    row: dict[str, Any] = {
        "method": config.method,
        "label": config.label,
        "settings": dict(config.changes),
    }
    row.update(pooled(results).summary())
    return {k: (round(v, 3) if isinstance(v, float) else v) for k, v in row.items()}


def run_configs(
    profile: DeskProfile,
    configs: list[Config],
    recordings: list[Recording],
    *,
    rounds: int = COST_ROUNDS,
    warmup: int = WARMUP_ROUNDS,
    stream_samples: int = 6000,
    common: list[np.ndarray] | None = None,
    progress: Callable[[str], None] | None = None,
) -> list[dict[str, Any]]:
    """One table row per configuration: its accuracy (:func:`accuracy_row`), then the cost
    of all of them measured together in rounds on the first recording
    (:func:`measure_costs`)."""
    rows = []
    for config in configs:
        rows.append(accuracy_row(profile, config, recordings, common))
        if progress is not None:
            progress(config.label)
    costs = measure_costs(
        profile,
        configs,
        recordings[0],
        rounds=rounds,
        warmup=warmup,
        stream_samples=stream_samples,
        progress=progress,
    )
    for row, values in zip(rows, costs, strict=True):
        row.update(cost_columns(values))
    return rows


def run_config(
    profile: DeskProfile,
    config: Config,
    recordings: list[Recording],
    *,
    rounds: int = COST_ROUNDS,
    stream_samples: int = 6000,
    common: list[np.ndarray] | None = None,
) -> dict[str, Any]:
    """Accuracy and cost of one configuration: one table row (:func:`run_configs`)."""
    return run_configs(
        profile, [config], recordings, rounds=rounds, stream_samples=stream_samples, common=common
    )[0]


def pareto_front(rows: list[dict[str, Any]], error_key: str, cost_key: str) -> list[int]:
    """Indices of the rows no other row beats: a row is beaten by one at least as accurate
    (more accurate, or as accurate and measurably cheaper) that is not measurably dearer.

    Where the rows carry their cost's range over the rounds (``<cost_key>_min``, ``_max``),
    "measurably" means the ranges do not overlap: two costs within each other's noise are
    a tie, which the more accurate row wins, so the front does not change with the noise
    of one run. Without ranges the medians are compared as they are."""

    def cheaper(b: dict[str, Any], a: dict[str, Any]) -> bool:  # measurably
        return bool(b.get(f"{cost_key}_max", b[cost_key]) < a.get(f"{cost_key}_min", a[cost_key]))

    front = []
    for i, a in enumerate(rows):
        if a[error_key] is None:
            continue
        dominated = any(
            b is not a
            and b[error_key] is not None
            and not cheaper(a, b)
            and (b[error_key] < a[error_key] or (b[error_key] == a[error_key] and cheaper(b, a)))
            for b in rows
        )
        if not dominated:
            front.append(i)
    return front
