"""The layout as the page sees it: checked like ``hapticdesk check``, edited keeping comments.

Checking goes through the loader ``check`` and ``run`` use (``load_scene_layout``), so the
page refuses what they would, at the same line and column. Edits are applied to the YAML text
with ruamel.yaml's round trip, so the user's comments, key order and flow style survive.
"""

from __future__ import annotations

import io
import os
import re
import tempfile
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


def error_dict(err: ConfigError) -> dict[str, Any]:
    """A ConfigError as ``{line, column, message}`` (0, 0 when it has no place in the file)."""
    where = err.where
    if isinstance(where, Position):
        return {"line": where.line, "column": where.column, "message": err.message}
    return message_error(err.message if where is None else f"{where}: {err.message}")


def message_error(message: str) -> dict[str, Any]:
    """An error with no place in the layout file, as :func:`error_dict` gives one."""
    return {"line": 0, "column": 0, "message": message}


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


# --- what the page draws ----------------------------------------------------------------------


def desk_message(profile: Any, layout: Any, *, live: bool) -> dict[str, Any]:
    """The WebSocket's first message: the desk's outline, surfaces and regions in metres."""
    import numpy as np

    surfaces = []
    for s in profile.surfaces:
        horizontal = abs(float(np.dot(s.normal, [0.0, 0.0, 1.0]))) > 0.99
        surfaces.append(
            {
                "name": s.name,
                "horizontal": horizontal,
                "height": float(s.origin[2]),
                "polygon": np.round(s.polygon, 5).tolist(),
            }
        )
    regions = []
    for name, r in layout.regions.items():
        regions.append(
            {
                "name": name,
                "kind": r.kind,
                "surface": r.surface,
                "outline": np.round(r.outline, 5).tolist(),
                "center": None if r.center is None else np.round(r.center, 5).tolist(),
                "radius": float(r.radius),
                "axis": None if r.axis is None else np.round(r.axis, 5).tolist(),
            }
        )
    bindings = [
        {
            "gesture": b.gesture,
            "region": b.region,
            "actions": [u.name for u in b.actions],
            "line": b.position.line,
        }
        for b in layout.bindings
    ]
    top = profile.surfaces[0].polygon if profile.surfaces else np.zeros((0, 2))
    return {
        "type": "desk",
        "name": profile.name,
        "live": live,
        "units": layout.units,
        "layout": str(layout.path),
        "outline": np.round(top, 5).tolist(),
        "surfaces": surfaces,
        "sensors": [
            {"name": s.name, "x": float(s.position[0]), "y": float(s.position[1])}
            for s in profile.sensors
        ],
        "regions": regions,
        "bindings": bindings,
        "templates": sorted(layout.templates),
    }


def schemas(registry: Any) -> dict[str, Any]:
    """Forms for the designer: each gesture's options (its recognizer's ``option_specs``, or
    the built-in table) and each action's options (the schema its plugin registered)."""
    from hapticdesk.gestures.options import GESTURE_OPTIONS

    gestures: dict[str, Any] = {}
    types = registry.recognizer_types()
    for name in sorted(set(GESTURE_OPTIONS) | set(types)):
        specs = GESTURE_OPTIONS.get(name)
        if specs is None:
            try:
                specs = getattr(types[name].load(), "option_specs", None) or {}
            except ConfigError:
                specs = {}
        gestures[name] = {
            key: {
                "kind": spec.kind,
                "default": spec.default,
                "help": spec.help,
                "choices": list(spec.choices),
                "role": spec.role,
            }
            for key, spec in specs.items()
        }
    actions = {
        name: {
            "description": record.description,
            "options": getattr(record, "options", None),
            "plugin": record.plugin,
        }
        for name, record in sorted(registry.actions.items())
        if name != "exec"  # the page never adds a program to run
    }
    return {"gestures": gestures, "actions": actions}


# --- edits ------------------------------------------------------------------------------------


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


