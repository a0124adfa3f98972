#!/usr/bin/env python3
"""Gestures nobody made, on randomised simulated desks.

Draws N desks from a seed (top 0.8-1.8 x 0.5-0.9 m at 0.6-1.1 m, 3-8 legs: corners plus
optional middle legs, random yaw, some upside down (roll 180), some `reports: load`, some
with the paper's rated ranges (so rounded to 1/2000 of the rating), mass 8-45 kg, natural
frequency 3.5-10 Hz, 500/1000/1200 Hz, `fused`) and on each runs

1. ``tap_accuracy.measure``'s runs (the edge taps of scripts/tap_accuracy.py with its
   not-taps every 40 taps: a swipe over the buttons, a 1.5 s press, a 0.35 kg mug put on a
   button and lifted), judged as it judges them (``tap_accuracy.judge_taps``): right/judged,
   wrong, missed, phantom, with what was happening at every wrong or phantom tap;
2. on the same contacts a second engine whose layout also binds ``long_press`` (0.8 s) on
   the nine buttons and ``swipe`` anywhere, to count long presses and swipes nobody made (a
   long press outside a 1.5 s press or in another button; a swipe outside the swipe, or in
   the wrong direction).

Desks with any gesture nobody made are measured again with ``sway_compensation`` off.

    python scripts/desk_sweep.py --desks 120 --taps 300 --seed 1 --jobs 2 --out sweep.json
    python scripts/desk_sweep.py --dig sweep.json DESK CASE [--sway off]  # one case, in detail
"""

from __future__ import annotations

import argparse
import json
import math
import multiprocessing as mp
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))  # (tap_accuracy beside this one)

import tap_accuracy as ta  # noqa: E402

from hapticdesk.estimator import ContactEstimator  # noqa: E402
from hapticdesk.estimator.contacts import PHASE_NAMES, SOURCE_NAMES  # noqa: E402
from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.profile_reader import profile_from_mapping  # noqa: E402
from hapticdesk.files.yamlfile import load_marked_yaml  # noqa: E402
from hapticdesk.gestures.layout_reader import load_layout  # noqa: E402
from hapticdesk.sim import LongPress, Swipe  # noqa: E402
from hapticdesk.sim.timeline import Timeline  # noqa: E402

RANGE = "range: {force_n: [150, 150, 300], moment_nm: [4, 4, 4]}"
EXTRA_BINDINGS = (
    "".join(
        f"  - {{gesture: long_press, region: b{k}, hold_s: 0.8, do: log}}\n" for k in range(1, 10)
    )
    + "  - {gesture: swipe, direction: [right, up, left, down], do: log}\n"
)


# --- desks ---------------------------------------------------------------------------------


