#!/usr/bin/env python3
"""Rules for rejecting a stroke with a writer's own templates, compared by nested
leave-one-writer-out on the $1 logs (the recognizer's scores, its choices as shipped).

A rule compares a statistic of the stroke against its nearest shape's templates with one of
those templates against each other (their *agreement*, from the templates alone) and takes
the stroke when the first reaches the second less a margin (and its best score reaches
``min_score``). The margin of every rule is made the way ``scripts/stroke_lowo.py`` makes the
shipped one (``stroke_lowo.nested_margin``: on four writers, nested, for the fifth), then
measured on the fifth: a writer's own 3 templates (% right), a shape left out of them (%
accepted), and writer-independent (the four others' 1,920 strokes as templates, % right).

    python scripts/stroke_rejection_rules.py $DOLLAR1      # ~5 min (the score matrix)
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import stroke_lowo  # noqa: E402

from hapticdesk.gestures.strokes.stroke_similarity import DEFAULT_CHOICES  # noqa: E402
from hapticdesk.gestures.strokes.stroke_verdict import nearest  # noqa: E402


def _off_diagonal(block: np.ndarray) -> np.ndarray:
    return block[~np.eye(len(block), dtype=bool)]


def _nearest_others(block: np.ndarray) -> np.ndarray:
    """Each template's best score against another of its shape (n,)."""
    return np.where(np.eye(len(block), dtype=bool), -np.inf, block).max(axis=1)


#: agreement of a shape's templates from their scores against each other (n, n)
AGREEMENTS: dict[str, Callable[[np.ndarray], float]] = {
    "lowest best": lambda b: float(_nearest_others(b).min()),
    "mean best": lambda b: float(_nearest_others(b).mean()),
    "median best": lambda b: float(np.median(_nearest_others(b))),
    "mean": lambda b: float(_off_diagonal(b).mean()),
    "lowest": lambda b: float(_off_diagonal(b).min()),
}
#: the stroke's statistic from its scores against its nearest shape's templates (k, n)
STATISTICS: dict[str, Callable[[np.ndarray], np.ndarray]] = {
    "best": lambda x: x.max(axis=1),
    "mean": lambda x: x.mean(axis=1),
}
#: (stroke statistic, agreement); the first is the shipped rule (stroke_verdict.py)
RULES = (
    ("best", "lowest best"),
    ("best", "mean best"),
    ("best", "median best"),
    ("mean", "mean"),
    ("mean", "lowest"),
)


