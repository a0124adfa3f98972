#!/usr/bin/env python3
"""The tap guard's odds chosen leaving one desk out, from one dump of the sweep's taps.

The tap guard (``recognizer.BoundRegions.find`` with a ``sigma``) refuses a tap whose place is
not ``ODDS`` times likelier in its region than in the nearest other one (``ODDS **
INSIDE_SHARE`` for a point inside its region). This script runs the taps of
scripts/desk_sweep.py (the same desks, seeds and judging: ``tap_accuracy.judge_taps``) once
with the guard off, keeps every tap's claimed place σ (radial), its distance to the region
it was placed in (0 inside, else the ``snap`` it took) and to the nearest other region, its
true error and whether it was right, then recounts the guard for a grid of rules: for each
desk, the rule the other desks allow (the most right taps with at most ``--wrong`` per 36,000
taps) counted on that desk. A refused tap is a missed one; a tap the guard refuses cannot
let another event match its touch (none does on the sweeps: the recount of the shipped rule
equals the sweep's).

The tap's place (``Touch.settled``: its pressed samples after a share of them) is chosen with
the guard: every tap is also placed with each of ``TAIL_SHARES`` (its region and distances
from there, right when that region is the one aimed at), and a rule is (tail share, inside
share, log odds). Only the taps the shipped place fires are kept: a touch no share of which
the shipped place brings into a button is not in the dump.

    python scripts/tap_guard_loo.py --desks 120 --seed 1 --jobs 2 --dump taps.json
    python scripts/tap_guard_loo.py --load taps.json          # the recount alone
"""

from __future__ import annotations

import argparse
import json
import math
import multiprocessing as mp
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))  # (the sweep's scripts beside this)

import desk_sweep as ds  # noqa: E402
import tap_accuracy as ta  # noqa: E402

from hapticdesk.gestures import recognizer, touch  # noqa: E402

#: shares of the odds a point inside its region needs, and the log odds tried
SHARES = (1.0, 2 / 3, 1 / 2, 1 / 3, 1 / 5, 0.0)
LOG_ODDS = np.exp(np.linspace(np.log(0.5), np.log(60.0), 240))
SNAP_BUDGET_TAPS = 36_000  # the floor: at most 5 wrong of 36,000 taps
#: shares of a touch's pressed samples left out of its place (Touch.settled), tried
TAIL_SHARES = (0.0, 0.2, 0.4, 0.5, 0.6, 0.65, 0.7, 0.75, 0.8, 0.9)

_found: list[dict] = []
_plain_find = recognizer.BoundRegions.find
_plain_settled = touch.Touch.settled
_last_touch: list[touch.Touch] = []


def _recording_settled(self, share=touch.SETTLED_SHARE):  # type: ignore[no-untyped-def]
    """``Touch.settled``, with the touch kept for :func:`_recording_find`."""
    _last_touch[:] = [self]
    return _plain_settled(self, share)


def _distances(regions, x: float, y: float, surface: int, region: str | None) -> dict:  # type: ignore[no-untyped-def]
    """The point's distance to ``region`` and to the nearest other region that does not hold it."""
    near = {r.name: float(r.distance(x, y)) for r in regions if r.surface_index == surface}
    others = [d for name, d in near.items() if name != region and d > 0]
    return {"d_found": near.get(region, math.inf), "d_other": min(others) if others else math.inf}


def _recording_find(self, x, y, surface, snap=False, sigma=0.0):  # type: ignore[no-untyped-def]
    """The guard off (``sigma`` dropped), with what it would have read kept, for the place
    the recognizer asks about and for each of TAIL_SHARES."""
    found, region = _plain_find(self, x, y, surface, snap)
    if sigma > 0 and self.gesture == "tap" and region is not None:
        tails = []
        for share in TAIL_SHARES:
            tx, ty, _ = _plain_settled(_last_touch[0], share)
            at = _plain_find(self, tx, ty, surface, snap)[1]
            tails.append({"region": at} | _distances(self.regions, tx, ty, surface, at))
        _found.append(
            {"x": x, "y": y, "sigma": sigma, "region": region, "tails": tails}
            | _distances(self.regions, x, y, surface, region)
        )  # fmt: skip
    return found, region