def draw_desk(seed: int, index: int) -> tuple[dict, str]:
    """Desk ``index`` of the sweep ``seed``: its parameters and its profile text."""
    rng = np.random.default_rng([seed, index])
    width = float(rng.uniform(0.8, 1.8))
    depth = float(rng.uniform(0.5, 0.9))
    height = float(rng.uniform(0.6, 1.1))
    n = int(rng.integers(3, 9))
    hx = width / 2 - float(rng.uniform(0.03, 0.10))  # legs a little inside the corners
    hy = depth / 2 - float(rng.uniform(0.03, 0.08))
    corners = [(-hx, -hy), (hx, -hy), (-hx, hy), (hx, hy)]
    mids = [(0.0, -hy), (0.0, hy), (-hx, 0.0), (hx, 0.0)]
    if n == 3:
        if rng.random() < 0.5:  # three corners
            drop = int(rng.integers(4))
            legs = [c for k, c in enumerate(corners) if k != drop]
            layout = f"3 corners (no {['fl', 'fr', 'bl', 'br'][drop]})"
        else:  # two corners on one long side, one leg in the middle of the other
            front = bool(rng.random() < 0.5)
            legs = (corners[:2] + [mids[1]]) if front else (corners[2:] + [mids[0]])
            layout = "tripod " + (
                "front pair + back middle" if front else "back pair + front middle"
            )
    else:
        order = rng.permutation(4)
        chosen = [mids[k] for k in order[: n - 4]]
        legs = corners + chosen
        names = ["front-mid", "back-mid", "left-mid", "right-mid"]
        layout = "4 corners" + ("".join(f" + {names[k]}" for k in order[: n - 4]))
    jitter = rng.uniform(-0.02, 0.02, size=(len(legs), 2))
    sensors = []
    lines = []
    for k, ((x, y), (jx, jy)) in enumerate(zip(legs, jitter, strict=True)):
        yaw = int(rng.integers(0, 360))
        flipped = bool(rng.random() < 0.25)
        load = bool(rng.random() < 0.25)
        ranged = bool(rng.random() < 0.5)
        x, y = round(x + jx, 3), round(y + jy, 3)
        sensors.append(
            {"pos": [x, y], "yaw": yaw, "roll180": flipped, "load": load, "range": ranged}
        )
        parts = [
            f"name: s{k}",
            f"position: [{x}, {y}, 0.0]",
            f"rotation_rpy_deg: [{180 if flipped else 0}, 0, {yaw}]",
        ]
        if load:
            parts.append("reports: load")
        if ranged:
            parts.append(RANGE)
        lines.append("  - {" + ", ".join(parts) + "}")
    mass = round(float(rng.uniform(8.0, 45.0)), 1)
    natural = round(float(rng.uniform(3.5, 10.0)), 2)
    rate = int(rng.choice([500, 1000, 1200]))
    w2, d2 = round(width / 2, 3), round(depth / 2, 3)
    name = f"sweep-{seed}-{index}"
    text = (
        f"name: {name}\n"
        f"sample_rate_hz: {rate}\n"
        f"desk: {{mass_kg: {mass}, natural_frequency_hz: {natural}}}\n"
        "sensors:\n" + "\n".join(lines) + "\n"
        "surfaces:\n"
        "  - name: top\n"
        f"    origin: [0.0, 0.0, {height:.3f}]\n"
        "    normal: [0, 0, 1]\n"
        f"    polygon: [[-{w2}, -{d2}], [{w2}, -{d2}], [{w2}, {d2}], [-{w2}, {d2}]]\n"
        "estimation: {method: fused}\n"
    )
    params = {
        "index": index,
        "width": round(width, 3),
        "depth": round(depth, 3),
        "height": round(height, 3),
        "n_sensors": n,
        "legs": layout,
        "mass_kg": mass,
        "fn_hz": natural,
        "rate_hz": rate,
        "flipped": sum(s["roll180"] for s in sensors),
        "load": sum(s["load"] for s in sensors),
        "ranged": sum(s["range"] for s in sensors),
        "sensors": sensors,
    }
    return params, text


def profile(text: str, name: str) -> DeskProfile:
    """The desk profile of :func:`draw_desk`'s text (named ``name``.yaml in messages)."""
    path = Path(f"{name}.yaml")
    return profile_from_mapping(load_marked_yaml(path, text), path)


def full_layout(desk: DeskProfile):
    """buttons.yaml with a 0.8 s long press on every button and swipes anywhere."""
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / ta.BUTTONS.name
        path.write_text(ta.BUTTONS.read_text() + EXTRA_BINDINGS)
        return load_layout(path, profile=desk)


# --- the detail pass -------------------------------------------------------------------------


def region_of(x: float, y: float) -> str | None:
    for k, (cx, cy) in enumerate(ta.CENTRES):
        if abs(x - cx) <= ta.HALF and abs(y - cy) <= ta.HALF:
            return f"b{k + 1}"
    return None


def inside_edge_mm(x: float, y: float, button: int) -> float:
    """How far (x, y) is inside button ``button`` (0..8), mm (negative: outside)."""
    cx, cy = ta.CENTRES[button]
    return 1e3 * min(ta.HALF - abs(x - cx), ta.HALF - abs(y - cy))


