"""Set-up with a known weight: each load cell's gain and position from a weight put on a few
marked spots, checked on a spot the fit did not use, written into the profile.

A cheap load cell's sensitivity is known to a few per cent (rated output 1.0 ± 0.1 mV/V is
common) and where it sits under the top to a centimetre or two; both move a located touch by
centimetres. A known weight W (a 1 kg bag of sugar, a 2 kg book) resting still on a spot
(x_s, y_s) of a horizontal top gives, with the tared readings r_s (one per cell), the paper's
equilibrium (eqs. 1–4) with only vertical forces:

    Σ_j α_j r_sj = W,      Σ_j β_j r_sj = W x_s,      Σ_j γ_j r_sj = W y_s

where α_j is cell j's newtons per unit of its reading (its gain) and β_j = α_j x_j,
γ_j = α_j y_j carry its position: three systems linear in the unknowns, one equation each per
spot. On a rigid top the cells' share of a vertical load depends on three numbers only (the
load and its two moments), so with four or more cells no number of spots pins every unknown:
what the spots leave open changes no load's located point either. The fit is the most
probable correction given the spots and a prior at the profile's nominal values (gains within
``gain_sd``, positions within ``position_sd_m``; least squares weighted by both: a MAP
estimate), so with three to five spots it moves the profile only as far as the weight shows.

Each spot's readings are the means over the weight's still rest, less the empty desk's on
either side of it (:func:`spots_from_recording`), so a zero that drifts between spots does not
count. :func:`calibrate` fits on all spots but the check spot, and places the weight at the
check spot with the fitted cells: the distance to the mark is the set-up's own error. The
result becomes a profile (:func:`calibrated_profile`) and a YAML file the reader accepts
(:func:`write_calibrated_profile`; each cell becomes ``channels: [fz]`` with a
``calibration`` column holding its gain, comments kept where ruamel.yaml is installed).
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from hapticdesk.errors import ConfigError
from hapticdesk.files.profile import STANDARD_GRAVITY, DeskProfile
from hapticdesk.files.profile_reader import profile_from_mapping
from hapticdesk.files.yamlfile import load_marked_yaml

#: prior spread of a cell's gain around the profile's (a cheap cell's rated output: ±10 %)
GAIN_SD = 0.1
#: prior spread of a cell's position around the profile's, metres (measured with a ruler)
POSITION_SD_M = 0.03
#: how far from its mark a person sets a weight down, metres (a bag of sugar on a cross)
PLACEMENT_SD_M = 0.003
#: a rest's mean reads the weight to this share (noise, creep, what putting it down left
#: ringing); the weight's own mass error only scales every gain alike, which moves no point
READING_SD = 0.002
#: a check spot placed further than this from its mark says the set-up should be redone
CHECK_TOLERANCE_M = 0.005
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
#: spots are suggested this far from the cells' centroid towards each cell
SUGGESTED_REACH = 0.6
#: the largest weight that makes sense on a desk top, and the smallest a cell resolves
MIN_MASS_KG, MAX_MASS_KG = 0.2, 100.0


@dataclass(frozen=True)
class WeightSpot:
    """The known weight resting on one marked spot: the spot (desk x, y, metres) and what
    each raw channel read there, less the empty desk (its mean over the rest)."""

    point: tuple[float, float]
    readings: np.ndarray  # (C,)


@dataclass(frozen=True)
class CellFit:
    """Each cell's fitted gain and position (the channels in the profile's order).

    ``newtons_per_unit`` (C,) is α (the cell's newtons per unit of its reading, sign
    included), ``positions`` (C, 2) desk (x, y); ``gains`` is α over the profile's (1: as
    it was). ``profile`` is the desk the fit started from.
    """

    profile: DeskProfile
    newtons_per_unit: np.ndarray
    positions: np.ndarray
    spots_used: int

    @property
    def gains(self) -> np.ndarray:
        return self.newtons_per_unit / nominal_terms(self.profile)[0]

    def nominal_positions(self) -> np.ndarray:
        """(C, 2) the cells' (x, y) in the profile the fit started from."""
        return np.array([s.position[:2] for s in self.profile.sensors], dtype=float)

    def locate(self, readings: np.ndarray) -> tuple[float, float, float]:
        """(x, y, load in newtons) of a vertical load that reads ``readings`` (C,) tared."""
        r = np.asarray(readings, dtype=float)
        load = float(r @ self.newtons_per_unit)
        if not abs(load) > 0:
            return math.nan, math.nan, load
        x = float(r @ (self.newtons_per_unit * self.positions[:, 0])) / load
        y = float(r @ (self.newtons_per_unit * self.positions[:, 1])) / load
        return x, y, load


