"""The $1 unistroke logs of real people (Wobbrock, Wilson, Li, UIST 2007), read as desk strokes.

One XML file a stroke: ``<Gesture Name="arrow01" Subject="2" Speed="fast" ...>`` holding
``<Point X=".." Y=".." T=".."/>`` in screen pixels (y points down) and milliseconds. A desk
stroke has y pointing away from the user (up on a page), so y is flipped; pixels become
millimetres (a $1 stroke of 100 px becomes 10 cm, the size a hand draws on a desk) and
times seconds from the first point. The logs name shapes a little differently from the
built-in templates (``delete_mark`` is ``delete``); :data:`SHAPE_NAMES` maps them.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np

from hapticdesk.errors import ConfigError
from hapticdesk.files.file_safety import regular_file_size

#: log name -> built-in template name
SHAPE_NAMES = {
    "arrow": "arrow",
    "caret": "caret",
    "check": "check",
    "circle": "circle",
    "delete_mark": "delete",
    "left_curly_brace": "left_brace",
    "left_sq_bracket": "left_bracket",
    "pigtail": "pigtail",
    "question_mark": "question_mark",
    "rectangle": "rectangle",
    "right_curly_brace": "right_brace",
    "right_sq_bracket": "right_bracket",
    "star": "star",
    "triangle": "triangle",
    "v": "v",
    "x": "x",
}
SPEEDS = ("slow", "medium", "fast")
METRES_PER_PIXEL = 0.001
#: a log holds one stroke of a few hundred points (the largest of the 2,400: 9 kB); a larger
#: file is not one, and is not read into memory to find out
MAX_LOG_BYTES = 1_000_000


@dataclass(frozen=True)
class LoggedStroke:
    """One logged stroke: ``shape`` (built-in name), who drew it, how fast, and its
    sample times (n,) in seconds and points (n, 2) in metres, y away from the user."""

    shape: str
    subject: str
    speed: str
    repetition: int
    t: np.ndarray
    points: np.ndarray


def read_logged_stroke(path: str | Path) -> LoggedStroke:
    """One $1 XML log file; a ConfigError at the file's line and column when it is not one.

    Read with expat, which gives each ``<Point>`` its place in the file (ElementTree's tree
    keeps none), from a regular file of at most :data:`MAX_LOG_BYTES`."""
    path = Path(path)
    elements = _elements(path)
    root = elements[0]
    name = root.attributes.get("Name", "")
    base = name.rstrip("0123456789")
    if root.tag != "Gesture" or base not in SHAPE_NAMES:
        raise ConfigError(
            root.where, f'expected <Gesture Name="<shape><rep>"> of a $1 shape, found {name!r}'
        )
    xyt = _point_rows([e for e in elements[1:] if e.tag == "Point"])
    if len(xyt) < 2:
        raise ConfigError(root.where, f"a stroke needs 2 or more points, found {len(xyt)}")
    points = np.column_stack([xyt[:, 0], -xyt[:, 1]]) * METRES_PER_PIXEL  # y down -> y away
    subject = root.attributes.get("Subject", "0")
    if not subject.isdigit():
        raise ConfigError(root.where, f"Subject is a number, found {subject!r}")
    return LoggedStroke(
        shape=SHAPE_NAMES[base],
        subject=f"s{int(subject):02d}",
        speed=root.attributes.get("Speed", "unknown"),
        repetition=int(name[len(base) :] or 0),
        t=(xyt[:, 2] - xyt[0, 2]) / 1000.0,
        points=points,
    )


class _Element(NamedTuple):
    """An XML element of a log: its tag and attributes, and where it begins
    (``file:line:column``)."""

    tag: str
    attributes: dict[str, str]
    where: str


def _elements(path: Path) -> list[_Element]:
    """The log's elements in order (at least one); a ConfigError where the file is not
    well-formed XML, or is not a regular file of at most :data:`MAX_LOG_BYTES`."""
    from xml.parsers import expat

    size = regular_file_size(path, "the $1 gesture log")
    if size > MAX_LOG_BYTES:
        raise ConfigError(
            str(path),
            f"{size:,} bytes; a $1 gesture log (a few hundred points) is at most {MAX_LOG_BYTES:,}",
        )
    parser = expat.ParserCreate()
    elements: list[_Element] = []

    def place(line: int, column: int) -> str:
        return f"{path}:{line}:{column + 1}"

    def start(tag: str, attributes: dict[str, str]) -> None:
        where = place(parser.CurrentLineNumber, parser.CurrentColumnNumber)
        elements.append(_Element(tag, attributes, where))

    parser.StartElementHandler = start
    try:
        data = path.read_bytes()
    except OSError as err:
        raise ConfigError(str(path), f"cannot read the $1 gesture log: {err}") from None
    try:
        parser.Parse(data, True)
    except expat.ExpatError as err:
        where = place(parser.ErrorLineNumber, parser.ErrorColumnNumber)
        message = expat.ErrorString(err.code)
        raise ConfigError(where, f"not a readable $1 gesture log: {message}") from None
    return elements


def _point_rows(marks: list[_Element]) -> np.ndarray:
    """(n, 3) X, Y and T of the ``<Point>`` elements ``marks``, each numeric and finite."""
    rows = []
    for point in marks:
        given = point.attributes
        try:
            rows.append((float(given["X"]), float(given["Y"]), float(given["T"])))
        except (KeyError, ValueError) as err:
            raise ConfigError(point.where, f"a <Point> needs numeric X, Y and T: {err}") from None
    xyt = np.array(rows).reshape(-1, 3)
    bad = np.flatnonzero(~np.isfinite(xyt).all(axis=1))
    if len(bad):
        raise ConfigError(
            marks[bad[0]].where, f"a <Point> needs finite X, Y and T, found {xyt[bad[0]]}"
        )
    return xyt


def read_logs(folder: str | Path) -> Iterator[LoggedStroke]:
    """Every ``*.xml`` log under ``folder`` (sorted by path)."""
    for path in sorted(Path(folder).rglob("*.xml")):
        yield read_logged_stroke(path)