def contact_summary(contacts, a: int, b: int) -> dict:
    """What the estimator said over samples a..b."""
    sl = slice(a, b)
    inc = contacts.in_contact[sl]
    loc = contacts.located[sl] & inc
    out = {
        "in_contact": int(inc.sum()),
        "located": int(loc.sum()),
        "peak_force_est": round(float(contacts.force_n[sl][inc].max()), 2) if inc.any() else 0,
    }
    if loc.any():
        x, y, s = contacts.x[sl][loc], contacts.y[sl][loc], contacts.sigma_m[sl][loc]
        best = int(np.argmin(s))
        out.update(
            x_med=round(1e3 * float(np.median(x)), 1),
            y_med=round(1e3 * float(np.median(y)), 1),
            x_best=round(1e3 * float(x[best]), 1),
            y_best=round(1e3 * float(y[best]), 1),
            sigma_min=round(1e3 * float(s.min()), 2),
            sigma_med=round(1e3 * float(np.median(s)), 2),
            spread_mm=round(1e3 * float(np.hypot(np.ptp(x), np.ptp(y))), 1),
            sources={
                SOURCE_NAMES[v]: int(c)
                for v, c in zip(
                    *np.unique(contacts.source[sl][loc], return_counts=True), strict=True
                )
            },
            phases={
                PHASE_NAMES[v]: int(c)
                for v, c in zip(
                    *np.unique(contacts.phase[sl][loc], return_counts=True), strict=True
                )
            },
        )
    return out


