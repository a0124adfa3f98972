"""Error against run time: every method and every setting, measured the same way.

For each configuration (a method plus changes to the profile's estimation settings) the
benchmark simulates the paper's experiment with the paper's noise for each seed, estimates
contacts, and measures accuracy against the truth (:mod:`hapticdesk.bench.accuracy`, errors
pooled over the seeds) and cost (:mod:`hapticdesk.bench.timing`, on the first seed's run).
"""

from __future__ import annotations

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


def run_config(
    profile: DeskProfile,
    config: Config,
    recordings: list[Recording],
    *,
    repeats: int = 3,
    stream_samples: int = 6000,
    common: list[np.ndarray] | None = None,
) -> dict[str, Any]:
    """Accuracy (pooled over the recordings) and cost of one configuration: one table row.

    ``common``: per recording, the samples every compared method locates
    (:func:`common_masks`); without it the row has no ``*_p95_common_mm``.
    """
    settings = replace(profile.estimation, method=config.method, **config.changes)
    results = []
    for i, rec in enumerate(recordings):
        block = ContactEstimator(profile, settings=settings).push(rec.t, rec.wrench)
        mask = None if common is None else common[i]
        results.append(measure_accuracy(block, rec.extra, settings.contact_force_n, mask))
    acc = pooled(results)
    cost = measure_cost(
        profile,
        recordings[0].t,
        recordings[0].wrench,
        config.method,
        settings,
        repeats=repeats,
        stream_samples=stream_samples,
    )
    row: dict[str, Any] = {
        "method": config.method,
        "label": config.label,
        "settings": dict(config.changes),
    }
    row.update(acc.summary())
    row.update(
        samples_per_s=round(cost.samples_per_s),
        us_per_sample_stream=round(cost.us_per_sample_stream, 2),
        us_per_sample_block12=round(cost.us_per_sample_block12, 2),
    )
    return {k: (round(v, 3) if isinstance(v, float) else v) for k, v in row.items()}


def pareto_front(rows: list[dict[str, Any]], error_key: str, cost_key: str) -> list[int]:
    """Indices of the rows no other row beats on both error and cost."""
    front = []
    for i, a in enumerate(rows):
        if a[error_key] is None:
            continue
        dominated = any(
            b[error_key] is not None
            and b[error_key] <= a[error_key]
            and b[cost_key] <= a[cost_key]
            and (b[error_key] < a[error_key] or b[cost_key] < a[cost_key])
            for b in rows
        )
        if not dominated:
            front.append(i)
    return front
