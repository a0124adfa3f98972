"""The page's set-up with a known weight: a load-cell desk's gains and cell positions fitted to
a weight put on a few marked spots, checked on a spot the fit did not use, and written as a
calibrated profile next to the layout.

The page asks for the weight's mass and how many spots (3 to 5), draws the spots
(:func:`hapticdesk.analysis.known_weight.suggested_spots`), and records the desk's raw
readings while the person puts the weight on each spot in turn and lifts it off between them
(:class:`~hapticdesk.plugins.ui.setup_api.BlockRecorder`). Finish reads the rests from the
recording and fits as ``hapticdesk calibrate`` does, through the same functions
(:func:`~hapticdesk.analysis.weight_rests.spots_from_recording`,
:func:`~hapticdesk.analysis.known_weight.calibrate`,
:func:`~hapticdesk.analysis.calibrated_profile.write_calibrated_profile`): no second fit here.

Routes (behind the guard like the rest of the API: :mod:`.guard`)::

    GET  /api/setup/weight/spots?count=N       the N spots to mark, metres
    POST /api/setup/weight/start  {mass_kg, count}
    POST /api/setup/weight/finish              the fit, its check, the profile written
"""

from __future__ import annotations

import asyncio
import math
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

from starlette.requests import Request
from starlette.responses import JSONResponse, Response
from starlette.routing import BaseRoute, Route

from hapticdesk.errors import ConfigError
from hapticdesk.plugins.ui.answers import error_dict, json_object, message_error, refusal
from hapticdesk.plugins.ui.setup_api import BlockRecorder
from hapticdesk.plugins.ui.shown_desk import ShownDesk

MIN_SPOTS, MAX_SPOTS = 3, 5
#: the written profile's file name, next to the layout: ``<desk name>-calibrated.yaml``
OUTPUT_SUFFIX = "-calibrated.yaml"


def _shown(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:40] + "…"


def read_mass(value: Any) -> float:
    """The known weight's mass from the page (kg): a number above 0 within what a desk top
    carries and a cell resolves; ConfigError saying what was expected otherwise."""
    from hapticdesk.analysis.known_weight import MAX_MASS_KG, MIN_MASS_KG

    expected = f"`mass_kg`: the known weight's mass in kg, a number from {MIN_MASS_KG:g} to "
    expected += f"{MAX_MASS_KG:g} (a 1 kg bag of sugar: 1)"
    if value is None or value == "":
        raise ConfigError(None, f"{expected}; none was given")
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ConfigError(None, f"{expected}, found {_shown(value)}")
    if not math.isfinite(value) or value <= 0:
        raise ConfigError(None, f"{expected}: a mass above 0, found {value:g}")
    if not MIN_MASS_KG <= value <= MAX_MASS_KG:
        raise ConfigError(None, f"{expected}, found {value:g}")
    return float(value)


def read_count(value: Any) -> int:
    """How many spots (3 to 5) from the page; ConfigError otherwise."""
    if isinstance(value, str) and value.strip().isdigit():
        value = int(value.strip())
    if isinstance(value, bool) or not isinstance(value, int) or not MIN_SPOTS <= value <= MAX_SPOTS:
        raise ConfigError(
            None,
            f"`count`: mark {MIN_SPOTS} to {MAX_SPOTS} spots for the weight (4 or 5 leave one "
            f"to check the fit on), found {_shown(value)}",
        )
    return value


def spots_for(profile: Any, count: int) -> list[list[float]]:
    """The ``count`` spots to mark on ``profile``'s top (metres), after checking that its
    sensors are load cells (ConfigError naming the others)."""
    from hapticdesk.analysis.known_weight import load_cell_channels, suggested_spots

    load_cell_channels(profile)
    return [[round(float(x), 5), round(float(y), 5)] for x, y in suggested_spots(profile, count)]


def output_path(layout_path: Path, desk_name: str) -> Path:
    """Where the page writes the calibrated profile: beside the layout, named after the desk
    (a set-up done again replaces it)."""
    slug = re.sub(r"[^A-Za-z0-9_.-]+", "-", desk_name).strip(".-") or "desk"
    return Path(layout_path).parent / f"{slug}{OUTPUT_SUFFIX}"