def detail_run(desk: DeskProfile, n: int, seed: int, sensors=None) -> dict:
    """``ta.run(desk, buttons, n, seed)``: its tally, with what happened at each wrong or
    phantom tap, and a second engine's long presses and swipes nobody made."""
    run = ta.simulate_taps(desk, n, seed, sensors)
    scene, which, peak, rec, contacts = run.scene, run.which, run.peak, run.rec, run.contacts
    touches = run.touches
    taps = [e for e in ta.gesture_events(desk, ta.buttons(desk), contacts) if e.gesture == "tap"]
    full = ta.gesture_events(desk, full_layout(desk), contacts)
    spans = Timeline(desk, scene, seed).spans
    starts = np.array([s.start_s for s in spans])
    fs = desk.sample_rate_hz

    def context(t: float) -> dict:
        k = int(np.searchsorted(starts, t, side="right")) - 1
        span = spans[max(k, 0)]
        action = scene.actions[span.index]
        return {
            "action": span.index,
            "kind": type(action).__name__,
            "since_start_s": round(t - span.start_s, 3),
            "span_s": [round(span.start_s, 3), round(span.end_s, 3)],
        }

    # taps: judged as ta.run judges them, each wrong one and each phantom in detail
    verdicts = ta.judge_taps(desk, contacts, touches, which, peak, taps)
    tally = verdicts.tally
    cases = []
    for i, k in verdicts.wrong:
        start, end, action, true_peak = touches[i]
        e = taps[k]
        a, b = int(round(start * fs)), int(round((end + 0.1) * fs))
        touching = rec.extra["true_fn"][a:b] > 0
        tx = float(np.mean(rec.extra["true_x"][a:b][touching]))
        ty = float(np.mean(rec.extra["true_y"][a:b][touching]))
        aim = scene.actions[action].point
        cases.append(
            {
                "class": "wrong tap",
                "seed": seed,
                "t": round(start, 3),
                "tap": i,
                "aimed": f"b{which[i] + 1}",
                "aim_mm": [round(1e3 * aim[0], 1), round(1e3 * aim[1], 1)],
                "true_mm": [round(1e3 * tx, 1), round(1e3 * ty, 1)],
                "true_region": region_of(tx, ty),
                "true_inside_mm": round(inside_edge_mm(tx, ty, int(which[i])), 1),
                "peak_n": round(true_peak, 2),
                "duration_ms": round(1e3 * (end - start)),
                "fired": e.region,
                "fired_mm": [round(1e3 * e.x, 1), round(1e3 * e.y, 1)],
                "error_mm": round(1e3 * math.hypot(e.x - tx, e.y - ty), 1),
                "est": contact_summary(contacts, a, b),
            }
        )
    for k in verdicts.phantom:
        e = taps[k]
        j = min(int(np.searchsorted(contacts.t, e.t)), len(contacts.t) - 1)
        seg_end = j
        while seg_end > 0 and not contacts.in_contact[seg_end]:
            seg_end -= 1  # the estimator's touch that ended at the event
        seg_start = seg_end
        while seg_start > 0 and contacts.in_contact[seg_start - 1]:
            seg_start -= 1
        cases.append(
            {
                "class": "phantom tap",
                "seed": seed,
                "t": round(e.t, 3),
                "fired": e.region,
                "fired_mm": [round(1e3 * e.x, 1), round(1e3 * e.y, 1)],
                "force_n": round(e.force_n or 0.0, 2),
                "context": context(e.t),
                "true_fn_at": round(float(rec.extra["true_fn"][min(j, len(rec.t) - 1)]), 2),
                "est_touch_s": [
                    round(float(contacts.t[seg_start]), 3),
                    round(float(contacts.t[seg_end]), 3),
                ],
                "est": contact_summary(contacts, seg_start, seg_end + 1),
            }
        )

    # long presses and swipes nobody made (the second engine)
    extra = {"lp_right": 0, "lp_wrong": 0, "lp_phantom": 0, "sw_right": 0, "sw_wrong": 0,
             "sw_phantom": 0, "lp_made": 0, "sw_made": 0, "tap_and_swipe": 0}  # fmt: skip
    # one gesture per touch: a tap and a swipe decided at the same release are one touch
    tap_times = {e.t for e in full if e.gesture == "tap"}
    extra["tap_and_swipe"] = sum(e.gesture == "swipe" and e.t in tap_times for e in full)
    extra["lp_made"] = sum(isinstance(a, LongPress) for a in scene.actions)
    extra["sw_made"] = sum(isinstance(a, Swipe) for a in scene.actions)
    for e in full:
        if e.gesture not in ("long_press", "swipe") or e.phase is not None:
            continue
        ctx = context(e.t)
        action = scene.actions[ctx["action"]]
        made, key = (LongPress, "lp") if e.gesture == "long_press" else (Swipe, "sw")
        if isinstance(action, made):
            # a long press in the pressed button; a swipe the way the scene's swipes go
            ok = (
                e.region == region_of(*action.point)
                if isinstance(action, LongPress)
                else e.direction == "right"
            )
            extra[f"{key}_right" if ok else f"{key}_wrong"] += 1
            if ok:
                continue
            cls = f"wrong {e.gesture}"
        else:
            extra[f"{key}_phantom"] += 1
            cls = f"phantom {e.gesture}"
        j = int(np.searchsorted(contacts.t, e.t))
        cases.append(
            {
                "class": cls,
                "seed": seed,
                "t": round(e.t, 3),
                "fired": e.region,
                "direction": e.direction,
                "fired_mm": [round(1e3 * e.x, 1), round(1e3 * e.y, 1)],
                "context": ctx,
                "true_fn_at": round(float(rec.extra["true_fn"][min(j, len(rec.t) - 1)]), 2),
            }
        )
    return {"tally": tally, "extra": extra, "cases": cases}


def assess(desk: DeskProfile, n: int, seed: int, chunk: int = 250, sensors=None) -> dict:
    """``ta.measure``'s runs (chunks of ``chunk`` taps, seeds ``seed``, ``seed`` + 1 …),
    each in detail (:func:`detail_run`)."""
    tally = ta.Tally()
    extra: dict = {}
    cases: list = []
    for k, start in enumerate(range(0, n, chunk)):
        part = detail_run(desk, min(chunk, n - start), seed + k, sensors)
        tally.add(part["tally"])
        for key, v in part["extra"].items():
            extra[key] = extra.get(key, 0) + v
        cases += part["cases"]
    return {"tally": vars(tally), "extra": extra, "cases": cases}


def problems(result: dict) -> int:
    t, x = result["tally"], result["extra"]
    return (
        t["wrong"]
        + t["phantom"]
        + x["lp_wrong"]
        + x["lp_phantom"]
        + x["sw_wrong"]
        + x["sw_phantom"]
    )


