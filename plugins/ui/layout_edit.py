"""The designer's edits of a layout's text, keeping comments, and saving it atomically.

Edits are applied to the YAML text with ruamel.yaml's round trip, so the user's comments, key
order and flow style survive; lengths from the page (metres) are written in the layout's
units. Checking what the edits make is the loader's (``check``'s) job: :mod:`.layout_api`.
"""

from __future__ import annotations

import io
import os
import re
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hapticdesk.errors import ConfigError, Position
from hapticdesk.files.strokefile import SHAPE_NAME
from hapticdesk.files.yamlfile import load_marked_yaml

# the names the layout's reader takes: the designer refuses none `check` accepts (it had
# refused `desk-lamp`) and takes none it refuses (`ẞtaste` passed Python's isidentifier)
from hapticdesk.gestures.layout_regions import REGION_NAME, REGION_RULE

#: decimals kept when metres from the page are written in a layout's units
DECIMALS = {"m": 4, "cm": 2, "mm": 1}
UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001}
SHAPE_KEYS = ("rect", "circle", "polygon")


def save_layout_text(layout_path: Path, text: str) -> None:
    """Write ``text`` to the layout file atomically (a reader never sees half a file)."""
    folder = layout_path.parent
    fd, tmp = tempfile.mkstemp(prefix=f".{layout_path.name}.", dir=folder)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as out:
            out.write(text)
        if layout_path.exists():
            os.chmod(tmp, layout_path.stat().st_mode & 0o777)
        os.replace(tmp, layout_path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _yaml(text: str) -> Any:
    from ruamel.yaml import YAML

    y = YAML(typ="rt")
    y.preserve_quotes = True
    y.width = 100
    # ruamel does not keep how far a block sequence's dashes are indented; take the file's
    # first one (`  - gesture: ...` under `bindings:` in the shipped layouts)
    dash = re.search(r"^( *)- ", text, re.MULTILINE)
    offset = len(dash.group(1)) if dash else 2
    y.indent(mapping=2, sequence=offset + 2, offset=offset)
    return y


def _flow(value: Any) -> Any:
    """``value`` as ruamel flow-style nodes, like the hand-written layouts' ``{rect: [...]}``."""
    from ruamel.yaml.comments import CommentedMap, CommentedSeq

    if isinstance(value, dict):
        m = CommentedMap()
        for k, v in value.items():
            m[k] = _flow(v)
        m.fa.set_flow_style()
        return m
    if isinstance(value, list | tuple):
        s = CommentedSeq(_flow(v) for v in value)
        s.fa.set_flow_style()
        return s
    return value


def _number(value: Any, what: str) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ConfigError(None, f"{what}: expected a number, found {value!r}") from None
    if number != number or number in (float("inf"), float("-inf")):
        raise ConfigError(None, f"{what}: expected a finite number, found {value!r}")
    return number


@dataclass(frozen=True)
class _Units:
    """Metres from the page, written in the layout's ``units`` (rounded to its decimals)."""

    scale: float
    digits: int

    @classmethod
    def of(cls, doc: Any) -> _Units:
        units = str(doc.get("units", "m"))
        return cls(UNITS.get(units, 1.0), DECIMALS.get(units, 4))

    def length(self, value: Any, what: str) -> float:
        return round(_number(value, what) / self.scale, self.digits)

    def point(self, p: Any, what: str) -> list[float]:
        if not isinstance(p, list | tuple) or len(p) != 2:
            raise ConfigError(None, f"{what}: expected [x, y], found {p!r}")
        return [self.length(p[0], what), self.length(p[1], what)]


def apply_edit(text: str, edit: dict[str, Any]) -> str:
    """``text`` with one edit from the designer applied; comments and order kept.

    Lengths in ``edit`` are metres (what the page measures); they are written in the
    layout's ``units``. Ops: ``set_region`` (name, shape rect|circle|polygon, rect
    [x0, y0, x1, y1] | center [x, y] + radius | points [[x, y], ...]), ``rename_region``
    (name, new_name), ``remove_region`` (name), ``add_binding`` (gesture, region or None,
    options, do {action: options}), ``remove_binding`` (index, 0-based), ``add_template``
    (shape, points)."""
    y, doc = _round_trip(text)
    op = edit.get("op")
    apply = EDITS.get(op) if isinstance(op, str) else None
    if apply is None:
        raise ConfigError(None, f"unknown edit {op!r}")
    apply(doc, edit, _Units.of(doc))
    out = io.StringIO()
    y.dump(doc, out)
    return out.getvalue()


def _round_trip(text: str) -> tuple[Any, Any]:
    """(ruamel's round-trip reader and writer for ``text``, the document it read)."""
    from ruamel.yaml.comments import CommentedMap
    from ruamel.yaml.error import YAMLError

    # first through the bounded reader `check` uses: ruamel recursed into 500 open brackets
    # until Python's stack ran out (a 500 and a 3,000-line traceback)
    if text.strip():
        load_marked_yaml("layout", text)
    y = _yaml(text)
    try:
        doc = y.load(text) if text.strip() else CommentedMap()
    except YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        where = Position("layout", mark.line + 1, mark.column + 1) if mark else None
        raise ConfigError(where, f"not valid YAML: {getattr(err, 'problem', err)}") from None
    if not isinstance(doc, dict):
        raise ConfigError(Position("layout", 1, 1), "a layout is a mapping")
    return y, doc


def _regions(doc: Any) -> Any:
    """The layout's ``regions:`` mapping (made when there is none)."""
    from ruamel.yaml.comments import CommentedMap

    regions = doc.get("regions")
    if not isinstance(regions, dict):
        regions = doc["regions"] = CommentedMap()
    return regions


def _region_name(name: Any) -> str:
    if not isinstance(name, str) or not REGION_NAME.match(name):
        raise ConfigError(None, f"region name {name!r} {REGION_RULE}")
    return name


def _shape(edit: dict[str, Any], units: _Units) -> dict[str, Any]:
    """The region's shape the edit gives, as the layout writes it."""
    shape = edit.get("shape")
    if shape == "rect":
        r = edit.get("rect") or []
        if len(r) != 4:
            raise ConfigError(None, "rect: expected [x0, y0, x1, y1]")
        x0, y0, x1, y1 = (units.length(v, "rect") for v in r)
        return {"rect": [min(x0, x1), min(y0, y1), max(x0, x1), max(y0, y1)]}
    if shape == "circle":
        center = units.point(edit.get("center"), "circle center")
        return {
            "circle": {
                "center": center,
                "radius": units.length(edit.get("radius"), "circle radius"),
            }
        }
    if shape == "polygon":
        pts = edit.get("points") or []
        if len(pts) < 3:
            raise ConfigError(None, "polygon: expected at least 3 points")
        return {"polygon": [units.point(p, "polygon point") for p in pts]}
    raise ConfigError(None, f"shape: expected rect, circle or polygon, found {shape!r}")


def _set_region(doc: Any, edit: dict[str, Any], units: _Units) -> None:
    regions = _regions(doc)
    name = _region_name(edit.get("name"))
    value = _shape(edit, units)
    existing = regions.get(name)
    if isinstance(existing, dict):  # keep its axis:, surface: and comments
        for key in SHAPE_KEYS:
            if key in existing:
                del existing[key]
        for k, v in value.items():
            existing.insert(0, k, _flow(v))
    else:
        regions[name] = _flow(value)


def _rename_region(doc: Any, edit: dict[str, Any], units: _Units) -> None:
    regions = _regions(doc)
    name, new = edit.get("name"), edit.get("new_name")
    if name not in regions:
        raise ConfigError(None, f"no region {name!r}")
    _region_name(new)
    if new in regions:
        raise ConfigError(None, f"there is already a region {new!r}")
    position = list(regions).index(name)
    regions.insert(position, new, regions.pop(name))
    for binding in doc.get("bindings") or []:
        if isinstance(binding, dict) and binding.get("region") == name:
            binding["region"] = new


def _remove_region(doc: Any, edit: dict[str, Any], units: _Units) -> None:
    regions = _regions(doc)
    name = edit.get("name")
    if name not in regions:
        raise ConfigError(None, f"no region {name!r}")
    del regions[name]


def _add_binding(doc: Any, edit: dict[str, Any], units: _Units) -> None:
    from ruamel.yaml.comments import CommentedSeq

    gesture = edit.get("gesture")
    if not isinstance(gesture, str) or not gesture:
        raise ConfigError(None, "add_binding needs a gesture")
    binding: dict[str, Any] = {"gesture": gesture}
    if edit.get("region"):
        binding["region"] = edit["region"]
    for k, v in (edit.get("options") or {}).items():
        binding[k] = v
    binding["do"] = edit.get("do") or {"log": {}}
    bindings = doc.get("bindings")
    if not isinstance(bindings, list):
        bindings = doc["bindings"] = CommentedSeq()
    bindings.append(_flow(binding))


def _remove_binding(doc: Any, edit: dict[str, Any], units: _Units) -> None:
    bindings = doc.get("bindings")
    index = edit.get("index")
    if not isinstance(bindings, list) or not isinstance(index, int):
        raise ConfigError(None, "remove_binding needs the binding's index")
    if not 0 <= index < len(bindings):
        raise ConfigError(None, f"no binding {index + 1}")
    del bindings[index]


def _add_template(doc: Any, edit: dict[str, Any], units: _Units) -> None:
    from ruamel.yaml.comments import CommentedMap, CommentedSeq

    shape = edit.get("shape")
    if not isinstance(shape, str) or not SHAPE_NAME.match(shape):
        raise ConfigError(None, f"a shape name is letters, digits and _; found {shape!r}")
    pts = [units.point(p, "template point") for p in edit.get("points") or []]
    if len(pts) < 2:
        raise ConfigError(None, "a template needs at least 2 points")
    templates = doc.get("templates")
    if not isinstance(templates, dict):
        if templates is not None:
            raise ConfigError(None, "`templates:` is a folder; add the stroke file there")
        templates = doc["templates"] = CommentedMap()
    current = templates.get(shape)
    if current is None:
        templates[shape] = CommentedSeq([_flow(pts)])
    elif isinstance(current, list) and current and isinstance(current[0], list | str):
        if isinstance(current[0], list) and current[0] and not isinstance(current[0][0], list):
            templates[shape] = CommentedSeq([current, _flow(pts)])  # was one inline stroke
        else:
            current.append(_flow(pts))
    else:
        templates[shape] = CommentedSeq([current, _flow(pts)])


#: the designer's edits by ``op``
EDITS: dict[str, Callable[[Any, dict[str, Any], _Units], None]] = {
    "set_region": _set_region,
    "rename_region": _rename_region,
    "remove_region": _remove_region,
    "add_binding": _add_binding,
    "remove_binding": _remove_binding,
    "add_template": _add_template,
}