def _one_run(desk, n: int, seed: int) -> list[dict]:  # type: ignore[no-untyped-def]
    """One of the sweep's runs: its taps judged with the guard off, each with its record."""
    run = ta.simulate_taps(desk, n, seed)
    _found.clear()
    events = ta.gesture_events(desk, ta.buttons(desk), run.contacts)
    events = [e for e in events if e.gesture == "tap"]
    kept = {(r["x"], r["y"]): r for r in _found}
    verdicts = ta.judge_taps(desk, run.contacts, run.touches, run.which, run.peak, events)
    wrong = {k for _, k in verdicts.wrong}
    fs = desk.sample_rate_hz
    true_x, true_y, true_fn = (run.rec.extra[k] for k in ("true_x", "true_y", "true_fn"))
    times = np.array([e.t for e in events])
    used = np.zeros(len(events), bool)
    taps = []
    for i, (start, end, _, true_peak) in enumerate(run.touches):  # judge_taps' pairs, in order
        hit = np.flatnonzero((times >= start) & (times <= end + 0.2) & ~used)
        if len(hit) == 0:
            continue
        k = int(hit[0])
        used[k] = True
        if true_peak < desk.estimation.contact_force_n and k not in wrong:
            continue  # felt though under the contact force: judged neither way
        a, b = int(round(start * fs)), int(round((end + 0.1) * fs))
        on = true_fn[a:b] > 0
        tx, ty = float(np.mean(true_x[a:b][on])), float(np.mean(true_y[a:b][on]))
        tap = dict(kept[(events[k].x, events[k].y)], right=k not in wrong)
        tap["aimed"] = f"b{run.which[i] + 1}"
        tap["error"] = math.hypot(tap["x"] - tx, tap["y"] - ty)
        tap["peak_n"] = events[k].force_n
        tap.update(_touch_sigmas(run.contacts, start, end))
        taps.append(tap)
    return taps


def _touch_sigmas(contacts, start: float, end: float) -> dict:  # type: ignore[no-untyped-def]
    """The σ of the touch's located samples (the touch's time, its release's 0.1 s too): the
    least, the one at its highest force, and its samples' count."""
    on = (contacts.t >= start) & (contacts.t <= end + 0.1) & contacts.located
    if not on.any():
        return {"sigma_min": math.nan, "sigma_peak": math.nan, "located_n": 0}
    sigma, force = contacts.sigma_m[on], contacts.force_n[on]
    return {
        "sigma_min": float(sigma.min()),
        "sigma_peak": float(sigma[np.argmax(force)]),
        "located_n": int(on.sum()),
    }


def one_desk(job: tuple[int, int, int]) -> dict:
    """The taps of desk ``index`` of sweep ``seed`` (desk_sweep.one_desk's runs)."""
    seed, index, n = job
    recognizer.BoundRegions.find = _recording_find  # type: ignore[method-assign]
    touch.Touch.settled = _recording_settled  # type: ignore[method-assign]
    params, text = ds.draw_desk(seed, index)
    desk = ds.profile(text, f"sweep-{seed}-{index}")
    run_seed = 1000 * seed + 10 * index + 1  # (desk_sweep.one_desk, assess)
    taps = []
    for k, start in enumerate(range(0, n, 250)):
        taps += _one_run(desk, min(250, n - start), run_seed + k)
    params.pop("sensors")
    return {"params": params, "taps": taps}


def guard_scores(taps: list[dict], share: float, tail: int) -> np.ndarray:
    """The log odds each tap, placed by TAIL_SHARES[tail], has against the guard's, for a
    point inside ``share`` of them: (d_other² - d_found²) / σ², divided by ``share`` inside
    (σ radial: σ²/2 along a line); -inf where that place is in no region."""
    places = [t["tails"][tail] for t in taps]
    d_o = np.array([p["d_other"] for p in places])
    d_f = np.array([p["d_found"] for p in places])
    sigma = np.array([t["sigma"] for t in taps])
    with np.errstate(invalid="ignore"):
        score = np.where(np.isfinite(d_o), (d_o**2 - d_f**2) / sigma**2, np.inf)
    inside = d_f <= 0
    score[inside] = np.inf if share == 0 else score[inside] / share
    score[~np.isfinite(d_f)] = -np.inf
    return score


def counts(desks: list[dict]) -> tuple[np.ndarray, np.ndarray, list[tuple[float, float, float]]]:
    """Right and wrong taps (rules, desks) for every tail share, inside share and log odds,
    and the rules."""
    rules = [(tail, share, float(t)) for tail in TAIL_SHARES for share in SHARES for t in LOG_ODDS]
    right = np.zeros((len(rules), len(desks)), int)
    wrong = np.zeros_like(right)
    for d, desk in enumerate(desks):
        for j in range(len(TAIL_SHARES)):
            ok = np.array([t["tails"][j]["region"] == t["aimed"] for t in desk["taps"]], bool)
            for s, share in enumerate(SHARES):
                fire = guard_scores(desk["taps"], share, j)[None, :] >= LOG_ODDS[:, None]
                start = (j * len(SHARES) + s) * len(LOG_ODDS)
                rows = slice(start, start + len(LOG_ODDS))
                right[rows, d] = (fire & ok).sum(1)
                wrong[rows, d] = (fire & ~ok).sum(1)
    return right, wrong, rules