def shortfalls(
    scores: np.ndarray, names: np.ndarray, templates_scores: np.ndarray, rule: tuple[str, str]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For strokes' ``scores`` (k, T) against templates of shapes ``names`` (T,) whose scores
    against each other are ``templates_scores`` (T, T): each stroke's nearest shape (k,), its
    best score (k,) and how far its statistic falls short of that shape's agreement (k,)."""
    found = nearest(scores, names, np.zeros(len(names), bool), {})
    statistic, agreement = STATISTICS[rule[0]], AGREEMENTS[rule[1]]
    short = np.empty(len(scores))
    for shape in dict.fromkeys(found.shape.tolist()):
        rows, columns = found.shape == shape, np.flatnonzero(names == shape)
        agreed = agreement(templates_scores[np.ix_(columns, columns)])
        short[rows] = agreed - statistic(scores[np.ix_(rows, columns)])
    return found.shape, found.score, short


def evaluate(logs: stroke_lowo.Logs, rule: tuple[str, str]) -> dict[str, dict[str, np.ndarray]]:
    """Per writer, % at each of MARGINS (arrays): own-3 right ("own"), unknown accepted,
    writer-independent right ("wi"), and of own-3 the strokes whose nearest shape is another
    and those of the right shape below ``min_score``; and the shortfalls (not %) of the own-3
    strokes of the right shape and of the unknown shapes, those reaching ``min_score``."""
    scores = logs.parts.score(DEFAULT_CHOICES)
    margins = np.asarray(stroke_lowo.MARGINS)
    # per writer and protocol: (of the right shape, best score, shortfall) of each split
    found: dict[str, dict[str, list[tuple[np.ndarray, np.ndarray, np.ndarray]]]] = {
        w: {"own": [], "unknown": [], "wi": []} for w in logs.writers
    }
    for w, _, te, tm in stroke_lowo.own_splits(logs, logs.writers):
        names, among = logs.shape[tm], scores[np.ix_(tm, tm)]
        shape, best, short = shortfalls(scores[np.ix_(te, tm)], names, among, rule)
        found[w]["own"].append((shape == logs.shape[te], best, short))
        for left_out in dict.fromkeys(logs.shape[te].tolist()):
            keep, tested = names != left_out, te[logs.shape[te] == left_out]
            _, best, short = shortfalls(
                scores[np.ix_(tested, tm[keep])], names[keep], among[np.ix_(keep, keep)], rule
            )
            found[w]["unknown"].append((np.zeros(len(tested), bool), best, short))
    for w in logs.writers:
        te, tm = np.flatnonzero(logs.writer == w), np.flatnonzero(logs.writer != w)
        shape, best, short = shortfalls(
            scores[np.ix_(te, tm)], logs.shape[tm], scores[np.ix_(tm, tm)], rule
        )
        found[w]["wi"].append((shape == logs.shape[te], best, short))
    out: dict[str, dict[str, np.ndarray]] = {}
    for w, protocols in found.items():
        mine = out[w] = {}
        for protocol, parts in protocols.items():
            right, best, short = (np.concatenate(p) for p in zip(*parts, strict=True))
            reaches = best >= stroke_lowo.MIN_SCORE
            taken = reaches[:, None] & (short[:, None] <= margins)
            if protocol == "unknown":
                mine["unknown"] = 100 * taken.mean(axis=0)
                mine["unknown shortfall"] = short[reaches]
                continue
            mine[protocol] = 100 * (taken & right[:, None]).mean(axis=0)
            if protocol == "own":
                mine["nearest wrong"] = np.full(len(margins), 100 * np.mean(~right))
                mine["below min_score"] = np.full(len(margins), 100 * np.mean(right & ~reaches))
                mine["own shortfall"] = short[right & reaches]
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", help="the $1 logs (one folder per writer)")
    args = parser.parse_args()
    started = time.perf_counter()
    logs, _ = stroke_lowo.load(args.folder)
    writers = logs.writers
    print(
        "| stroke's | against the templates' | own 3: mean | worst | unknown: mean | worst |"
        " writer-independent: mean | worst | margins (each fold; all five) |\n"
        "|---|---|---:|---:|---:|---:|---:|---:|---|"
    )
    losses = []
    for rule in RULES:
        per = evaluate(logs, rule)
        rates = {w: per[w]["unknown"] / 100 for w in writers}
        chosen = {
            w: stroke_lowo.nested_margin(rates, [v for v in writers if v != w]) for w in writers
        }
        cells = []
        for key, worst in (("own", min), ("unknown", max), ("wi", min)):
            held = {w: per[w][key][chosen[w]] for w in writers}
            who = worst(held, key=held.__getitem__)
            cells += [f"{np.mean(list(held.values())):.2f} %", f"{held[who]:.2f} % ({who})"]
        margins = ", ".join(f"{stroke_lowo.MARGINS[chosen[w]]:g}" for w in writers)
        on_all = stroke_lowo.MARGINS[stroke_lowo.nested_margin(rates, writers)]
        print(f"| {rule[0]} | {rule[1]} | {' | '.join(cells)} | {margins}; {on_all:g} |")
        if rule == RULES[0]:
            for w in writers:
                at = chosen[w]
                wrong, below = per[w]["nearest wrong"][at], per[w]["below min_score"][at]
                rejected = 100 - per[w]["own"][at] - wrong - below
                margin = stroke_lowo.MARGINS[at]
                short = per[w]["own shortfall"]
                short = short[short > margin]
                fall = f": {short.min():.3f}-{short.max():.3f} short" if len(short) else ""
                losses.append(
                    f"- {w}: {per[w]['own'][at]:.2f} % right; {wrong:.2f} % nearest another "
                    f"shape, {below:.2f} % below min_score, {rejected:.2f} % rejected by the "
                    f"margin ({margin:g}{fall})"
                )
            unknown = np.concatenate([per[w]["unknown shortfall"] for w in writers])
            tenth, quarter, half = np.quantile(unknown, [0.1, 0.25, 0.5])
            losses.append(
                f"- unknown shapes (all writers) that reach min_score fall short of their "
                f"nearest shape's agreement by less than {tenth:.3f} (a tenth), "
                f"{quarter:.3f} (a quarter), {half:.3f} (half)"
            )
    print("\nA writer's own 3 templates with the shipped rule, what is lost:\n")
    print("\n".join(losses))
    print(
        f"\n(`python scripts/stroke_rejection_rules.py {args.folder}`, "
        f"{time.perf_counter() - started:.0f} s)"
    )


if __name__ == "__main__":
    main()
