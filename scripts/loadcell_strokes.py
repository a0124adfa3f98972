#!/usr/bin/env python3
"""Real strokes on load-cell desks: the $1 logs at their real speed (scripts/stroke_accuracy.py
``--human-speed``), on each shipped load-cell profile, with and without the drag's lever
taken off.

A load cell sees no shear. A finger dragged across the top pulls it along with its friction
(μ·F_n along the motion) at the top's height h above the cells; the cells feel that force's
moment, so the located point runs ahead of the finger by μ·h along the motion (15 mm at
μ = 0.5, h = 3 cm; the simulator's finger has μ = 0.5). ``--lever MU`` takes μ·h back off
every located point along the track's own direction of motion before the strokes are
captured: an experiment for the gesture and estimator code, which do not do it (see
docs/loadcells.md).

    python scripts/loadcell_strokes.py ../shared/data/dollar1                 # every desk
    python scripts/loadcell_strokes.py ../shared/data/dollar1 --desk balance-board --lever 0.5
"""

from __future__ import annotations

import argparse
from functools import partial

import numpy as np
import stroke_accuracy  # (beside this)
from tap_accuracy import LOADCELL_DESKS  # (beside this)

from hapticdesk.estimator.contacts import ContactBlock
from hapticdesk.files.profile import DeskProfile

#: the located track's direction of motion: its velocity over this long
VELOCITY_S = 0.05
#: below this speed the finger is taken as still (the simulator's friction fades below
#: 5 mm/s, human.py's V_STATIC)
STILL_M_S = 0.005


def without_lever(desk: DeskProfile, contacts: ContactBlock, mu: float) -> ContactBlock:
    """``contacts`` with every located point moved back by μ·h along the track's direction
    of motion, h the top's height above the cells (in place; returned)."""
    cells_z = float(np.mean([s.position[2] for s in desk.sensors]))
    lever = mu * (float(desk.surfaces[0].origin[2]) - cells_z)
    fs = desk.sample_rate_hz
    span = max(1, round(VELOCITY_S * fs))
    x, y, ok = contacts.x, contacts.y, contacts.located
    # a touch's samples in a row: velocity by a central difference over the span
    vx = np.zeros_like(x)
    vy = np.zeros_like(y)
    inner = np.arange(span, len(x) - span)
    both = ok[inner - span] & ok[inner + span] & ok[inner]
    idx = inner[both]
    vx[idx] = (x[idx + span] - x[idx - span]) * fs / (2 * span)
    vy[idx] = (y[idx + span] - y[idx - span]) * fs / (2 * span)
    speed = np.hypot(vx, vy)
    # friction builds up with speed as the simulated finger's does (regularised near rest)
    scale = lever / np.sqrt(speed**2 + STILL_M_S**2)
    contacts.x = np.where(ok, x - scale * vx, x)
    contacts.y = np.where(ok, y - scale * vy, y)
    return contacts


def trace_without_lever(
    items: list, seed: int, desk_name: str = "kitamura2017", sway: str = "auto", mu: float = 0.5
) -> list[np.ndarray | None]:
    """stroke_accuracy.trace_on_desk with :func:`without_lever` between the estimator and
    the capture."""
    paths: list[np.ndarray | None] = []
    session = stroke_accuracy.STROKES_A_SESSION
    for lo in range(0, len(items), session):
        part = items[lo : lo + session]
        desk, rec, contacts = stroke_accuracy.simulate_strokes(part, seed + lo, desk_name, sway)
        contacts = without_lever(desk, contacts, mu)
        paths += stroke_accuracy.capture_strokes(desk, rec, contacts, len(part))
    return paths


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dollar", help="the $1 logs' folder (../shared/data/dollar1)")
    parser.add_argument("--desk", choices=(*LOADCELL_DESKS, "all"), default="all")
    parser.add_argument("--reps", type=int, default=3, help="test strokes per shape and speed")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument(
        "--lever",
        type=float,
        metavar="MU",
        help="take the drag's lever μ·h off the located points, with this μ (default: not)",
    )
    args = parser.parse_args()
    names = LOADCELL_DESKS if args.desk == "all" else (args.desk,)
    if args.lever is not None:
        # run_human_speed traces through the module's trace_on_desk: this run's goes there
        stroke_accuracy.trace_on_desk = partial(trace_without_lever, mu=args.lever)  # type: ignore[assignment]
        print(f"(the drag's lever μ·h taken off the located points, μ = {args.lever:g})\n")
    for name in names:
        stroke_accuracy.run_human_speed(args.dollar, args.reps, args.seed, name, "auto")
        print()


if __name__ == "__main__":
    main()
