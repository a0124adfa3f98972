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
either side of it (:func:`hapticdesk.analysis.weight_rests.spots_from_recording`), so a zero
that drifts between spots does not count. :func:`calibrate` fits on all spots but the check
spot, and places the weight at the check spot with the fitted cells: the distance to the mark
is the set-up's own error. The result becomes a profile and a YAML file the reader accepts
(:mod:`hapticdesk.analysis.calibrated_profile`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from hapticdesk.errors import ConfigError
from hapticdesk.files.profile import STANDARD_GRAVITY, DeskProfile

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
    check_mass(mass_kg)
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
    # a scale every cell shares (a board's `scale` worked out roughly: an HX711's gain, the
    # cells' rating) is no cell's own ±10 %: where the weight as the profile reads it on the
    # spots is off by more than a cell's own spread, that share is taken out first (×0.6
    # readings left the cells' places 12 mm off; within it, the prior stays the profile's:
    # taken out there too, the leave-one-out of scripts/loadcell_accuracy.py grew 0.1-0.3 mm)
    read_as = float(np.mean(readings @ alpha0))
    common = weight / read_as if read_as > 0 and np.isfinite(read_as) else 1.0
    if abs(common - 1.0) > gain_sd:
        alpha0, beta0, gamma0 = alpha0 * common, beta0 * common, gamma0 * common
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


def check_mass(mass_kg: float) -> None:
    """Raise :class:`ConfigError` unless the known weight is a mass a desk and its cells can
    take (:data:`MIN_MASS_KG` to :data:`MAX_MASS_KG`)."""
    if not (MIN_MASS_KG <= mass_kg <= MAX_MASS_KG):
        raise ConfigError(
            "--mass-kg",
            f"the known weight must be {MIN_MASS_KG:g} to {MAX_MASS_KG:g} kg, found {mass_kg:g}",
        )