def apply_edit(text: str, edit: dict[str, Any]) -> str:
    """``text`` with one edit from the designer applied; comments and order kept.

    Lengths in ``edit`` are metres (what the page measures); they are written in the
    layout's ``units``. Ops: ``set_region`` (name, shape rect|circle|polygon, rect
    [x0, y0, x1, y1] | center [x, y] + radius | points [[x, y], ...]), ``rename_region``
    (name, new_name), ``remove_region`` (name), ``add_binding`` (gesture, region or None,
    options, do {action: options}), ``remove_binding`` (index, 0-based), ``add_template``
    (shape, points)."""
    from ruamel.yaml.comments import CommentedMap, CommentedSeq
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
    units = str(doc.get("units", "m"))
    scale = UNITS.get(units, 1.0)
    digits = DECIMALS.get(units, 4)

    def length(v: Any, what: str) -> float:
        return round(_number(v, what) / scale, digits)

    def point(p: Any, what: str) -> list[float]:
        if not isinstance(p, list | tuple) or len(p) != 2:
            raise ConfigError(None, f"{what}: expected [x, y], found {p!r}")
        return [length(p[0], what), length(p[1], what)]

    op = edit.get("op")
    regions = doc.get("regions")
    if op in ("set_region", "rename_region", "remove_region") and not isinstance(regions, dict):
        regions = doc["regions"] = CommentedMap()
    name = edit.get("name")
    if op == "set_region":
        if not isinstance(name, str) or not REGION_NAME.match(name):
            raise ConfigError(None, f"region name {name!r} {REGION_RULE}")
        shape = edit.get("shape")
        if shape == "rect":
            r = edit.get("rect") or []
            if len(r) != 4:
                raise ConfigError(None, "rect: expected [x0, y0, x1, y1]")
            x0, y0, x1, y1 = (length(v, "rect") for v in r)
            value: Any = {"rect": [min(x0, x1), min(y0, y1), max(x0, x1), max(y0, y1)]}
        elif shape == "circle":
            value = {
                "circle": {
                    "center": point(edit.get("center"), "circle center"),
                    "radius": length(edit.get("radius"), "circle radius"),
                }
            }
        elif shape == "polygon":
            pts = edit.get("points") or []
            if len(pts) < 3:
                raise ConfigError(None, "polygon: expected at least 3 points")
            value = {"polygon": [point(p, "polygon point") for p in pts]}
        else:
            raise ConfigError(None, f"shape: expected rect, circle or polygon, found {shape!r}")
        existing = regions.get(name)
        if isinstance(existing, dict):  # keep its axis:, surface: and comments
            for key in SHAPE_KEYS:
                if key in existing:
                    del existing[key]
            for k, v in value.items():
                existing.insert(0, k, _flow(v))
        else:
            regions[name] = _flow(value)
    elif op == "rename_region":
        new = edit.get("new_name")
        if name not in regions:
            raise ConfigError(None, f"no region {name!r}")
        if not isinstance(new, str) or not REGION_NAME.match(new):
            raise ConfigError(None, f"region name {new!r} {REGION_RULE}")
        if new in regions:
            raise ConfigError(None, f"there is already a region {new!r}")
        position = list(regions).index(name)
        regions.insert(position, new, regions.pop(name))
        for binding in doc.get("bindings") or []:
            if isinstance(binding, dict) and binding.get("region") == name:
                binding["region"] = new
    elif op == "remove_region":
        if name not in regions:
            raise ConfigError(None, f"no region {name!r}")
        del regions[name]
    elif op == "add_binding":
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
    elif op == "remove_binding":
        bindings = doc.get("bindings")
        index = edit.get("index")
        if not isinstance(bindings, list) or not isinstance(index, int):
            raise ConfigError(None, "remove_binding needs the binding's index")
        if not 0 <= index < len(bindings):
            raise ConfigError(None, f"no binding {index + 1}")
        del bindings[index]
    elif op == "add_template":
        shape = edit.get("shape")
        if not isinstance(shape, str) or not SHAPE_NAME.match(shape):
            raise ConfigError(None, f"a shape name is letters, digits and _; found {shape!r}")
        pts = [point(p, "template point") for p in edit.get("points") or []]
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
    else:
        raise ConfigError(None, f"unknown edit {op!r}")
    out = io.StringIO()
    y.dump(doc, out)
    return out.getvalue()
