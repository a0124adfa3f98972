"""An independent reference implementation of the paper's method, for speed comparisons.

Kitamura, Tsuji, Sakaino 2017 (docs: /work/shared/paper/METHOD.md), written the plain way a
researcher would: whole arrays, numpy and scipy.signal, no per-sample loop, no state carried
between calls, nothing the paper does not describe. It shares no code with
``hapticdesk.estimator``; only the profile's ``wrench_map()`` (the rotation and sign of each
sensor, input plumbing) is taken from ``hapticdesk.files.profile``.

1. F_o, M_o about P_o: every sample's stacked sensor channels through one linear map
   (paper eqs. 1–4).
2. Tare: the mean of the first ``tare_s`` seconds is the zero (gravity of the desk).
3. The conventional low-pass: 2nd-order Butterworth at ``force_lowpass_hz`` (``sosfilt``,
   started in steady state on the first sample).
4. The pseudo-differentiated wrench: the difference over ``diff_window_s`` divided by the
   window, then the 2nd-order low-pass at ``diff_lowpass_hz`` (paper eqs. 8, 12).
5. Each wrench's line of action meets the top plane z = h at
   x = (h·F_x − M_y) / F_z, y = (h·F_y + M_x) / F_z (paper eq. 5); a point outside the top's
   outline (its bounding rectangle) is not located.
6. Methods: ``force`` (P_er), ``diff`` (P_ed), ``switched`` (paper Fig. 3: the motion is the
   sign of the differentiated force magnitude; touching uses P_ed while |F_o| ≤ F_tth,
   releasing while |F_o| ≤ F_rth, else P_er); a point only while |F_o| ≥ contact_force_n and
   after the tare.

Used by ``scripts/bench_estimator.py`` (speed side by side) and
``tests/bench/test_bench_reference.py`` (it locates the same points as the estimator).

    python scripts/reference_paper.py RECORDING --desk kitamura2017 [--method switched]
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass

import numpy as np
from scipy import signal

from hapticdesk.files.profile import DeskProfile

REFERENCE_METHODS = ("force", "diff", "switched")
SOURCE_NONE, SOURCE_FORCE, SOURCE_DIFF = 0, 1, 2


@dataclass(frozen=True)
class ReferenceContacts:
    """Per input sample: where the method located the contact, if it did."""

    t: np.ndarray  # (k,) seconds
    located: np.ndarray  # (k,) bool
    x: np.ndarray  # (k,) metres, desk frame; 0 where not located
    y: np.ndarray
    force_n: np.ndarray  # (k,) |F_o| after the tare and the low-pass
    source: np.ndarray  # (k,) int8: SOURCE_FORCE or SOURCE_DIFF where located, else 0


def _top_plane(profile: DeskProfile) -> tuple[float, np.ndarray, np.ndarray]:
    """Height of the top board above P_o and its outline's bounding box (lo, hi) in (x, y)."""
    top = profile.surfaces[0]
    if not np.allclose(top.normal, [0.0, 0.0, 1.0]):
        raise ValueError(f"the reference handles a horizontal top only, not {top.name!r}")
    return float(top.origin[2]), top.polygon.min(axis=0), top.polygon.max(axis=0)