def one_desk(job: tuple[int, int, int]) -> dict:
    seed, index, taps = job
    started = time.monotonic()
    params, text = draw_desk(seed, index)
    desk = profile(text, f"sweep-{seed}-{index}")
    run_seed = 1000 * seed + 10 * index + 1
    out = {"params": params, "run_seed": run_seed, "auto": assess(desk, taps, run_seed)}
    if problems(out["auto"]):
        out["off"] = assess(ta.with_sway_compensation(desk, "off"), taps, run_seed)
    out["seconds"] = round(time.monotonic() - started, 1)
    return out


# --- report ----------------------------------------------------------------------------------


def counts(r: dict) -> str:
    t, x = r["tally"], r["extra"]
    judged = t["taps"] - t["under"]
    return (
        f"{t['right']}/{judged} wrong {t['wrong']} phantom {t['phantom']} missed {t['missed']}"
        f" | lp wrong {x['lp_wrong']} phantom {x['lp_phantom']} (right {x['lp_right']}/"
        f"{x['lp_made']}) | swipe wrong {x['sw_wrong']} phantom {x['sw_phantom']} (right "
        f"{x['sw_right']}/{x['sw_made']})"
    )


def describe(p: dict) -> str:
    return (
        f"#{p['index']}: {p['width']:.2f}x{p['depth']:.2f} m h {p['height']:.2f}, "
        f"{p['n_sensors']} legs ({p['legs']}; {p['flipped']} flipped, {p['load']} load, "
        f"{p['ranged']} ranged), {p['mass_kg']} kg, {p['fn_hz']} Hz, {p['rate_hz']} Hz"
    )


def report(results: list[dict]) -> None:
    total: dict = {}
    for r in results:
        for key, v in [*r["auto"]["tally"].items(), *r["auto"]["extra"].items()]:
            total[key] = total.get(key, 0) + v
    print(f"\n{len(results)} desks")
    for r in results:
        flag = " <-- PROBLEM" if problems(r["auto"]) else ""
        print(f"{describe(r['params'])}\n    auto: {counts(r['auto'])}{flag}")
        if "off" in r:
            print(f"    off:  {counts(r['off'])}")
    judged = total["taps"] - total["under"]
    print(
        f"\nALL: taps {total['taps']}, judged {judged}, right {total['right']} "
        f"({100 * total['right'] / judged:.1f} %), wrong {total['wrong']}, phantom "
        f"{total['phantom']}, missed {total['missed']} ({total['unlocated']} not located, "
        f"{total['unfelt']} not felt); long presses wrong {total['lp_wrong']} phantom "
        f"{total['lp_phantom']} right {total['lp_right']}/{total['lp_made']}; swipes wrong "
        f"{total['sw_wrong']} phantom {total['sw_phantom']} right {total['sw_right']}/"
        f"{total['sw_made']}; touches that fired a tap and a swipe {total['tap_and_swipe']}"
    )
    bad = [r for r in results if problems(r["auto"])]
    print(f"desks with a gesture nobody made: {len(bad)} of {len(results)}")
    for r in bad:
        print(f"\n{describe(r['params'])}")
        for c in r["auto"]["cases"]:
            print("   ", json.dumps(c))


# --- dig ------------------------------------------------------------------------------------


