"""Layouts: which parts of the desk are buttons, sliders and drawing areas, and what each
gesture there does (DESIGN.md, "Layout").

Loading validates everything a person can get wrong and reports ``file:line:column``, what
was found and what is allowed: unknown keys, unknown region, gesture, action or shape names,
values out of range, overlapping regions that bind the same gesture, a region off the desk.
Gesture settings resolve at three levels (options.py): built-in, layout-wide ``settings:``,
binding. The top-level ``mqtt:`` and ``desk_name:`` are kept raw in :attr:`Layout.raw` for
the MQTT action plugin, which validates them.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Collection, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hapticdesk.files.profile import DeskProfile, load_profile
from hapticdesk.files.strokefile import (
    SHAPE_NAME,
    read_stroke,
    read_template_dir,
    stroke_files,
)
from hapticdesk.files.yamlfile import (
    ConfigError,
    MarkedDict,
    MarkedList,
    Position,
    check_keys,
    choice,
    load_marked_yaml,
    number,
    require_mapping,
    vector,
)
from hapticdesk.gestures.event import GestureEvent
from hapticdesk.gestures.options import (
    ANYWHERE_GESTURES,
    DIRECTIONS_4,
    DIRECTIONS_8,
    GESTURE_OPTIONS,
    PHASES,
    OptionSpec,
    defaults,
    read_option,
)
from hapticdesk.gestures.regions import (
    Region,
    circle_outline,
    points_in_polygon,
    polygon_area,
    regions_overlap,
)

UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001}
TOP_KEYS = frozenset(
    {"desk", "units", "regions", "bindings", "settings", "templates", "description"}
    | {"builtin_templates"}
    | {"mqtt", "desk_name"}  # kept raw for the MQTT action plugin
)
REGION_KINDS = ("rect", "circle", "polygon")
REGION_KEYS = frozenset({*REGION_KINDS, "surface", "axis", "description"})
BINDING_KEYS = frozenset({"gesture", "region", "do", "description"})
REGION_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_-]*$")
#: the folder beside the layout that `hapticdesk strokes record` fills by default
DEFAULT_TEMPLATE_DIR = "strokes"

ValidateAction = Callable[[str, Any, Position], None]


@dataclass(frozen=True)
class ActionUse:
    """One action a binding runs: its name, its options as written, and where they stand."""

    name: str
    options: Any
    position: Position


@dataclass
class Binding:
    """A gesture (in a region, or anywhere) and the actions it runs.

    ``options`` holds every option of the gesture resolved over the three levels (lengths in
    metres): the recognizer settings of its region and this binding's match filters.
    """

    index: int
    gesture: str
    region: str | None
    options: dict[str, Any]
    actions: list[ActionUse]
    position: Position

    def matches(self, event: GestureEvent) -> bool:
        """Whether this binding reacts to ``event``."""
        if event.gesture != self.gesture:
            return False
        if self.region is not None and event.region != self.region:
            return False
        if self.gesture not in GESTURE_OPTIONS:
            return True  # a plugin gesture: its options tune its recognizer
        o = self.options
        if self.gesture == "stroke" and event.shape is None:
            return False  # a rejected stroke triggers nothing
        if self.gesture == "long_press":
            hold = event.hold_s or 0.0
            if o.get("release"):
                return event.phase == "end" and hold >= o["hold_s"] - 1e-9
            return event.phase != "end" and abs(hold - o["hold_s"]) < 1e-9
        for key in ("shape", "direction", "level", "phase"):
            wanted = o.get(key)
            if wanted is not None and getattr(event, key) not in wanted:
                return False
        return True


@dataclass
class Layout:
    """A validated layout on a desk."""

    path: Path
    desk: DeskProfile
    units: str
    regions: dict[str, Region]
    bindings: list[Binding]
    #: layout-wide settings per bound gesture: built-in defaults updated by `settings:`
    settings: dict[str, dict[str, Any]]
    #: recognizer settings per (gesture, region or None), after the binding level
    region_options: dict[tuple[str, str | None], dict[str, Any]]
    #: user stroke templates: shape -> strokes (n, 2)
    templates: dict[str, list[np.ndarray]]
    raw: MarkedDict
    warnings: list[str] = field(default_factory=list)
    #: whether strokes are matched against the shipped templates too (`builtin_templates:`)
    builtin_templates: bool = True

    @classmethod
    def from_yaml(cls, path: str | Path, **kwargs: Any) -> Layout:
        """Same as :func:`load_layout`."""
        return load_layout(path, **kwargs)

    @property
    def gestures(self) -> list[str]:
        """Bound gesture names in the order they first appear."""
        return list(dict.fromkeys(b.gesture for b in self.bindings))

    def options_for(self, gesture: str, region: str | None) -> dict[str, Any]:
        """Recognizer settings of ``gesture`` in ``region`` (layout-wide where not bound there)."""
        found = self.region_options.get((gesture, region))
        if found is not None:
            return found
        if gesture in self.settings:
            return self.settings[gesture]
        return defaults(GESTURE_OPTIONS.get(gesture, {}))

    @property
    def metres_per_unit(self) -> float:
        return UNITS[self.units]

    @property
    def template_dir(self) -> Path:
        """Where `hapticdesk strokes record` puts templates for this layout."""
        value = self.raw.get("templates")
        folder = value if isinstance(value, str) else DEFAULT_TEMPLATE_DIR
        return (self.path.parent / folder).resolve()


def load_layout(
    path: str | Path,
    profile: DeskProfile | None = None,
    action_names: Collection[str] | None = None,
    validate_action: ValidateAction | None = None,
    recognizer_types: Mapping[str, type] | None = None,
) -> Layout:
    """Load and validate a layout; raises :class:`ConfigError` on any problem.

    ``profile`` overrides the layout's ``desk:``. ``action_names``: the known actions (an
    unknown one is an error); ``validate_action(name, options, position)`` is called for
    every action use and may raise ConfigError. ``recognizer_types``: plugin gestures (name
    -> recognizer class, whose optional ``option_specs`` describe its options).
    """
    path = Path(path)
    doc = require_mapping(load_marked_yaml(path), str(path), "a layout")
    return _LayoutReader(doc, path, profile, action_names, validate_action, recognizer_types).read()


class _LayoutReader:
    """The validation, step by step; each step raises ConfigError at the offending spot."""

    def __init__(
        self,
        doc: MarkedDict,
        path: Path,
        profile: DeskProfile | None,
        action_names: Collection[str] | None,
        validate_action: ValidateAction | None,
        recognizer_types: Mapping[str, type] | None,
    ) -> None:
        self.doc = doc
        self.path = path
        self.profile = profile
        self.action_names = set(action_names) if action_names is not None else None
        self.validate_action = validate_action
        self.specs: dict[str, dict[str, OptionSpec] | None] = dict(GESTURE_OPTIONS)
        for name, cls in (recognizer_types or {}).items():
            if name in GESTURE_OPTIONS:
                raise ConfigError(None, f"a plugin recognizer may not replace built-in `{name}`")
            self.specs[name] = getattr(cls, "option_specs", None)
        self.scale = 1.0
        self.units = "m"
        self.warnings: list[str] = []

    # -- top level ---------------------------------------------------------------------------
    def read(self) -> Layout:
        doc = self.doc
        check_keys(doc, TOP_KEYS, "the layout", required={"bindings"})
        desk = self._desk()
        self.units = choice(doc, "units", tuple(UNITS), "the layout", default="m")
        self.scale = UNITS[self.units]
        regions = self._regions(desk)
        settings = self._settings()
        templates = self._templates()
        builtin = self._builtin_templates(bool(templates))
        bindings, explicit = self._bindings(regions)
        region_options = self._resolve(bindings, explicit, settings)
        shapes = (builtin_shape_names() if builtin else set()) | set(templates)
        for b in bindings:
            self._check_binding(b, shapes)
        self._check_overlaps(bindings, regions)
        bound = {b.gesture for b in bindings}
        return Layout(
            path=self.path,
            desk=desk,
            units=self.units,
            regions=regions,
            bindings=bindings,
            settings={g: s for g, s in settings.items() if g in bound},
            region_options=region_options,
            templates=templates,
            raw=doc,
            warnings=self.warnings,
            builtin_templates=builtin,
        )

    def _desk(self) -> DeskProfile:
        if self.profile is not None:
            return self.profile
        if "desk" not in self.doc:
            raise ConfigError(
                self.doc.where(),
                "the layout is missing `desk` (a profile name from profiles/ or a path); "
                "or give one with --desk",
            )
        value = self.doc["desk"]
        if not isinstance(value, str) or not value:
            raise ConfigError(
                self.doc.where("desk"), f"`desk` must be a profile name or path, found {value!r}"
            )
        try:
            profile = load_profile(value, relative_to=self.path.parent)
        except ConfigError as err:
            if err.where == value:  # not found: point at the layout, not at the bare name
                raise ConfigError(
                    self.doc.where("desk"), f"desk `{value}`: {err.message}"
                ) from None
            raise
        if not profile.surfaces:
            raise ConfigError(
                self.doc.where("desk"), f"desk `{profile.name}` has no surfaces to touch"
            )
        return profile

    # -- regions -----------------------------------------------------------------------------
    def _regions(self, desk: DeskProfile) -> dict[str, Region]:
        if "regions" not in self.doc:
            return {}
        raw = require_mapping(self.doc["regions"], self.doc.where("regions"), "`regions`")
        out: dict[str, Region] = {}
        for name in raw:
            if not REGION_NAME.match(name):
                raise ConfigError(
                    raw.where(name, of_key=True),
                    f"region name {name!r} must start with a letter and hold only letters, "
                    "digits, _ and -",
                )
            out[name] = self._region(name, raw[name], raw.where(name), desk)
        return out

    def _region(self, name: str, value: Any, where: Position, desk: DeskProfile) -> Region:
        what = f"region `{name}`"
        m = require_mapping(value, where, what)
        check_keys(m, REGION_KEYS, what)
        kinds = [k for k in REGION_KINDS if k in m]
        if len(kinds) != 1:
            found = ", ".join(kinds) if kinds else "none"
            raise ConfigError(
                m.where(), f"{what} needs exactly one of rect, circle, polygon; found {found}"
            )
        kind = kinds[0]
        surfaces = [s.name for s in desk.surfaces]
        surface = choice(m, "surface", tuple(surfaces), what, default=surfaces[0])
        index = surfaces.index(surface)
        s = self.scale
        center = None
        radius = 0.0
        if kind == "rect":
            x0, y0, x1, y1 = (
                v * s
                for v in vector(
                    m["rect"], m.where("rect"), f"`rect` of {what} ([x0, y0, x1, y1])", 4
                )
            )
            if not (x0 < x1 and y0 < y1):
                raise ConfigError(
                    m.where("rect"),
                    f"`rect` of {what} is [x0, y0, x1, y1] with x0 < x1 and y0 < y1, "
                    f"found {list(m['rect'])}",
                )
            outline = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
        elif kind == "circle":
            c = require_mapping(
                m["circle"],
                m.where("circle"),
                f"`circle` of {what} ({{center: [x, y], radius: r}})",
            )
            check_keys(
                c, {"center", "radius"}, f"`circle` of {what}", required={"center", "radius"}
            )
            center = np.array(vector(c["center"], c.where("center"), f"`center` of {what}", 2)) * s
            radius = (
                number(c, "radius", f"`circle` of {what}", minimum=0.0, exclusive_minimum=True) * s
            )
            outline = circle_outline(center, radius)
        else:
            pts = m["polygon"]
            if not isinstance(pts, MarkedList) or len(pts) < 3:
                raise ConfigError(
                    m.where("polygon"), f"`polygon` of {what} must list 3 or more [x, y] points"
                )
            outline = (
                np.array(
                    [
                        vector(p, pts.where(i), f"point {i + 1} of {what}", 2)
                        for i, p in enumerate(pts)
                    ]
                )
                * s
            )
            if abs(polygon_area(outline)) < 1e-12:
                raise ConfigError(m.where("polygon"), f"`polygon` of {what} has no area")
        axis = self._axis(m, what, outline) if "axis" in m else None
        region = Region(name, kind, surface, index, outline, center, radius, axis)
        self._check_on_surface(region, desk, m.where(kind))
        return region

    def _axis(self, m: MarkedDict, what: str, outline: np.ndarray) -> np.ndarray:
        value = m["axis"]
        lo, hi = outline.min(axis=0), outline.max(axis=0)
        mid = (lo + hi) / 2
        if value == "x":
            return np.array([[lo[0], mid[1]], [hi[0], mid[1]]])
        if value == "y":
            return np.array([[mid[0], lo[1]], [mid[0], hi[1]]])
        if isinstance(value, MarkedList) and len(value) == 2:
            a, b = (
                np.array(vector(p, value.where(i), f"axis point {i + 1} of {what}", 2)) * self.scale
                for i, p in enumerate(value)
            )
            if np.hypot(*(b - a)) <= 0:
                raise ConfigError(m.where("axis"), f"the two `axis` points of {what} are the same")
            return np.array([a, b])
        raise ConfigError(
            m.where("axis"),
            f"`axis` of {what} must be x, y or two points [[x0, y0], [x1, y1]] "
            f"(value 0 at the first), found {value!r}",
        )

    def _check_on_surface(self, region: Region, desk: DeskProfile, where: Position) -> None:
        surface = desk.surfaces[region.surface_index]
        x0, y0, x1, y1 = region.bounds
        grid = np.meshgrid(np.linspace(x0, x1, 41), np.linspace(y0, y1, 41))
        gx, gy = grid[0].ravel(), grid[1].ravel()
        inside = region.contains(gx, gy)
        on_surface = points_in_polygon(gx[inside], gy[inside], surface.polygon)
        if on_surface.all():
            return
        sx0, sy0 = surface.polygon.min(axis=0) / self.scale
        sx1, sy1 = surface.polygon.max(axis=0) / self.scale
        extent = f"x {sx0:g}..{sx1:g} and y {sy0:g}..{sy1:g} {self.units}"
        if on_surface.any():
            self.warnings.append(
                f"{where}: region `{region.name}` reaches beyond surface `{surface.name}` "
                f"({extent})"
            )
            return
        hint = ""
        if self.units == "m" and np.all(
            np.abs(region.outline) * 0.01 <= np.abs(surface.polygon).max()
        ):
            hint = "; are the numbers in cm? add `units: cm`"
        raise ConfigError(
            where,
            f"region `{region.name}` lies entirely outside surface `{surface.name}` of desk "
            f"`{desk.name}`, which spans {extent}{hint}",
        )

    # -- settings ----------------------------------------------------------------------------
    def _settings(self) -> dict[str, dict[str, Any]]:
        out = {g: defaults(spec) for g, spec in self.specs.items() if spec is not None}
        if "settings" not in self.doc:
            return out
        raw = require_mapping(self.doc["settings"], self.doc.where("settings"), "`settings`")
        for gesture in raw:
            if gesture not in self.specs:
                raise ConfigError(
                    raw.where(gesture, of_key=True),
                    f"unknown gesture `{gesture}` in `settings`; "
                    f"known: {', '.join(sorted(self.specs))}",
                )
            what = f"`settings.{gesture}`"
            m = require_mapping(raw[gesture], raw.where(gesture), what)
            spec = self.specs[gesture]
            if spec is None:  # a plugin recognizer without a schema takes what it is given
                out[gesture] = dict(m)
                continue
            tunable = {k for k, v in spec.items() if v.role == "recognize"}
            for key in m:
                if key in spec and key not in tunable:
                    raise ConfigError(
                        m.where(key, of_key=True),
                        f"`{key}` chooses what a binding reacts to; "
                        f"put it on a `{gesture}` binding",
                    )
            check_keys(m, tunable, what)
            for key in m:
                out[gesture][key] = read_option(spec[key], m, key, what, self.scale)
        return out

    # -- templates ---------------------------------------------------------------------------
    def _templates(self) -> dict[str, list[np.ndarray]]:
        if "templates" not in self.doc:
            return {}
        value = self.doc["templates"]
        where = self.doc.where("templates")
        base = self.path.parent
        if isinstance(value, str):
            folder = base / value
            if not folder.is_dir():
                raise ConfigError(where, f"no template folder `{value}` (looked in {folder})")
            return read_template_dir(folder)
        raw = require_mapping(value, where, "`templates` (a folder, or shape -> files or points)")
        out: dict[str, list[np.ndarray]] = {}
        for shape in raw:
            if not SHAPE_NAME.match(shape):
                raise ConfigError(
                    raw.where(shape, of_key=True),
                    f"shape name {shape!r} must be letters, digits and _, starting with a letter",
                )
            out[shape] = self._template_items(raw[shape], raw.where(shape), shape, base)
        return out

    def _builtin_templates(self, has_user_templates: bool) -> bool:
        """`builtin_templates: false` leaves only the layout's own templates."""
        value = self.doc.get("builtin_templates", True)
        where = self.doc.where("builtin_templates")
        if not isinstance(value, bool):
            raise ConfigError(where, f"`builtin_templates` is true or false, found {value!r}")
        if not value and not has_user_templates:
            raise ConfigError(where, "`builtin_templates: false` needs shapes under `templates:`")
        return value

    def _template_items(
        self, value: Any, where: Position, shape: str, base: Path
    ) -> list[np.ndarray]:
        if _is_point_list(value):  # one inline template
            return [self._inline(value, where, shape)]
        items = value if isinstance(value, MarkedList) else [value]
        positions = (
            [value.where(i) for i in range(len(value))]
            if isinstance(value, MarkedList)
            else [where]
        )
        out: list[np.ndarray] = []
        for item, pos in zip(items, positions, strict=True):
            if isinstance(item, str):
                target = base / item
                if target.is_dir():
                    files = stroke_files(target)
                    if not files:
                        raise ConfigError(
                            pos, f"template folder `{item}` holds no .csv or .json stroke"
                        )
                    out.extend(_read_at(f, pos) for f in files)
                elif target.is_file():
                    out.append(_read_at(target, pos))
                else:
                    raise ConfigError(
                        pos, f"no stroke file or folder `{item}` (looked in {target})"
                    )
            elif _is_point_list(item):
                out.append(self._inline(item, pos, shape))
            else:
                raise ConfigError(
                    pos,
                    f"a template of `{shape}` is a stroke file, a folder of them, or a list of "
                    f"[x, y] points; found {item!r}",
                )
        if not out:
            raise ConfigError(where, f"shape `{shape}` lists no templates")
        return out

    def _inline(self, value: MarkedList, where: Position, shape: str) -> np.ndarray:
        pts = (
            np.array(
                [
                    vector(p, value.where(i), f"point {i + 1} of template `{shape}`", 2)
                    for i, p in enumerate(value)
                ]
            )
            * self.scale
        )
        if len(pts) < 2 or float(np.sum(np.hypot(*np.diff(pts, axis=0).T))) <= 0:
            raise ConfigError(where, f"a template of `{shape}` needs at least 2 distinct points")
        return pts

    # -- bindings ----------------------------------------------------------------------------
    def _bindings(
        self, regions: dict[str, Region]
    ) -> tuple[list[Binding], dict[tuple[str, str | None], dict[str, tuple[Any, Position, int]]]]:
        raw = self.doc["bindings"]
        if not isinstance(raw, MarkedList) or not raw:
            raise ConfigError(
                self.doc.where("bindings"), "`bindings` must be a list of at least one binding"
            )
        bindings = []
        # (gesture, region) -> option -> (value, where, binding index) set explicitly on a binding
        explicit: dict[tuple[str, str | None], dict[str, tuple[Any, Position, int]]] = {}
        for i, item in enumerate(raw):
            what = f"binding {i + 1}"
            m = require_mapping(item, raw.where(i), what)
            gesture = choice(m, "gesture", tuple(sorted(self.specs)), what)
            what = f"binding {i + 1} (`{gesture}`)"
            spec = self.specs[gesture]
            allowed = BINDING_KEYS | set(spec or {})
            if spec is not None:
                check_keys(m, allowed, what, required={"do"})
            elif "do" not in m:
                raise ConfigError(m.where(), f"{what} is missing `do`")
            region = self._binding_region(m, gesture, what, regions)
            options: dict[str, Any] = {}
            for key in m:
                if key in BINDING_KEYS:
                    continue
                if spec is None:
                    options[key] = m[key]
                    continue
                value = read_option(spec[key], m, key, what, self.scale)
                if spec[key].role == "recognize":
                    slot = explicit.setdefault((gesture, region), {})
                    if key in slot and slot[key][0] != value:
                        first_value, first_where, first_index = slot[key]
                        raise ConfigError(
                            m.where(key),
                            f"`{key}` of `{gesture}` in {_region_text(region)} is {m[key]!r} "
                            "here but "
                            f"binding {first_index + 1} ({first_where}) sets another value; one "
                            "recognizer judges that region, so its settings must agree",
                        )
                    slot[key] = (value, m.where(key), i)
                options[key] = value
            actions = self._actions(m, what)
            bindings.append(Binding(i, gesture, region, options, actions, m.where()))
        return bindings, explicit

    def _binding_region(
        self, m: MarkedDict, gesture: str, what: str, regions: dict[str, Region]
    ) -> str | None:
        names = ", ".join(regions) or "none defined"
        if "region" not in m:
            if gesture in ANYWHERE_GESTURES or gesture not in GESTURE_OPTIONS:
                return None
            raise ConfigError(m.where(), f"{what} needs `region` (one of: {names})")
        region = m["region"]
        if region not in regions:
            raise ConfigError(
                m.where("region"), f"unknown region {region!r} in {what}; regions: {names}"
            )
        if gesture == "slide" and regions[region].axis is None:
            raise ConfigError(
                m.where("region"),
                f"region `{region}` has no `axis`; a slider needs `axis: x`, `axis: y` "
                "or two points",
            )
        return str(region)

    def _actions(self, m: MarkedDict, what: str) -> list[ActionUse]:
        value = m["do"]
        where = m.where("do")
        items = value if isinstance(value, MarkedList) else [value]
        positions = value.item_positions if isinstance(value, MarkedList) else [where]
        uses: list[tuple[ActionUse, Position]] = []  # with the position of the name
        for item, pos in zip(items, positions, strict=True):
            if isinstance(item, str):
                uses.append((ActionUse(item, None, pos), pos))
            elif isinstance(item, MarkedDict) and item:
                uses += [
                    (ActionUse(name, item[name], item.where(name)), item.where(name, of_key=True))
                    for name in item
                ]
            else:
                raise ConfigError(
                    pos,
                    f"`do` of {what} must be actions like {{log: {{}}}} or a list of them, "
                    f"found {item!r}",
                )
        if not uses:
            raise ConfigError(where, f"`do` of {what} names no action, e.g. `do: {{log: {{}}}}`")
        for use, name_at in uses:
            if self.action_names is not None and use.name not in self.action_names:
                known = ", ".join(sorted(self.action_names)) or "none installed"
                raise ConfigError(name_at, f"unknown action `{use.name}` in {what}; known: {known}")
            if self.validate_action is not None:
                self.validate_action(use.name, use.options, use.position)
        return [use for use, _ in uses]

    def _resolve(
        self,
        bindings: list[Binding],
        explicit: dict[tuple[str, str | None], dict[str, tuple[Any, Position, int]]],
        settings: dict[str, dict[str, Any]],
    ) -> dict[tuple[str, str | None], dict[str, Any]]:
        """Recognizer settings per (gesture, region): settings level, then the bindings'."""
        resolved: dict[tuple[str, str | None], dict[str, Any]] = {}
        for b in bindings:
            key = (b.gesture, b.region)
            if key not in resolved:
                base = dict(settings.get(b.gesture, {}))
                base.update({k: v[0] for k, v in explicit.get(key, {}).items()})
                resolved[key] = base
            spec = self.specs[b.gesture]
            own_match = {
                k: v for k, v in b.options.items() if spec is None or spec[k].role == "match"
            }
            match_defaults = {k: s.default for k, s in (spec or {}).items() if s.role == "match"}
            b.options = {**resolved[key], **match_defaults, **own_match}
        return resolved

    def _check_binding(self, b: Binding, shapes: set[str]) -> None:
        o = b.options
        what = f"binding {b.index + 1} (`{b.gesture}`)"
        raw = self.doc["bindings"][b.index]
        if b.gesture == "force" and not o["min_n"] < o["max_n"]:
            raise ConfigError(
                raw.where(),
                f"{what}: `min_n` ({o['min_n']:g} N) must be below `max_n` ({o['max_n']:g} N)",
            )
        if b.gesture == "press":
            if o["hysteresis_n"] >= min(o["levels"].values()):
                raise ConfigError(
                    raw.where("hysteresis_n") if "hysteresis_n" in raw else raw.where(),
                    f"{what}: `hysteresis_n` ({o['hysteresis_n']:g} N) must be below the "
                    "lowest level",
                )
            self._check_names(raw, "level", o["level"], tuple(o["levels"]), what)
        if b.gesture == "swipe":
            allowed = DIRECTIONS_8 if o["directions"] == 8 else DIRECTIONS_4
            self._check_names(
                raw,
                "direction",
                o["direction"],
                allowed,
                what,
                f" with directions: {o['directions']}",
            )
        if b.gesture == "stroke":
            self._check_names(
                raw,
                "shape",
                o["shape"],
                tuple(sorted(shapes)),
                what,
                " (built-in or in `templates:`)",
            )
        if b.gesture in ("force", "slide"):
            self._check_names(raw, "phase", o["phase"], PHASES, what)

    @staticmethod
    def _check_names(
        raw: MarkedDict,
        key: str,
        names: tuple[str, ...] | None,
        allowed: tuple[str, ...],
        what: str,
        note: str = "",
    ) -> None:
        for name in names or ():
            if name not in allowed:
                raise ConfigError(
                    raw.where(key),
                    f"unknown {key} {name!r} in {what}; allowed{note}: {', '.join(allowed)}",
                )

    def _check_overlaps(self, bindings: list[Binding], regions: dict[str, Region]) -> None:
        by_gesture: dict[str, list[Binding]] = {}
        for b in bindings:
            if b.region is not None and all(
                o.region != b.region for o in by_gesture.get(b.gesture, [])
            ):
                by_gesture.setdefault(b.gesture, []).append(b)
        for gesture, bs in by_gesture.items():
            for j, later in enumerate(bs):
                for earlier in bs[:j]:
                    assert later.region is not None and earlier.region is not None
                    if regions_overlap(regions[earlier.region], regions[later.region]):
                        raw = self.doc["bindings"][later.index]
                        raise ConfigError(
                            raw.where("region"),
                            f"regions `{earlier.region}` and `{later.region}` overlap and "
                            "both bind "
                            f"`{gesture}` (binding {earlier.index + 1} and {later.index + 1}); a "
                            "touch in the overlap would be ambiguous: move them apart",
                        )


def _region_text(region: str | None) -> str:
    return f"region `{region}`" if region is not None else "anywhere"


def _is_point_list(value: Any) -> bool:
    return (
        isinstance(value, list)
        and len(value) > 0
        and all(
            isinstance(p, list) and len(p) == 2 and all(isinstance(v, int | float) for v in p)
            for p in value
        )
    )


def _read_at(path: Path, where: Position) -> np.ndarray:
    try:
        return read_stroke(path)
    except ConfigError as err:
        raise ConfigError(where, f"template {err}") from None


def builtin_shape_names() -> set[str]:
    """Names of the shipped stroke templates (the file names under templates/)."""
    from importlib import resources

    root = resources.files("hapticdesk.gestures.strokes").joinpath("templates")
    if not root.is_dir():
        return set()
    return {Path(str(p)).stem for p in root.iterdir() if str(p).endswith(".json")}
