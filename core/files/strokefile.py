"""Stroke files (DESIGN.md, "Strokes"): CSV ``x,y[,t]`` with a header, or JSON
``{"points": [[x, y], ...]}``, in desk coordinates (metres, y away from the user).

A template folder holds one sub-folder per shape name with one or more stroke files.
"""

from __future__ import annotations

import csv
import io
import json
import math
import re
from pathlib import Path

import numpy as np

from hapticdesk.files.yamlfile import ConfigError

STROKE_SUFFIXES = (".csv", ".json")
SHAPE_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")


def read_stroke(path: str | Path) -> np.ndarray:
    """Points (n, 2) of one stroke file; a ConfigError naming file and line when malformed."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as err:
        raise ConfigError(
            str(path), f"cannot read the stroke file: {err.strerror or err}"
        ) from None
    if path.suffix.lower() == ".json":
        return _parse_json(text, str(path))
    if path.suffix.lower() == ".csv":
        return _parse_csv(text, str(path))
    raise ConfigError(
        str(path), 'a stroke file must end in .csv (x,y[,t]) or .json ({"points": ...})'
    )


def _checked(points: list[list[float]], where: str) -> np.ndarray:
    arr = np.asarray(points, dtype=float).reshape(-1, 2)
    if len(arr) < 2:
        raise ConfigError(where, f"a stroke needs at least 2 points, found {len(arr)}")
    if not np.all(np.isfinite(arr)):
        raise ConfigError(where, "a stroke's points must be finite numbers")
    if float(np.sum(np.hypot(*np.diff(arr, axis=0).T))) <= 0.0:
        raise ConfigError(where, "the stroke does not move: all its points are the same")
    return arr


def _parse_csv(text: str, where: str) -> np.ndarray:
    rows = list(csv.reader(io.StringIO(text)))
    if not rows:
        raise ConfigError(f"{where}:1", "empty stroke file, expected a header `x,y` or `x,y,t`")
    header = [h.strip() for h in rows[0]]
    if header[:2] != ["x", "y"] or header[2:] not in ([], ["t"]):
        raise ConfigError(
            f"{where}:1", f"the header must be `x,y` or `x,y,t`, found {','.join(header)!r}"
        )
    points = []
    for line, row in enumerate(rows[1:], start=2):
        if not row or not "".join(row).strip():
            continue
        if len(row) != len(header):
            raise ConfigError(f"{where}:{line}", f"expected {len(header)} values, found {len(row)}")
        try:
            values = [float(v) for v in row]
        except ValueError:
            raise ConfigError(f"{where}:{line}", f"not a number in {','.join(row)!r}") from None
        if not all(math.isfinite(v) for v in values):
            raise ConfigError(f"{where}:{line}", "values must be finite")
        points.append(values[:2])
    return _checked(points, where)


def _parse_json(text: str, where: str) -> np.ndarray:
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as err:
        raise ConfigError(
            f"{where}:{err.lineno}:{err.colno}", f"not valid JSON: {err.msg}"
        ) from None
    points = doc.get("points") if isinstance(doc, dict) else None
    if not isinstance(points, list) or not all(
        isinstance(p, list)
        and len(p) == 2
        and all(isinstance(v, int | float) and not isinstance(v, bool) for v in p)
        for p in points
    ):
        raise ConfigError(where, 'expected {"points": [[x, y], ...]} with two numbers per point')
    return _checked(points, where)


def write_stroke(path: str | Path, points: np.ndarray, t: np.ndarray | None = None) -> None:
    """Write a stroke as CSV ``x,y[,t]`` (or JSON when the name ends in .json)."""
    path = Path(path)
    pts = np.asarray(points, dtype=float)
    if path.suffix.lower() == ".json":
        path.write_text(json.dumps({"points": np.round(pts, 6).tolist()}) + "\n", encoding="utf-8")
        return
    with path.open("w", encoding="utf-8", newline="") as fh:
        if t is None:
            fh.write("x,y\n")
            np.savetxt(fh, pts, delimiter=",", fmt="%.6f")
        else:
            fh.write("x,y,t\n")
            np.savetxt(fh, np.column_stack([pts, t]), delimiter=",", fmt="%.6f")


def stroke_files(folder: str | Path) -> list[Path]:
    """Stroke files directly in ``folder``, sorted by name."""
    return sorted(
        p for p in Path(folder).iterdir() if p.is_file() and p.suffix.lower() in STROKE_SUFFIXES
    )


def read_template_dir(folder: str | Path) -> dict[str, list[np.ndarray]]:
    """``folder/<shape>/*.csv|json`` -> shape -> strokes (folders without strokes skipped)."""
    root = Path(folder)
    if not root.is_dir():
        raise ConfigError(str(root), "no such template folder (expected one sub-folder per shape)")
    out: dict[str, list[np.ndarray]] = {}
    for sub in sorted(p for p in root.iterdir() if p.is_dir()):
        if not SHAPE_NAME.match(sub.name):
            raise ConfigError(
                str(sub),
                "a shape folder's name must be letters, digits and _, starting with a letter",
            )
        files = stroke_files(sub)
        if files:
            out[sub.name] = [read_stroke(f) for f in files]
    return out
