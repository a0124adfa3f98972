"""The $1 unistroke logs of real people (Wobbrock, Wilson, Li, UIST 2007), read as desk strokes.

One XML file a stroke: ``<Gesture Name="arrow01" Subject="2" Speed="fast" ...>`` holding
``<Point X=".." Y=".." T=".."/>`` in screen pixels (y points down) and milliseconds. A desk
stroke has y pointing away from the user (up on a page), so y is flipped; pixels become
millimetres (a $1 stroke of 100 px becomes 10 cm, the size a hand draws on a desk) and
times seconds from the first point. The logs name shapes a little differently from the
built-in templates (``delete_mark`` is ``delete``); :data:`SHAPE_NAMES` maps them.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hapticdesk.files.yamlfile import ConfigError

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
    """One $1 XML log file; a ConfigError naming the file when it is not one."""
    path = Path(path)
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError) as err:
        raise ConfigError(str(path), f"not a readable $1 gesture log: {err}") from None
    name = root.get("Name", "")
    base = name.rstrip("0123456789")
    if root.tag != "Gesture" or base not in SHAPE_NAMES:
        raise ConfigError(
            str(path), f'expected <Gesture Name="<shape><rep>"> of a $1 shape, found {name!r}'
        )
    try:
        xyt = np.array(
            [[float(p.attrib[k]) for k in ("X", "Y", "T")] for p in root.iter("Point")]
        ).reshape(-1, 3)
    except (KeyError, ValueError) as err:
        raise ConfigError(str(path), f"a <Point> needs numeric X, Y and T: {err}") from None
    if len(xyt) < 2 or not np.all(np.isfinite(xyt)):
        raise ConfigError(str(path), f"a stroke needs 2 or more finite points, found {len(xyt)}")
    points = np.column_stack([xyt[:, 0], -xyt[:, 1]]) * METRES_PER_PIXEL  # y down -> y away
    subject = root.get("Subject", "0")
    if not subject.isdigit():
        raise ConfigError(str(path), f"Subject is a number, found {subject!r}")
    return LoggedStroke(
        shape=SHAPE_NAMES[base],
        subject=f"s{int(subject):02d}",
        speed=root.get("Speed", "unknown"),
        repetition=int(name[len(base) :] or 0),
        t=(xyt[:, 2] - xyt[0, 2]) / 1000.0,
        points=points,
    )


def read_logs(folder: str | Path) -> Iterator[LoggedStroke]:
    """Every ``*.xml`` log under ``folder`` (sorted by path)."""
    for path in sorted(Path(folder).rglob("*.xml")):
        yield read_logged_stroke(path)