def _on_top(
    wrench: np.ndarray, h: float, lo: np.ndarray, hi: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Paper eq. (5): the line of action of (F, M) rows meets z = h at (x, y); and inside."""
    fx, fy, fz, mx, my = wrench[:, 0], wrench[:, 1], wrench[:, 2], wrench[:, 3], wrench[:, 4]
    safe = np.abs(fz) > 1e-12
    fz_safe = np.where(safe, fz, 1.0)
    x = (h * fx - my) / fz_safe
    y = (h * fy + mx) / fz_safe
    inside = safe & (x >= lo[0]) & (x <= hi[0]) & (y >= lo[1]) & (y <= hi[1])
    return x, y, inside


@dataclass(frozen=True)
class ReferenceFiltered:
    """Steps 1–4 for a whole recording ((k, 6) arrays of [F_o; M_o])."""

    wrench_f: np.ndarray  # low-passed, tared
    wrench_d: np.ndarray  # pseudo-differentiated, low-passed
    n_tare: int  # samples of the tare


def reference_filtered(profile: DeskProfile, wrench: np.ndarray) -> ReferenceFiltered:
    """Steps 1–4: the map, the tare, the low-pass and the differentiated force for a whole
    recording ``wrench`` (k, S, 6). What every method of the paper must compute before it
    locates anything: ``scripts/bench_estimator.py`` times it apart as the reference's own
    floor."""
    s = profile.estimation
    fs = profile.sample_rate_hz
    k = len(wrench)

    # paper eqs. (1)–(4): [F_o; M_o] = A · w for every sample at once
    w = wrench.reshape(k, -1) @ profile.wrench_map().T  # (k, 6)

    # the conventional second-order low-pass, in steady state on the first sample
    sos_f = signal.butter(2, s.force_lowpass_hz, fs=fs, output="sos")
    zi = signal.sosfilt_zi(sos_f)[:, :, None] * w[0]
    low, _ = signal.sosfilt(sos_f, w, axis=0, zi=zi)
    n_tare = max(1, round(s.tare_s * fs))
    wrench_f = low - w[:n_tare].mean(axis=0)  # tared (the zero: the first tare_s)

    # paper eq. (8): f'(t) = (f(t) − f(t − n·T_s)) / (n·T_s), then the low-pass (eq. 12)
    n = max(1, round(s.diff_window_s * fs))
    past = np.concatenate([np.repeat(w[:1], n, axis=0), w[:-n]])
    sos_d = signal.butter(2, s.diff_lowpass_hz, fs=fs, output="sos")
    wrench_d = signal.sosfilt(sos_d, (w - past) * (fs / n), axis=0)
    return ReferenceFiltered(wrench_f, wrench_d, n_tare)


def reference_contacts(
    profile: DeskProfile, t: np.ndarray, wrench: np.ndarray, method: str = "switched"
) -> ReferenceContacts:
    """Contacts by the paper's method for a whole recording: ``t`` (k,), ``wrench`` (k, S, 6)."""
    if method not in REFERENCE_METHODS:
        raise ValueError(f"method must be one of {', '.join(REFERENCE_METHODS)}, not {method!r}")
    s = profile.estimation
    k = len(t)
    filtered = reference_filtered(profile, wrench)
    wrench_f, wrench_d, n_tare = filtered.wrench_f, filtered.wrench_d, filtered.n_tare

    force = np.linalg.norm(wrench_f[:, :3], axis=1)
    contact = (force >= s.contact_force_n) & (np.arange(k) >= n_tare)  # Fig. 3, step 4

    h, lo, hi = _top_plane(profile)
    x_f, y_f, in_f = _on_top(wrench_f, h, lo, hi)  # P_er
    x_d, y_d, in_d = _on_top(wrench_d, h, lo, hi)  # P_ed
    if method == "force":
        use_d = np.zeros(k, bool)
    elif method == "diff":
        use_d = np.ones(k, bool)
    else:  # Fig. 3, steps 2–3: touching (|F| grows) or releasing, each with its threshold
        rate = np.einsum("ki,ki->k", wrench_f[:, :3], wrench_d[:, :3])
        threshold = np.where(rate >= 0, s.touch_threshold_n, s.release_threshold_n)
        use_d = force <= threshold
    located = contact & np.where(use_d, in_d, in_f)
    return ReferenceContacts(
        t=t,
        located=located,
        x=np.where(located, np.where(use_d, x_d, x_f), 0.0),
        y=np.where(located, np.where(use_d, y_d, y_f), 0.0),
        force_n=force,
        source=np.where(located, np.where(use_d, SOURCE_DIFF, SOURCE_FORCE), SOURCE_NONE).astype(
            np.int8
        ),
    )


def main() -> None:
    from hapticdesk.files.profile_reader import load_profile
    from hapticdesk.recordings import read_any_recording

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("recording")
    parser.add_argument("--desk", default="kitamura2017")
    parser.add_argument("--method", choices=REFERENCE_METHODS, default="switched")
    args = parser.parse_args()
    desk = load_profile(args.desk)
    rec = read_any_recording(args.recording, desk)
    out = reference_contacts(desk, rec.t, rec.wrench, args.method)
    print("t,x,y,force_n,source")
    for i in np.flatnonzero(out.located):
        print(f"{out.t[i]:.5f},{out.x[i]:.5f},{out.y[i]:.5f},{out.force_n[i]:.3f},{out.source[i]}")


if __name__ == "__main__":
    main()