class WeightSession(BlockRecorder):
    """One set-up with a known weight: the desk's raw readings from Start, the mass and the
    spots in the order the weight goes on them."""

    def __init__(self, runtime: Any, mass_kg: float, points: list[list[float]]) -> None:
        super().__init__(runtime)
        self.profile = runtime.scene.profile
        self.mass_kg = mass_kg
        self.points = points

    def finish(self, output: Path | None) -> dict[str, Any]:
        """Stop recording, find the weight's rests, fit on every spot but the last (with 4
        or 5; with 3 on all of them), check the fit on the last, and write the calibrated
        profile to ``output`` (None: not written). JSON-ready; ConfigError for a set-up
        that cannot be read (a spot with no weight on it, the desk never still)."""
        import numpy as np

        from hapticdesk.analysis.calibrated_profile import write_calibrated_profile
        from hapticdesk.analysis.known_weight import (
            CHECK_TOLERANCE_M,
            CellFit,
            calibrate,
            check_spot,
            nominal_terms,
        )
        from hapticdesk.analysis.weight_rests import spots_from_recording
        from hapticdesk.commands.calibrate import profile_header
        from hapticdesk.commands.output_path import cannot_write

        t, raw = self.samples()
        profile = self.profile
        channels = profile.flat_channels(raw)
        points = np.asarray(self.points, dtype=float)
        spots = spots_from_recording(profile, t, channels, points, self.mass_kg)
        result = calibrate(profile, spots, self.mass_kg)  # (`hapticdesk calibrate`'s default)
        out = result.to_dict()
        out.update(
            ok=True,
            desk=profile.name,
            mass_kg=self.mass_kg,
            spots_m=self.points,
            captured_s=round(float(t[-1] - t[0]), 2),
            tolerance_m=CHECK_TOLERANCE_M,
            check_index=None if result.check is None else len(spots) - 1,
            check_before_m=None,
            profile_path=None,
            note="",
        )
        if result.check is not None:  # the same spot placed by the profile as it was
            alpha, beta, gamma = nominal_terms(profile)
            before = CellFit(profile, alpha, np.column_stack([beta / alpha, gamma / alpha]), 0)
            error = check_spot(before, spots[-1], self.mass_kg).error_m
            out["check_before_m"] = round(error, 5)
        if profile.path is None:
            out["note"] = "not written: the desk was not read from a profile file"
        elif output is None:
            out["note"] = "not written: start with --layout FILE to write it beside the layout"
        else:
            header = profile_header(result, self.mass_kg, len(spots), "the page's set-up")
            try:
                write_calibrated_profile(Path(profile.path), result.fit, output, header)
            except OSError as err:
                raise cannot_write(output, err) from None
            out["profile_path"] = str(output)
        return _finite(out)


def _finite(value: Any) -> Any:
    """``value`` with every NaN or infinity (a spot the fit cannot place) made None: JSON
    has no such numbers."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    return value


class WeightSetup:
    """The routes' state: the set-up in progress (one at a time), for the desk one page's
    server shows."""

    def __init__(self, shown: ShownDesk) -> None:
        self.shown = shown
        self.session: WeightSession | None = None

    def runtime_profile(self) -> Any:
        runtime = self.shown.runtime
        if runtime is None:
            raise ConfigError(
                None,
                "the set-up with a known weight needs a running desk (`hapticdesk ui` or "
                "`run --ui`)",
            )
        return runtime.scene.profile

    def spots(self, count: Any) -> dict[str, Any]:
        return {"ok": True, "spots_m": spots_for(self.runtime_profile(), read_count(count))}

    def start(self, payload: dict[str, Any]) -> dict[str, Any]:
        mass = read_mass(payload.get("mass_kg"))
        points = spots_for(self.runtime_profile(), read_count(payload.get("count", 4)))
        if self.session is not None:
            self.session.finish_quietly()
        self.session = WeightSession(self.shown.runtime, mass, points)
        return {"ok": True, "mass_kg": mass, "spots_m": points}

    def finish(self) -> dict[str, Any]:
        session, self.session = self.session, None
        if session is None:
            raise ConfigError(None, "no set-up with a known weight was started")
        shown = self.shown
        output = None if shown.read_only else output_path(shown.layout_path, session.profile.name)
        return session.finish(output)


def _state(request: Request) -> WeightSetup:
    """The app's :class:`WeightSetup`, made at its first request."""
    state = request.app.state
    if getattr(state, "weight_setup", None) is None:
        state.weight_setup = WeightSetup(state.shown)
    setup: WeightSetup = state.weight_setup
    return setup


async def _answer(work: Callable[..., dict[str, Any]], *args: Any) -> Response:
    try:
        return JSONResponse(await asyncio.to_thread(work, *args))
    except ConfigError as err:
        return refusal(422, error_dict(err))
    except ValueError as err:  # (readings of a shape the desk does not have)
        return refusal(422, message_error(str(err)))


async def weight_spots(request: Request) -> Response:
    """``GET /api/setup/weight/spots?count=N``: the N spots to mark, metres."""
    return await _answer(_state(request).spots, request.query_params.get("count", "4"))


async def weight_start(request: Request) -> Response:
    """``POST /api/setup/weight/start``: ``{mass_kg, count}``: start recording."""
    return await _answer(_state(request).start, await json_object(request))


async def weight_finish(request: Request) -> Response:
    """``POST /api/setup/weight/finish``: the fit, its check, the profile written."""
    return await _answer(_state(request).finish)


#: this module's part of the HTTP contract (gathered in :data:`.server.ROUTES`)
ROUTES: list[BaseRoute] = [
    Route("/api/setup/weight/spots", weight_spots, methods=["GET"]),
    Route("/api/setup/weight/start", weight_start, methods=["POST"]),
    Route("/api/setup/weight/finish", weight_finish, methods=["POST"]),
]