@dataclass(frozen=True)
class SpotCheck:
    """Where a fit places the weight on a spot it did not use."""

    point: tuple[float, float]
    located: tuple[float, float]
    error_m: float  # distance from the mark
    mass_error: float  # the weight's share it reads too much (+) or too little (-)


@dataclass(frozen=True)
class Calibration:
    """:func:`calibrate`'s result: the fit, and its check on the spot it left out (None
    with fewer than four spots), and each spot left out in turn (``leave_one_out``)."""

    fit: CellFit
    check: SpotCheck | None
    leave_one_out: list[SpotCheck]

    @property
    def passed(self) -> bool:
        """The check spot was placed within :data:`CHECK_TOLERANCE_M` (True without one)."""
        return self.check is None or self.check.error_m <= CHECK_TOLERANCE_M

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: per cell its gain and position (and the profile's), the checks."""
        fit = self.fit
        cells = []
        nominal = fit.nominal_positions()
        for j, name in enumerate(fit.profile.channel_names()):
            cells.append(
                {
                    "channel": name,
                    "gain": round(float(fit.gains[j]), 5),
                    "position_m": [round(float(v), 5) for v in fit.positions[j]],
                    "profile_position_m": [round(float(v), 5) for v in nominal[j]],
                }
            )

        def check(c: SpotCheck) -> dict[str, Any]:
            return {
                "point_m": list(c.point),
                "located_m": [round(v, 5) for v in c.located],
                "error_m": round(c.error_m, 5),
                "mass_error": round(c.mass_error, 5),
            }

        return {
            "cells": cells,
            "spots_used": fit.spots_used,
            "check": None if self.check is None else check(self.check),
            "leave_one_out": [check(c) for c in self.leave_one_out],
            "passed": self.passed,
        }


def load_cell_channels(profile: DeskProfile) -> None:
    """Raise :class:`ConfigError` unless every sensor of ``profile`` is a load cell that
    measures the vertical force (one channel; its column of the wrench map has only F_z and
    the moments a vertical force at the cell makes), under a horizontal top."""
    what = f"desk {profile.name!r}"
    where = str(profile.path) if profile.path else None
    columns = profile.wrench_map()
    bad = [
        s.name
        for s in profile.sensors
        if len(s.channels) != 1 or abs(abs(float(s.rotation[2, 2])) - 1.0) > 1e-6
    ]
    if not bad:
        bad = [
            name
            for name, col in zip(profile.channel_names(), columns.T, strict=True)
            if np.abs(col[[0, 1, 5]]).max() > 1e-9 * max(np.abs(col).max(), 1e-300) or col[2] == 0
        ]
    if bad:
        raise ConfigError(
            where,
            f"set-up with a known weight fits load cells that measure the vertical force (one "
            f"channel each, upright or upside down); {what} has other sensors: {', '.join(bad)}",
        )
    if not profile.surfaces or not np.allclose(np.abs(profile.surfaces[0].normal), [0, 0, 1]):
        raise ConfigError(where, f"{what} needs a horizontal top (its first surface)")


def nominal_terms(profile: DeskProfile) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(α, β, γ) (C,) each in ``profile``: F_z = Σ α r, M_y = −Σ β r, M_x = Σ γ r."""
    a = profile.wrench_map()
    return a[2].copy(), -a[4], a[3].copy()


def fit_cells(
    profile: DeskProfile,
    spots: list[WeightSpot],
    mass_kg: float,
    *,
    gain_sd: float = GAIN_SD,
    position_sd_m: float = POSITION_SD_M,
    placement_sd_m: float = PLACEMENT_SD_M,
    reading_sd: float = READING_SD,
) -> CellFit:
    """Fit each cell's gain and position to ``spots`` (see the module docstring): the spreads
    weigh the spots against the profile (``gain_sd``, ``position_sd_m`` of the prior;
    ``placement_sd_m`` of where the weight sat, ``reading_sd`` of how much it read)."""
    load_cell_channels(profile)
    _check_mass(mass_kg)
    if not spots:
        raise ConfigError(None, "the fit needs the weight on at least one spot")
    weight = mass_kg * STANDARD_GRAVITY
    alpha0, beta0, gamma0 = nominal_terms(profile)
    pos0 = np.column_stack([beta0 / alpha0, gamma0 / alpha0])
    readings = np.array([s.readings for s in spots], dtype=float)  # (K, C)
    points = np.array([s.point for s in spots], dtype=float)  # (K, 2)
    if readings.shape[1] != len(alpha0) or not np.isfinite(readings).all():
        raise ConfigError(
            None,
            f"each spot needs {len(alpha0)} finite readings (the desk's channels "
            f"{', '.join(profile.channel_names())})",
        )
    # prior spread of α, β, γ around the profile's (β = α x: its gain's and position's)
    sd_alpha = gain_sd * np.abs(alpha0)
    sd_beta = np.hypot(sd_alpha * pos0[:, 0], np.abs(alpha0) * position_sd_m)
    sd_gamma = np.hypot(sd_alpha * pos0[:, 1], np.abs(alpha0) * position_sd_m)
    alpha = _map_solve(readings, np.full(len(spots), weight), weight * reading_sd, alpha0, sd_alpha)
    placement = weight * placement_sd_m
    beta = _map_solve(readings, weight * points[:, 0], placement, beta0, sd_beta)
    gamma = _map_solve(readings, weight * points[:, 1], placement, gamma0, sd_gamma)
    positions = np.column_stack([beta / alpha, gamma / alpha])
    return CellFit(profile, alpha, positions, len(spots))


def _map_solve(
    rows: np.ndarray, rhs: np.ndarray, rhs_sd: float, prior: np.ndarray, prior_sd: np.ndarray
) -> np.ndarray:
    """argmin ‖(rows θ − rhs)/rhs_sd‖² + ‖(θ − prior)/prior_sd‖²."""
    scaled = rows * prior_sd[None, :] / rhs_sd  # in units of the prior's spread
    residual = (rhs - rows @ prior) / rhs_sd
    k = scaled.shape[1]
    step = np.linalg.solve(scaled.T @ scaled + np.eye(k), scaled.T @ residual)
    return prior + step * prior_sd


def check_spot(fit: CellFit, spot: WeightSpot, mass_kg: float) -> SpotCheck:
    """Where ``fit`` places the weight resting on ``spot``."""
    x, y, load = fit.locate(spot.readings)
    weight = mass_kg * STANDARD_GRAVITY
    error = math.hypot(x - spot.point[0], y - spot.point[1])
    return SpotCheck(
        (float(spot.point[0]), float(spot.point[1])),
        (x, y),
        error if math.isfinite(error) else math.inf,
        load / weight - 1.0,
    )


def calibrate(
    profile: DeskProfile,
    spots: list[WeightSpot],
    mass_kg: float,
    *,
    check_index: int | None = -1,
    **priors: float,
) -> Calibration:
    """Fit on every spot but ``check_index`` (default the last; None: fit on all, no
    check) and place the weight on that one; each spot is also left out in turn
    (``leave_one_out``, with three spots or more). With fewer than four spots the fit uses
    them all and there is no check. ``priors``: :func:`fit_cells`'s spreads."""
    if len(spots) < 4:
        check_index = None
    if check_index is not None:
        check_index = range(len(spots))[check_index]  # an IndexError names a wrong one
        used = [s for i, s in enumerate(spots) if i != check_index]
        fit = fit_cells(profile, used, mass_kg, **priors)
        check = check_spot(fit, spots[check_index], mass_kg)
    else:
        fit, check = fit_cells(profile, spots, mass_kg, **priors), None
    loo = []
    if len(spots) >= 3:
        for i, spot in enumerate(spots):
            others = [s for j, s in enumerate(spots) if j != i]
            loo.append(check_spot(fit_cells(profile, others, mass_kg, **priors), spot, mass_kg))
    return Calibration(fit, check, loo)


def suggested_spots(profile: DeskProfile, count: int = 4) -> np.ndarray:
    """(count, 2) spots to mark for the weight, 3 to 5: towards each cell from the cells'
    centroid (:data:`SUGGESTED_REACH` of the way), where the spots tell the cells apart best,
    the centre as the fifth; kept inside the top's outline."""
    if not 3 <= count <= 5:
        raise ValueError(f"mark 3 to 5 spots, found {count}")
    cells = np.array([s.position[:2] for s in profile.sensors], dtype=float)
    centre = cells.mean(axis=0)
    order = np.argsort(np.arctan2(*(cells - centre).T[::-1]))  # around the centre
    ring = centre + SUGGESTED_REACH * (cells[order] - centre)
    if count <= len(ring):
        pick = np.round(np.linspace(0, len(ring), count, endpoint=False)).astype(int)
        out = ring[pick]
    else:
        out = np.vstack([ring, centre[None, :]])[:count]
    return out


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
    drifting linearly between them cancels).

    The recording is cut where the readings change (the weight put down or lifted: it
    changes the readings by W in a fraction of a second, a zero drifts by far less), into
    still stretches; a still stretch reading at least half the weight more than the empty
    one before it is a rest."""
    load_cell_channels(profile)
    _check_mass(mass_kg)
    t = np.asarray(t, dtype=float)
    channels = profile.flat_channels(channels)
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    if len(t) < 10 or len(t) != len(channels):
        raise ConfigError(None, "the recording is too short for a set-up with a weight")
    weight = mass_kg * STANDARD_GRAVITY
    alpha = np.abs(nominal_terms(profile)[0])  # sign-blind: a cell read upside down counts
    rate = 1.0 / float(np.median(np.diff(t)))
    stretches = _still_stretches(channels * alpha, rate, weight)
    if not stretches:
        raise ConfigError(None, "the desk was never still: nothing to read the weight from")
    # each rest: the stretches it spans (a knock or the desk ringing can cut one in two:
    # still stretches reading the same load in a row are one rest), first to last
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
    if len(rests) != len(points):
        raise ConfigError(
            None,
            f"expected the {mass_kg:g} kg weight on {len(points)} spots one after another, "
            f"found it {len(rests)} times: start with the desk empty, put the weight on each "
            "marked spot in turn and lift it off between them",
        )
    width = max(1, int(round(BASELINE_S * rate)))
    out = []
    for k, members in enumerate(rests):
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
        out.append(WeightSpot((float(points[k, 0]), float(points[k, 1])), rest - baseline))
    return out


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


def _check_mass(mass_kg: float) -> None:
    if not (MIN_MASS_KG <= mass_kg <= MAX_MASS_KG):
        raise ConfigError(
            "--mass-kg",
            f"the known weight must be {MIN_MASS_KG:g} to {MAX_MASS_KG:g} kg, found {mass_kg:g}",
        )


# --- the calibrated profile --------------------------------------------------------------------


def cell_calibrations(fit: CellFit) -> list[tuple[float, float, float, float]]:
    """Per sensor (in order): its new (x, y, z) and the ``calibration`` number of its fz
    channel (newtons of its own axis per unit of its reading) that give the fitted α."""
    out = []
    for j, sensor in enumerate(fit.profile.sensors):
        axis = sensor.sign * float(sensor.rotation[2, 2])  # ±1: upright or upside down
        x, y = (float(v) for v in fit.positions[j])
        out.append((x, y, float(sensor.position[2]), float(fit.newtons_per_unit[j]) / axis))
    return out


def calibrated_profile(fit: CellFit) -> DeskProfile:
    """The profile with the fitted cells (each a calibrated one-channel sensor ``fz``)."""
    sensors = []
    for sensor, (x, y, z, number) in zip(fit.profile.sensors, cell_calibrations(fit), strict=True):
        column = np.zeros((6, 1))
        column[2, 0] = number
        limits = sensor.channel_limits()
        sensors.append(
            replace(
                sensor,
                position=np.array([x, y, z]),
                channels=("fz",),
                calibration=column,
                channel_range=limits if np.isfinite(limits).all() else None,
                force_range=None,
                moment_range=None,
            )
        )
    return replace(fit.profile, sensors=tuple(sensors))


def calibrated_yaml(source_text: str, fit: CellFit, header: str = "") -> str:
    """``source_text`` (the profile's YAML) with each cell calibrated: ``position``, and
    ``channels: [fz]`` with its ``calibration`` in place of ``kind``/``axes``; a ``range``
    becomes the channel's. Comments are kept with ruamel.yaml, else the file is rewritten
    by PyYAML (a note at the top says so). ``header``: comment lines put first."""
    cells = {s.name: c for s, c in zip(fit.profile.sensors, cell_calibrations(fit), strict=True)}
    try:
        from ruamel.yaml import YAML
        from ruamel.yaml.comments import CommentedMap, CommentedSeq
    except ImportError:
        return _plain_yaml(source_text, cells, header)
    yaml = YAML()
    yaml.preserve_quotes = True
    yaml.width = 4096  # a sensor's flow mapping stays on its line
    yaml.indent(mapping=2, sequence=4, offset=2)  # the profiles' own "  - {...}"
    doc = yaml.load(source_text)

    def flow(values: list[Any]) -> CommentedSeq:
        seq = CommentedSeq(values)
        seq.fa.set_flow_style()
        return seq

    for item in doc["sensors"]:
        x, y, z, number = cells[str(item["name"])]
        _calibrate_item(item, x, y, z, number, flow, CommentedMap)
    out = io.StringIO()
    yaml.dump(doc, out)
    return _with_header(out.getvalue(), header)


def _calibrate_item(
    item: Any, x: float, y: float, z: float, number: float, seq: Any, mapping: Any
) -> None:
    """One sensor entry of the YAML made the calibrated cell (in place)."""
    limit = None
    if "range" in item and "force_n" in item["range"]:
        rated = item["range"]["force_n"]
        limit = float(rated[2] if isinstance(rated, list) else rated)
    for key in ("kind", "axes", "channels", "calibration", "range"):
        if key in item:
            del item[key]
    item["position"] = seq([_round(x, 6), _round(y, 6), _round(z, 6)])  # to a micrometre
    item["channels"] = seq(["fz"])
    item["calibration"] = seq([seq([v]) for v in (0, 0, _round(number, 6), 0, 0, 0)])
    if limit is not None:
        rng = mapping()
        rng["channels"] = seq([_round(limit, 6)])
        if hasattr(rng, "fa"):
            rng.fa.set_flow_style()
        item["range"] = rng


def _round(value: float, digits: int = 5) -> float:
    return float(round(value, digits))


def _plain_yaml(
    source_text: str, cells: dict[str, tuple[float, float, float, float]], header: str
) -> str:
    import yaml

    doc = yaml.safe_load(source_text)
    for item in doc["sensors"]:
        x, y, z, number = cells[str(item["name"])]
        _calibrate_item(item, x, y, z, number, list, dict)
    note = "# (rewritten without its comments: pip install ruamel.yaml to keep them)\n"
    return _with_header(note + yaml.safe_dump(doc, sort_keys=False), header)


def _with_header(text: str, header: str) -> str:
    if not header:
        return text
    lines = [f"# {line}".rstrip() for line in header.splitlines()]
    return "\n".join(lines) + "\n" + text


def write_calibrated_profile(
    source: Path, fit: CellFit, output: Path, header: str = ""
) -> DeskProfile:
    """Write :func:`calibrated_yaml` of the profile file ``source`` to ``output``, after
    reading it back as a profile (the reader must accept what is written); returns it."""
    text = calibrated_yaml(Path(source).read_text(encoding="utf-8"), fit, header)
    checked = profile_from_mapping(load_marked_yaml(Path(output), text), Path(output))
    Path(output).write_text(text, encoding="utf-8")
    return checked
