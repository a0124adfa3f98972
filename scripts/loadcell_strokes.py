#!/usr/bin/env python3
"""Real strokes on the load-cell desks: the $1 logs at their real speed, traced on each
shipped load-cell profile (scripts/stroke_accuracy.py ``--human-speed`` on every desk in
turn), built-in templates and a person's own (1 and 3 a shape, captured on the same desk).

A load cell sees no shear: a finger dragged along the top pulls it with its friction
(μ·F_n along the motion) at the top's height h above the cells, and the cells feel that
force's moment, so the located point runs μ·h ahead of the finger (15 mm at μ = 0.5,
h = 3 cm). A person's own templates carry the same offset; the built-in ones do not.

``--sway-compensation on`` smooths the strokes as a desk whose path does not sway (the stroke
recognizer's calm σ; the compensation itself has no shear to work with on load cells): the
measure of what the recognizer's heavy σ costs here (docs/loadcells.md).

    python scripts/loadcell_strokes.py ../shared/data/dollar1 [--desk NAME] [--reps 3]
"""

from __future__ import annotations

import argparse

import stroke_accuracy  # (beside this)
from tap_accuracy import LOADCELL_DESKS, add_sway_compensation_option  # (beside this)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dollar", help="the $1 logs' folder (../shared/data/dollar1)")
    parser.add_argument("--desk", choices=(*LOADCELL_DESKS, "all"), default="all")
    parser.add_argument("--reps", type=int, default=3, help="test strokes per shape and speed")
    parser.add_argument("--seed", type=int, default=1)
    add_sway_compensation_option(parser, "the desk (on: its strokes smoothed as calm ones)")
    args = parser.parse_args()
    names = LOADCELL_DESKS if args.desk == "all" else (args.desk,)
    for name in names:
        stroke_accuracy.run_human_speed(
            args.dollar, args.reps, args.seed, name, args.sway_compensation
        )
        print()


if __name__ == "__main__":
    main()
