"""Stroke files (docs/reference/files.md): CSV ``x,y[,t]`` with a header, or JSON
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

from hapticdesk.errors import ConfigError
from hapticdesk.files.file_safety import check_confined, decode_utf8, regular_file_size

STROKE_SUFFIXES = (".csv", ".json")
SHAPE_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")


#: the largest stroke file read: a captured stroke is a few thousand points (tens of kB)
MAX_STROKE_BYTES = 4_000_000
#: the most points a stroke may have (10 s of capture at 10 kHz; the recognizer resamples)
MAX_STROKE_POINTS = 100_000
#: the farthest a point may lie from the desk's origin, metres (desks are a few metres wide)
MAX_COORDINATE_M = 1000.0
#: JSON nesting deeper than this is refused before Python's decoder would recurse on it
_MAX_JSON_DEPTH = 32


def read_stroke(path: str | Path) -> np.ndarray:
    """Points (n, 2) of one stroke file; a ConfigError naming file and line when malformed."""
    path = Path(path)
    # (first: a missing file is said missing, not to end in the wrong suffix)
    size = regular_file_size(path, "the stroke file")
    suffix = path.suffix.lower()
    if suffix not in STROKE_SUFFIXES:
        raise ConfigError(
            str(path), 'a stroke file must end in .csv (x,y[,t]) or .json ({"points": ...})'
        )
    if size > MAX_STROKE_BYTES:
        raise ConfigError(
            str(path),
            f"the stroke file is {size / 1e6:.3g} MB, more than the {MAX_STROKE_BYTES / 1e6:g} MB "
            f"a stroke may have (at most {MAX_STROKE_POINTS} points)",
        )
    try:
        with path.open("rb") as fh:
            data = fh.read(MAX_STROKE_BYTES + 1)
    except OSError as err:
        raise ConfigError(
            str(path), f"cannot read the stroke file: {err.strerror or err}"
        ) from None
    if len(data) > MAX_STROKE_BYTES:  # it grew since it was measured
        raise ConfigError(
            str(path), f"the stroke file is larger than {MAX_STROKE_BYTES / 1e6:g} MB"
        )
    if suffix == ".json":
        return _parse_json(decode_utf8(data, str(path), "a JSON stroke"), str(path))
    return _parse_csv(decode_utf8(data, str(path), "a CSV stroke"), str(path))


def _checked(points: list[list[float]], where: str) -> np.ndarray:
    if len(points) > MAX_STROKE_POINTS:
        raise ConfigError(
            where, f"a stroke has at most {MAX_STROKE_POINTS} points, found {len(points)}"
        )
    arr = np.asarray(points, dtype=float).reshape(-1, 2)
    if len(arr) < 2:
        raise ConfigError(where, f"a stroke needs at least 2 points, found {len(arr)}")
    finite = np.isfinite(arr).all(axis=1)
    if not finite.all():
        i = int(np.argmin(finite))
        raise ConfigError(
            where,
            f"a stroke's points must be finite numbers; point {i + 1} is "
            f"[{arr[i, 0]:g}, {arr[i, 1]:g}]",
        )
    far = np.abs(arr).max(axis=1) > MAX_COORDINATE_M
    if far.any():
        i = int(np.argmax(far))
        raise ConfigError(
            where,
            f"a stroke's points are in metres on the desk, at most {MAX_COORDINATE_M:g} from "
            f"its origin; point {i + 1} is [{arr[i, 0]:g}, {arr[i, 1]:g}]",
        )
    if float(np.sum(np.hypot(*np.diff(arr, axis=0).T))) <= 0.0:
        raise ConfigError(where, "the stroke does not move: all its points are the same")
    return arr


def _parse_csv(text: str, where: str) -> np.ndarray:
    reader = csv.reader(io.StringIO(text))
    try:
        first = next(reader, None)
        if first is None:
            raise ConfigError(f"{where}:1", "empty stroke file, expected a header `x,y` or `x,y,t`")
        header = [h.strip() for h in first]
        if header[:2] != ["x", "y"] or header[2:] not in ([], ["t"]):
            shown = ",".join(header)
            shown = shown if len(shown) <= 60 else shown[:60] + "…"
            raise ConfigError(f"{where}:1", f"the header must be `x,y` or `x,y,t`, found {shown!r}")
        points = []
        for row in reader:
            line = reader.line_num
            if not row or not "".join(row).strip():
                continue
            if len(row) != len(header):
                raise ConfigError(
                    f"{where}:{line}", f"expected {len(header)} values, found {len(row)}"
                )
            try:
                values = [float(v) for v in row]
            except ValueError:
                shown = ",".join(row)
                shown = shown if len(shown) <= 60 else shown[:60] + "…"
                raise ConfigError(f"{where}:{line}", f"not a number in {shown!r}") from None
            if not all(math.isfinite(v) for v in values):
                raise ConfigError(f"{where}:{line}", "values must be finite")
            points.append(values[:2])
            if len(points) > MAX_STROKE_POINTS:
                raise ConfigError(
                    f"{where}:{line}", f"a stroke has at most {MAX_STROKE_POINTS} points"
                )
    except csv.Error as err:  # a cell over the csv module's field limit, a stray NUL …
        raise ConfigError(
            f"{where}:{reader.line_num}", f"not a CSV stroke (x,y[,t] per line): {err}"
        ) from None
    return _checked(points, where)


def _json_depth_error(text: str, where: str) -> ConfigError | None:
    """A ConfigError where brackets nest deeper than :data:`_MAX_JSON_DEPTH`, else None
    (Python's JSON decoder recurses once per level; a stroke needs 3)."""
    depth, line, column, in_string, escaped = 0, 1, 0, False, False
    for ch in text:
        column += 1
        if ch == "\n":
            line, column = line + 1, 0
        if in_string:
            if escaped:
                escaped = False
            elif ch == "\\":
                escaped = True
            elif ch == '"':
                in_string = False
        elif ch == '"':
            in_string = True
        elif ch in "[{":
            depth += 1
            if depth > _MAX_JSON_DEPTH:
                return ConfigError(
                    f"{where}:{line}:{column}",
                    f"JSON nested more than {_MAX_JSON_DEPTH} deep; a stroke is "
                    '{"points": [[x, y], ...]}',
                )
        elif ch in "]}":
            depth -= 1
    return None


def _parse_json(text: str, where: str) -> np.ndarray:
    try:
        # numbers as floats: a 5,000-digit integer is a mistake, not a reason to stop (int()
        # refuses over 4,300 digits; a huge one overflows a float later)
        doc = json.loads(text, parse_int=float)
    except json.JSONDecodeError as err:
        raise ConfigError(
            f"{where}:{err.lineno}:{err.colno}", f"not valid JSON: {err.msg}"
        ) from None
    except RecursionError:
        raise _json_depth_error(text, where) or ConfigError(
            where, "not valid JSON: nested too deep"
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
        check_confined(sub, "a template folder")  # (a link inside to a folder outside)
        if not SHAPE_NAME.match(sub.name):
            raise ConfigError(
                str(sub),
                "a shape folder's name must be letters, digits and _, starting with a letter",
            )
        files = stroke_files(sub)
        if files:
            out[sub.name] = [read_stroke(f) for f in files]
    return out
