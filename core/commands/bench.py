"""``hapticdesk bench``: error against run time for every method, and the paper reproduced."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

from hapticdesk.commands.output_path import cannot_write, check_output_path
from hapticdesk.errors import ConfigError
from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.profile_reader import load_profile


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--desk", default="kitamura2017", help="desk profile (default: the paper's)"
    )
    parser.add_argument(
        "--quick", action="store_true", help="fewer settings and one seed (< 1 min)"
    )
    parser.add_argument("--seeds", type=int, default=None, help="simulated sessions to pool")
    parser.add_argument("--json", action="store_true", help="print the results as JSON")
    parser.add_argument("--plot", type=Path, help="PNG of error against µs per sample")
    parser.add_argument(
        "--paper", action="store_true", help="reproduce the paper's Fig. 2, 8, 14 and 16 instead"
    )
    parser.add_argument(
        "--paper-png",
        type=Path,
        default=None,
        help="with --paper: where to draw the traced 北 (Fig. 16)",
    )
    parser.add_argument(
        "--figures",
        type=Path,
        default=None,
        metavar="FOLDER",
        help="with --paper: draw Figs. 2, 8, 14 and 16 into FOLDER (fig2.png, fig8.png, "
        "fig14.png, fig16.png; the folder is made if its parent exists)",
    )


#: the most simulated sessions pooled: 1000 had grown the process past 3 GB
MAX_SEEDS = 20


def run(args: argparse.Namespace) -> int:
    _check_arguments(args)  # before minutes of work
    profile = load_profile(args.desk)
    if args.paper:
        return _paper(args, profile)
    info = _measure(args, profile)
    if args.json:
        print(json.dumps(info, indent=1))
    else:
        _print_table(info, args.plot)
    return 0


def _check_arguments(args: argparse.Namespace) -> None:
    """The outputs and the seeds, checked before the work."""
    # matplotlib would refuse a format only when it draws
    for flag, path in (("--plot", args.plot), ("--paper-png", args.paper_png)):
        if path is not None:
            check_output_path(path, flag, (".png",), "the plot")
    if args.figures is not None:
        if not args.paper:
            raise ConfigError("--figures", "draws the paper's figures: give it with --paper")
        if args.figures.exists() and not args.figures.is_dir():
            raise ConfigError("--figures", f"{args.figures} is a file; expected a folder")
        if not args.figures.parent.is_dir():
            raise ConfigError(
                "--figures", f"cannot make {args.figures}: {args.figures.parent} does not exist"
            )
    if args.seeds is not None and not 1 <= args.seeds <= MAX_SEEDS:
        # each session's recording and contacts are held for the pooled figures (~80 MB)
        raise ConfigError(
            "--seeds", f"must be 1 to {MAX_SEEDS} simulated sessions, found {args.seeds}"
        )


def _measure(args: argparse.Namespace, profile: DeskProfile) -> dict[str, Any]:
    """Every method's errors and run time on the paper's experiment simulated (the plot
    drawn if asked), with how they were measured."""
    from hapticdesk.bench.report import plot_pareto
    from hapticdesk.bench.runner import (
        COST_ROUNDS,
        WARMUP_ROUNDS,
        common_masks,
        default_configs,
        run_configs,
    )
    from hapticdesk.bench.scenes import paper_experiment
    from hapticdesk.sim import simulate

    started = time.perf_counter()
    seeds = args.seeds or (1 if args.quick else 3)
    recordings = [simulate(profile, paper_experiment(), seed=s) for s in range(seeds)]
    common = common_masks(profile, recordings)
    configs = default_configs(args.quick)
    stream_samples = 2400 if args.quick else 6000
    rows = run_configs(
        profile,
        configs,
        recordings,
        common=common,
        # (single pushes over 2 s of the desk, not 5: five rounds of every configuration
        # keep --quick under a minute)
        stream_samples=stream_samples,
        progress=None if args.json else lambda label: print(f"  {label}", file=sys.stderr),
    )
    if args.plot:
        plot_pareto(rows, args.plot)
    return {
        "desk": profile.name,
        "scene": "paper-experiment (9 points × 3 presses)",
        "seeds": seeds,
        "samples": int(sum(len(r.t) for r in recordings)),
        "seconds": round(time.perf_counter() - started, 1),
        "run_time": {
            "rounds": COST_ROUNDS,
            "warmup_rounds": WARMUP_ROUNDS,
            "single_pushes": stream_samples,
        },
        "methods": rows,
    }


def _print_table(info: dict[str, Any], plot: Path | None) -> None:
    from hapticdesk.bench.report import table

    rounds = info["run_time"]["rounds"]
    print(
        f"hapticdesk bench: {info['desk']}, the paper's experiment simulated with the "
        f"paper's noise, {info['seeds']} session(s), {info['samples']} samples"
    )
    print(
        "errors in mm against the truth, p95: at +20/+50 ms after the true touch-down and "
        "-20 ms before the true release (a point not reported is a miss: 'miss' when over "
        "5 % are), then on the samples all four methods locate (touch, hold, release until "
        "the contact ends); delays in ms after the true force crosses 2 N; run time the "
        f"median of {rounds} rounds after a warm-up, each timing every configuration "
        "in turn, with its range\n"
    )
    print(table(info["methods"]))
    if plot:
        print(f"\nplot: {plot}")


def _paper(args: argparse.Namespace, profile: DeskProfile) -> int:
    from hapticdesk.bench.paper import FIGURE_FILES, reproduce

    seeds = tuple(range(args.seeds or 3))
    if args.figures is not None:
        try:
            args.figures.mkdir(exist_ok=True)
        except OSError as err:
            raise cannot_write(args.figures, err) from None
    findings = reproduce(profile, seeds, args.paper_png, args.figures)
    if args.json:
        print(json.dumps([f.__dict__ for f in findings], indent=1, default=float))
        return 0
    for f in findings:
        mark = "holds" if f.holds else "DOES NOT HOLD"
        print(f"{f.figure}  [{mark}]\n  paper: {f.paper}\n  ours:  {f.ours}\n")
    if args.figures is not None:
        print(f"figures: {', '.join(str(args.figures / n) for n in FIGURE_FILES.values())}")
    return 0
