"""The known weight's rests in a recording of the set-up: one :class:`WeightSpot` per marked
spot, its mean readings less the empty desk's on either side of it.

The recording is cut where the readings change (the weight put down or lifted changes them by
W in a fraction of a second, a zero drifts by far less) into still stretches; a still stretch
reading at least half the weight more than the empty one before it is a rest. The fit on the
spots is :mod:`hapticdesk.analysis.known_weight`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hapticdesk.analysis.known_weight import (
    WeightSpot,
    check_mass,
    load_cell_channels,
    nominal_terms,
)
from hapticdesk.errors import ConfigError
from hapticdesk.files.profile import STANDARD_GRAVITY, DeskProfile

#: a spot's rest: the part of its bump that the first and last share of are trimmed from
TRIM_SHARE = 0.2
#: the empty desk read on either side of a rest over this long
BASELINE_S = 1.5
#: still stretches: readings smoothed over SMOOTH_S changing slower than this share of the
#: weight a second (putting it down changes them by all of it in well under a second), this
#: far from any change, at least MIN_STILL_S long
STILL_SHARE_PER_S = 0.2
SMOOTH_S = 0.1
BASELINE_MARGIN_S = 0.3
MIN_STILL_S = 0.4
#: still stretches in a row whose readings differ by less than this share of the weight are
#: one rest (cut by the desk ringing), more: the weight was slid to the next spot
SAME_REST_SHARE = 0.05
#: the weight as the readings show it: this quantile of the load over the recording (the
#: weight rests a third of a set-up's time) — a board's `scale` worked out roughly is off by
#: one factor for every cell (an HX711's gain 64 for 128: ×0.5), which the thresholds below
#: follow (they took the profile's newtons: readings ×0.45 found no rests, ×3 one) and
#: known_weight.fit_cells takes out; used where it is READ_RANGE of the weight's newtons
SEEN_QUANTILE = 90
READ_RANGE = (0.2, 5.0)


@dataclass(frozen=True)
class Rests:
    """The recording's still stretches ((start, stop) sample indices), each one's kind
    ("empty" or "rest"), and the weight's rests in order: each the stretches it spans."""

    stretches: list[tuple[int, int]]
    kinds: list[str]
    members: list[list[int]]


def spots_from_recording(
    profile: DeskProfile,
    t: np.ndarray,
    channels: np.ndarray,
    points: np.ndarray,
    mass_kg: float,
) -> list[WeightSpot]:
    """The weight's rests in a recording (t (n,), raw channels (n, C)) that starts with an
    empty desk, one rest per spot of ``points`` (K, 2) in order: each rest's mean readings
    less the empty desk's, read on either side of it and taken at the rest's time (a zero
    drifting linearly between them cancels)."""
    load_cell_channels(profile)
    check_mass(mass_kg)
    t = np.asarray(t, dtype=float)
    channels = profile.flat_channels(channels)
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    if len(t) < 10 or len(t) != len(channels):
        raise ConfigError(None, "the recording is too short for a set-up with a weight")
    weight = mass_kg * STANDARD_GRAVITY
    alpha = np.abs(nominal_terms(profile)[0])  # sign-blind: a cell read upside down counts
    rate = 1.0 / float(np.median(np.diff(t)))
    weight = _weight_as_read(channels, alpha, rate, weight)
    stretches = _still_stretches(channels * alpha, rate, weight)
    if not stretches:
        raise ConfigError(None, "the desk was never still: nothing to read the weight from")
    rests = _find_rests(channels, stretches, alpha, weight)
    if len(rests.members) != len(points):
        raise ConfigError(
            None,
            f"expected the {mass_kg:g} kg weight on {len(points)} spots one after another, "
            f"found it {len(rests.members)} times: start with the desk empty, put the weight on "
            "each marked spot in turn and lift it off between them",
        )
    width = max(1, int(round(BASELINE_S * rate)))
    return [
        WeightSpot(
            (float(points[k, 0]), float(points[k, 1])),
            _rest_readings(t, channels, rests, k, width),
        )
        for k in range(len(rests.members))
    ]


def _find_rests(
    channels: np.ndarray, stretches: list[tuple[int, int]], alpha: np.ndarray, weight: float
) -> Rests:
    """Which still stretches the weight rested in, and each rest's stretches (a knock or the
    desk ringing can cut one in two: still stretches reading the same load in a row are one
    rest), first to last. ``alpha`` (C,): each channel's newtons per unit, sign-blind."""
    rests: list[list[int]] = []
    kinds: list[str] = []
    for i, (a, b) in enumerate(stretches):
        level = channels[a:b].mean(axis=0)
        if i == 0:
            kinds.append("empty")
            continue
        ref = _nearest_empty(channels, stretches, kinds)
        loaded = float(np.abs((level - ref) * alpha).sum()) >= 0.5 * weight
        kinds.append("rest" if loaded else "empty")
        if not loaded:
            continue
        if kinds[i - 1] == "rest":
            pa, pb = stretches[i - 1]
            before = channels[pa:pb].mean(axis=0)
            if float(np.abs((level - before) * alpha).sum()) < SAME_REST_SHARE * weight:
                rests[-1].append(i)
                continue
        rests.append([i])
    return Rests(stretches, kinds, rests)


