"""The calibrated profile from a known-weight fit: each load cell becomes a calibrated
one-channel sensor ``fz`` at its fitted place (:func:`calibrated_profile`), and the profile's
YAML is rewritten to match (:func:`write_calibrated_profile`; a ``calibration`` column holds
each cell's gain, comments kept where ruamel.yaml is installed). The fit itself is
:mod:`hapticdesk.analysis.known_weight`.
"""

from __future__ import annotations

import io
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from hapticdesk.analysis.known_weight import CellFit
from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.profile_reader import profile_from_mapping
from hapticdesk.files.yamlfile import load_marked_yaml


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
