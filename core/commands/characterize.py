"""``hapticdesk characterize REC --desk D [--json]``: measure what a new desk needs — noise per
channel, natural frequencies (from the free decay after knocks), a low-pass cut-off below the
lowest mode, and drift — and print the profile snippet. A profile of one sensor and no
surfaces (a sensor on the bench) is valid here.

Record the desk untouched for half a minute or more, then knock it sideways (or tap it) a few
times with a few seconds of quiet after each.
"""

from __future__ import annotations

import argparse
import json

from hapticdesk.analysis.characterize import CUTOFF_RATIO, Characterization, characterize
from hapticdesk.analysis.quiet_windows import ChannelDrift, ChannelNoise
from hapticdesk.files.profile_reader import load_profile
from hapticdesk.recordings import read_any_recording


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("recording", help="recording (.csv, .npz) or CAN log")
    parser.add_argument("--desk", required=True, help="desk (or bench sensor) profile name or path")
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def run(args: argparse.Namespace) -> int:
    profile = load_profile(args.desk)
    # (its rate is measured, not taken from the profile)
    recording = read_any_recording(args.recording, profile, at_profile_rate=False)
    result = characterize(profile, recording, where=str(args.recording))
    if args.json:
        info = result.to_dict()
        info.update(recording=str(args.recording), desk=profile.name)
        print(json.dumps(info))
    else:
        print(format_report(result, str(args.recording), profile.name))
    return 0


def format_report(c: Characterization, recording: str, desk: str) -> str:
    """The measurements as text, ending with the profile snippet."""
    lines = [
        f"{recording}: {c.samples} samples, {c.duration_s:.1f} s at {c.sample_rate_hz:.1f} Hz "
        f"(desk {desk})",
        f"quiet: {c.quiet_windows} windows of {c.window_s:.3g} s ({c.quiet_s:.1f} s)",
        "",
    ]
    if c.noise:
        lines.append('noise in the quiet windows (σ and 3σ, the paper\'s "amplitude"):')
        lines.append(f"  {'channel':<12} {'σ':>10} {'3σ':>10}")
        lines += [_noise_line(n) for n in (*c.total_noise, *c.noise)]
    else:
        lines.append(f"noise: {c.noise_reason}")
    lines.append("")
    if c.drift:
        lines.append("drift (slope of the quiet windows' means, per minute ± standard error):")
        lines += [_drift_line(d) for d in (*c.total_drift, *c.drift)]
    else:
        lines.append(f"drift: {c.drift_reason}")
    lines.append("")
    if c.modes:
        lines.append(f"natural frequencies (free decay after {c.segments} excitation(s)):")
        for m in c.modes:
            lines.append(
                f"  {m.frequency_hz:8.2f} Hz   power {m.relative_power:6.3f} of the strongest, "
                f"{m.peak_over_floor:.0f}× the floor"
            )
        assert c.lowest_mode_hz is not None
        lines.append(
            f"suggested low-pass cut-off: {c.suggested_cutoff_hz:g} Hz "
            f"({CUTOFF_RATIO:.3f} × the lowest mode {c.lowest_mode_hz:.2f} Hz, the paper's "
            "4.77 Hz for 5.9 Hz)"
        )
    else:
        lines.append(f"natural frequencies: {c.modes_reason}")
    if c.inertia is not None:
        fit = c.inertia
        if fit.reason:
            lines.append(f"moments of inertia: {fit.reason}")
        else:
            lines.append(
                f"moments of inertia (from {fit.presses} press(es) and the accelerometers):"
            )
            for axis, moment, rho in zip("xyz", fit.moments, fit.correlation, strict=True):
                got = f"{moment:.4g} kg·m²" if moment is not None else "not moved enough to fit"
                lines.append(f"  about {axis}: {got} (correlation {rho:.3f})")
    for note in c.notes:
        lines.append(f"note: {note}")
    snippet = c.snippet()
    lines.append("")
    if snippet is None:
        lines.append("nothing measured: no profile snippet")
    else:
        lines.append("paste into the desk profile:")
        lines += [f"  {line}" for line in snippet.splitlines()]
    return "\n".join(lines)


def _noise_line(n: ChannelNoise) -> str:
    return f"  {n.channel:<12} {n.sigma:10.4g} {n.amplitude:10.4g} {n.unit}"


def _drift_line(d: ChannelDrift) -> str:
    return f"  {d.channel:<12} {d.rate_per_min:+10.4g} ± {d.stderr_per_min:.2g} {d.unit}/min"