def _rest_readings(
    t: np.ndarray, channels: np.ndarray, rests: Rests, k: int, width: int
) -> np.ndarray:
    """Rest ``k``'s mean readings (its stretches trimmed of their edges) less the empty
    desk's over ``width`` samples on either side, interpolated to the rest's time."""
    stretches, kinds, members = rests.stretches, rests.kinds, rests.members[k]
    parts = []
    for i in members:
        a, b = stretches[i]
        trim = int((b - a) * TRIM_SHARE)
        parts.append(np.arange(a + trim, max(b - trim, a + trim + 1)))
    held = np.concatenate(parts)
    rest = channels[held].mean(axis=0)
    first, last = members[0], members[-1]
    sides = []
    if kinds[first - 1] == "empty":
        pa, pb = stretches[first - 1]
        sides.append((t[max(pa, pb - width) : pb].mean(), channels[max(pa, pb - width) : pb]))
    if last + 1 < len(stretches) and kinds[last + 1] == "empty":
        na, nb = stretches[last + 1]
        sides.append((t[na : min(nb, na + width)].mean(), channels[na : min(nb, na + width)]))
    if not sides:
        raise ConfigError(
            None,
            f"spot {k + 1}: the desk was not still and empty around the weight's rest at "
            f"t = {t[held[0]]:.2f} s: lift the weight off for a second or two between spots",
        )
    times = np.array([when for when, _ in sides])
    means = np.array([values.mean(axis=0) for _, values in sides])
    if len(sides) == 2 and times[1] > times[0]:
        share = (t[held].mean() - times[0]) / (times[1] - times[0])
        baseline = means[0] + share * (means[1] - means[0])
    else:
        baseline = means.mean(axis=0)
    return rest - baseline


def _weight_as_read(channels: np.ndarray, alpha: np.ndarray, rate: float, weight: float) -> float:
    """The weight's newtons as the readings show it (:data:`SEEN_QUANTILE`): the load against
    the recording's first half second (the desk empty); ``weight`` where that is not within
    :data:`READ_RANGE` of it."""
    empty = channels[: max(1, int(round(0.5 * rate)))].mean(axis=0)
    seen = float(np.percentile(np.abs((channels - empty) * alpha).sum(axis=1), SEEN_QUANTILE))
    low, high = READ_RANGE
    return seen if low * weight < seen < high * weight else weight


def _still_stretches(forces: np.ndarray, rate: float, weight: float) -> list[tuple[int, int]]:
    """(start, stop) of the stretches where the channels (as newtons) change slower than
    :data:`STILL_SHARE_PER_S` of the weight a second, at least :data:`MIN_STILL_S` long and
    :data:`BASELINE_MARGIN_S` clear of any change."""
    width = max(1, int(round(SMOOTH_S * rate)))
    kernel = np.ones(width) / width
    smooth = np.column_stack(
        [np.convolve(forces[:, j], kernel, mode="same") for j in range(forces.shape[1])]
    )
    # the change over one smoothing width (N/s, sign-blind): its noise does not grow with the
    # rate, as a sample-to-sample difference's would (1 kHz cells read "never still")
    step = np.zeros_like(smooth)
    step[width:] = smooth[width:] - smooth[:-width]
    step[:width] = step[width] if len(step) > width else 0.0
    change = np.abs(step).sum(axis=1) * rate / width
    moving = change > STILL_SHARE_PER_S * weight
    margin = max(1, int(round(BASELINE_MARGIN_S * rate)))
    near = np.convolve(moving.astype(float), np.ones(2 * margin + 1), mode="same") > 0
    # (the smoothing's own edges are not a change)
    near[:width] = near[width] if len(near) > width else near[:width]
    near[-width:] = near[-width - 1] if len(near) > width else near[-width:]
    still = np.concatenate([[False], ~near, [False]])
    edges = np.flatnonzero(np.diff(still.astype(np.int8)))
    shortest = max(1, int(round(MIN_STILL_S * rate)))
    return [
        (int(a), int(b)) for a, b in zip(edges[::2], edges[1::2], strict=True) if b - a >= shortest
    ]


def _nearest_empty(
    channels: np.ndarray, stretches: list[tuple[int, int]], kinds: list[str]
) -> np.ndarray:
    """The readings of the last empty stretch so far (its end: the nearest in time)."""
    for (a, b), kind in zip(reversed(stretches[: len(kinds)]), reversed(kinds), strict=True):
        if kind == "empty":
            return channels[max(a, b - 10) : b].mean(axis=0)
    raise AssertionError("the first stretch is empty by definition")