def leave_one_out(right: np.ndarray, wrong: np.ndarray, budget: float) -> np.ndarray:
    """For each desk the rule the other desks choose: the most right taps with at most
    ``budget`` wrong on them (ties: the first, the strictest share and odds)."""
    chosen = np.zeros(right.shape[1], int)
    for d in range(right.shape[1]):
        r, w = right.sum(1) - right[:, d], wrong.sum(1) - wrong[:, d]
        allowed = np.flatnonzero(w <= budget)
        chosen[d] = allowed[np.argmax(r[allowed])] if len(allowed) else len(r) - 1
    return chosen


def report(desks: list[dict], taps_per_desk: int, wrong_per_36k: float) -> None:
    """The held-out totals per share and with the share chosen too, then the desks with a
    wrong tap unguarded or another rule than most folds'."""
    right, wrong, rules = counts(desks)
    budget = wrong_per_36k * taps_per_desk * (len(desks) - 1) / SNAP_BUDGET_TAPS
    cols = np.arange(len(desks))
    unguarded = np.array([sum(not t["right"] for t in d["taps"]) for d in desks])
    fired = sum(len(d["taps"]) for d in desks)
    print(
        f"{len(desks)} desks; unguarded {fired - unguarded.sum()} right, {unguarded.sum()} "
        f"wrong; the others' budget {budget:.2f} wrong"
    )
    per_tail = len(SHARES) * len(LOG_ODDS)
    for j, tail in enumerate(TAIL_SHARES):
        rows = slice(j * per_tail, (j + 1) * per_tail)
        chosen = leave_one_out(right[rows], wrong[rows], budget)
        most = np.bincount(chosen).argmax()
        _, share, odds = rules[j * per_tail + most]
        print(f"placed after {tail:.2f} of the samples: held out {right[rows][chosen, cols].sum()}"
              f" right, {wrong[rows][chosen, cols].sum()} wrong (inside share {share:.2f}, log "
              f"odds {odds:.2f} in {np.sum(chosen == most)} folds)")  # fmt: skip
    chosen = leave_one_out(right, wrong, budget)
    most = np.bincount(chosen).argmax()
    tail, share, odds = rules[most]
    print(f"all chosen: held out {right[chosen, cols].sum()} right, {wrong[chosen, cols].sum()} "
          f"wrong (placed after {tail:.2f}, inside share {share:.2f}, log odds {odds:.2f} in "
          f"{np.sum(chosen == most)} folds; on every desk {right[most].sum()} right, "
          f"{wrong[most].sum()} wrong)")  # fmt: skip
    print("held out, desk by desk, where a tap was wrong unguarded or the rule differs:")
    for d, desk in enumerate(desks):
        p = desk["params"]
        if unguarded[d] == 0 and chosen[d] == most:
            continue
        tail, share, t = rules[chosen[d]]
        print(f"  #{p['index']:3d}: {right[chosen[d], d]} right, {wrong[chosen[d], d]} wrong "
              f"({unguarded[d]} unguarded; after {tail:.2f}, share {share:.2f}, log odds {t:.2f}; "
              f"{p['n_sensors']} legs, {p['ranged']} ranged, {p['rate_hz']} Hz)")  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--desks", type=int, default=120)
    parser.add_argument("--taps", type=int, default=300)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--dump", help="write the taps here")
    parser.add_argument("--load", help="recount the taps of an earlier --dump")
    parser.add_argument("--wrong", type=float, default=5.0, help="wrong taps per 36,000")
    args = parser.parse_args()
    if args.load:
        dump = json.loads(Path(args.load).read_text())
        desks, args.taps = dump["desks"], dump["taps"]
    else:
        jobs = [(args.seed, i, args.taps) for i in range(args.desks)]
        with mp.Pool(args.jobs) as pool:
            desks = pool.map(one_desk, jobs)
        if args.dump:
            dump = {"seed": args.seed, "taps": args.taps, "desks": desks}
            Path(args.dump).write_text(json.dumps(dump))
    report(desks, args.taps, args.wrong)


if __name__ == "__main__":
    main()