def dig(path: str, index: int, case: int, sway: str, sensors=None) -> None:
    """Print one case of a results file sample by sample."""
    sweep = json.loads(Path(path).read_text())
    r = {d["params"]["index"]: d for d in sweep["desks"]}[index]
    seed = sweep["seed"]
    params, text = draw_desk(seed, index)
    desk = ta.with_sway_compensation(profile(text, f"sweep-{seed}-{index}"), sway)
    c = r["auto"]["cases"][case]
    print(describe(params))
    print(json.dumps(c, indent=1))
    chunk_seed = c["seed"]
    n_in_chunk = min(250, sweep["taps"] - 250 * (chunk_seed - r["run_seed"]))
    taps = ta.simulate_taps(desk, n_in_chunk, chunk_seed, sensors)
    rec, contacts = taps.rec, taps.contacts
    for layout in (ta.buttons(desk), full_layout(desk)):
        ev = ta.gesture_events(desk, layout, contacts)
        near = [e for e in ev if abs(e.t - c["t"]) < 1.5]
        print(
            "events near:",
            [
                (
                    round(e.t, 3),
                    e.gesture,
                    e.region,
                    e.direction,
                    e.phase,
                    round(1e3 * e.x, 1),
                    round(1e3 * e.y, 1),
                )
                for e in near
            ],
        )
    fs = desk.sample_rate_hz
    a, b = int((c["t"] - 0.3) * fs), int((c["t"] + 0.5) * fs)
    est = ContactEstimator(desk, trace=True)
    est.push(rec.t, rec.wrench)
    from hapticdesk.estimator import CandidateTrace

    tr = CandidateTrace.concat(est.traces)
    win = (tr.t >= rec.t[a]) & (tr.t <= rec.t[min(b, len(rec.t) - 1)])
    print("candidates in contact: t, |F| lp, rate | force, diff, fast: x y sig (* not valid)")
    for k in np.flatnonzero(win)[:: max(1, int(fs / 500))]:
        row = f"{tr.t[k]:8.3f} {tr.force_n[k]:5.2f} {tr.rate_n_s[k]:6.1f}"
        for name in ("force", "diff", "fast"):
            p, v, sg = (
                getattr(tr, name + "_point")[:, k],
                getattr(tr, name + "_valid")[k],
                getattr(tr, name + "_sigma_m")[k],
            )
            row += f" | {1e3 * p[0]:7.1f} {1e3 * p[1]:7.1f} {1e3 * sg:6.1f}{'' if v else '*'}"
        print(row)
    step = 1
    print("t, true_fn, true_x, true_y | in_contact, located, force, x, y, sigma mm, source, phase")
    for k in range(a, b, step):
        tf = rec.extra["true_fn"][k]
        if tf <= 0 and not contacts.in_contact[k]:
            continue
        print(
            f"{rec.t[k]:8.3f} {tf:5.2f} {1e3 * rec.extra['true_x'][k]:7.1f} "
            f"{1e3 * rec.extra['true_y'][k]:7.1f} | {int(contacts.in_contact[k])} "
            f"{int(contacts.located[k])} {contacts.force_n[k]:5.2f} {1e3 * contacts.x[k]:7.1f} "
            f"{1e3 * contacts.y[k]:7.1f} {1e3 * contacts.sigma_m[k]:6.2f} "
            f"{SOURCE_NAMES[contacts.source[k]]:5s} {PHASE_NAMES[contacts.phase[k]]}"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--desks", type=int, default=40)
    parser.add_argument("--first", type=int, default=0, help="first desk index")
    parser.add_argument("--taps", type=int, default=300)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--out", default="results.json")
    parser.add_argument("--dig", nargs=3, metavar=("RESULTS", "DESK", "CASE"))
    parser.add_argument("--sway", default="auto", choices=("auto", "on", "off"))
    parser.add_argument("--res0", action="store_true", help="--dig with unrounded sensors")
    args = parser.parse_args()
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)  # (before minutes of work)
    if args.dig:
        from hapticdesk.sim.sensors import SensorParameters

        sensors = SensorParameters(resolution=0.0) if args.res0 else None
        dig(args.dig[0], int(args.dig[1]), int(args.dig[2]), args.sway, sensors)
        return
    started = time.monotonic()
    jobs = [(args.seed, i, args.taps) for i in range(args.first, args.first + args.desks)]
    results = []
    with mp.Pool(args.jobs) as pool:
        for r in pool.imap_unordered(one_desk, jobs):
            results.append(r)
            print(
                f"desk {r['params']['index']}: {counts(r['auto'])} ({r['seconds']} s)", flush=True
            )
    results.sort(key=lambda r: r["params"]["index"])
    Path(args.out).write_text(
        json.dumps({"seed": args.seed, "taps": args.taps, "desks": results}, indent=1)
    )
    report(results)
    print(f"\n({time.monotonic() - started:.0f} s)")


if __name__ == "__main__":
    main()
