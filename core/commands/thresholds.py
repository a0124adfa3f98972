"""``hapticdesk thresholds REC --desk D [--json]``: derive F_tth and F_rth from recorded presses
with the paper's criteria (§5.2), per press and summarised, and print the profile snippet.

Exit status: 0 when at least one threshold was derived, 1 when no press gave either (the
report still says why for each press), 2 for a wrong file or desk.
"""

from __future__ import annotations

import argparse
import json
import sys

from hapticdesk.analysis.thresholds import (
    CONVERGED_M_S,
    DIVERGED_M,
    MAX_SLOPE_WINDOW_S,
    SLOPE_WINDOW_S,
    ThresholdReport,
    ThresholdSummary,
    derive_thresholds,
)
from hapticdesk.errors import ConfigError
from hapticdesk.files.profile_reader import load_profile
from hapticdesk.recordings import read_any_recording


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("recording", help="recording of presses (.csv, .npz) or CAN log")
    parser.add_argument("--desk", required=True, help="desk profile name or path")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument(
        "--converged",
        type=float,
        default=CONVERGED_M_S,
        metavar="M_S",
        help=f"touch: D_er has converged when |dD_er/dt| <= this (default {CONVERGED_M_S:g})",
    )
    parser.add_argument(
        "--diverged",
        type=float,
        default=DIVERGED_M,
        metavar="M",
        help=f"release: D_er diverges when |D_er - D_ed| >= this (default {DIVERGED_M:g})",
    )
    parser.add_argument(
        "--slope-window",
        type=float,
        default=SLOPE_WINDOW_S,
        metavar="S",
        help=f"window of the dD_er/dt line fit, seconds (default {SLOPE_WINDOW_S:g}, at most "
        f"{MAX_SLOPE_WINDOW_S:g})",
    )


def run(args: argparse.Namespace) -> int:
    for name in ("converged", "diverged", "slope_window"):
        value = getattr(args, name)
        if not (value > 0 and value < float("inf")):
            flag = "--" + name.replace("_", "-")
            raise ConfigError(flag, f"must be a positive number, found {value}")
    if args.slope_window > MAX_SLOPE_WINDOW_S:
        raise ConfigError(
            "--slope-window",
            f"must be at most {MAX_SLOPE_WINDOW_S:g} s (a touch lasts about half a second), "
            f"found {args.slope_window:g}",
        )
    profile = load_profile(args.desk)
    recording = read_any_recording(args.recording, profile)
    report = derive_thresholds(
        profile,
        recording,
        converged_m_s=args.converged,
        diverged_m=args.diverged,
        slope_window_s=args.slope_window,
    )
    if args.json:
        info = report.to_dict()
        info.update(recording=str(args.recording), desk=profile.name)
        print(json.dumps(info))
    else:
        print(format_report(report))
    # (a refused tare is said as the estimator logs it, once: it was printed twice)
    if report.touch.triggered == 0 and report.release.triggered == 0:
        if not report.presses:
            print(
                f"hapticdesk thresholds: {args.recording}: no presses found (the estimator needs "
                f"{profile.estimation.tare_s:g} s of a quiet desk at the start to tare)",
                file=sys.stderr,
            )
        return 1
    return 0


def _value(value: float | None, width: int = 7) -> str:
    return f"{value:{width}.2f}" if value is not None else f"{'—':>{width}}"


def format_report(report: ThresholdReport) -> str:
    """The per-press table, both summaries and the snippet as text."""
    s = report.settings
    lines = [
        f"F_tth: |F_o| where D_er has converged (|dD_er/dt| <= {s['converged_m_s']:g} m/s, "
        f"line fit over {s['slope_window_s'] * 1e3:.0f} ms)",
        f"F_rth: |F_o| where D_er starts to diverge (|D_er - D_ed| >= {s['diverged_m']:g} m); "
        f"forces below {s['contact_force_n']:g} N are not considered (paper §5.2)",
        "",
        f"{'press':>5} {'t (s)':>8} {'peak N':>7} {'x (m)':>7} {'y (m)':>7} "
        f"{'F_tth N':>7} {'F_rth N':>7}  note",
    ]
    for p in report.presses:
        notes = []
        if p.touch_n is None or p.touch_reason != "converged":
            notes.append(f"touch: {p.touch_reason}")
        if p.release_n is None:
            notes.append(f"release: {p.release_reason}")
        lines.append(
            f"{p.index:5d} {p.t_start:8.2f} {p.peak_n:7.1f} {p.x:7.3f} {p.y:7.3f} "
            f"{_value(p.touch_n)} {_value(p.release_n)}  {'; '.join(notes)}"
        )
    if not report.presses:
        lines.append("  (no presses found)")
    lines.append("")
    for name, summary in (("F_tth", report.touch), ("F_rth", report.release)):
        lines.append(_summary_line(name, summary))
    snippet = report.snippet()
    lines.append("")
    if snippet is None:
        lines.append("no threshold could be derived: nothing to paste")
    else:
        lines.append("paste into the desk profile (the upper candidates, as the paper chose):")
        lines.append(f"  {snippet}")
    return "\n".join(lines)


def _summary_line(name: str, s: ThresholdSummary) -> str:
    head = f"{name}: triggered in {s.triggered} of {s.presses} presses"
    if s.mean_n is None:
        return head
    assert s.std_n is not None and s.low_n is not None and s.high_n is not None
    candidates = ", ".join(f"{c:g}" for c in s.candidates_n) or "none >= the contact force"
    return (
        f"{head}; mean {s.mean_n:.2f} N, std {s.std_n:.2f} N, min {s.min_n:.2f} N, "
        f"max {s.max_n:.2f} N; mean ± std {s.low_n:.2f}–{s.high_n:.2f} N\n"
        f"  candidates (mean, mean ± std, >= the contact force): {candidates} N; "
        f"suggested {s.suggested_n:g} N"
    )
