"""Reading and validating a layout's YAML into the model of ``layout.py``.

Loading validates everything a person can get wrong and reports ``file:line:column``, what
was found and what is allowed: unknown keys, unknown region, gesture, action or shape names,
values out of range, overlapping regions that bind the same gesture, a region off the desk.
Gesture settings resolve at three levels (options.py): built-in, layout-wide ``settings:``,
binding. Regions are read by ``layout_regions``, stroke templates by ``layout_templates``.
"""

from __future__ import annotations

import re
import warnings
from collections.abc import Collection, Mapping
from pathlib import Path
from typing import Any

from hapticdesk.files.profile import DeskProfile, load_profile
from hapticdesk.files.yamlfile import (
    ConfigError,
    LayoutWarning,
    MarkedDict,
    MarkedList,
    Position,
    as_flag,
    check_confined,
    check_keys,
    choice,
    require_mapping,
)
from hapticdesk.gestures.layout import (
    UNITS,
    ActionUse,
    Binding,
    Layout,
    ValidateAction,
    builtin_shape_names,
)
from hapticdesk.gestures.layout_regions import RegionReader
from hapticdesk.gestures.layout_templates import TemplateReader
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
from hapticdesk.gestures.regions import Region, regions_overlap

#: the layout's own top-level keys
LAYOUT_KEYS = frozenset(
    {
        "desk",
        "desk_name",
        "units",
        "regions",
        "bindings",
        "settings",
        "templates",
        "description",
        "layouts",
    }
    | {"builtin_templates"}
)
#: a desk name goes into topics, URLs and file names: no spaces, slashes or wildcards
DESK_NAME = re.compile(r"[A-Za-z0-9_-]+")
BINDING_KEYS = frozenset({"gesture", "region", "do", "description"})


def allowed_top_keys(plugin_sections: Collection[str] = ()) -> frozenset[str]:
    """Every key a layout may have at its top level (the one place that decides it): its own
    and the sections plugins claimed (``register_layout_sections``)."""
    return LAYOUT_KEYS | frozenset(plugin_sections)


class LayoutReader:
    """The validation, step by step; each step raises ConfigError at the offending spot."""

    def __init__(
        self,
        doc: MarkedDict,
        path: Path,
        profile: DeskProfile | None,
        action_names: Collection[str] | None,
        validate_action: ValidateAction | None,
        recognizer_types: Mapping[str, Any] | None,
        plugin_sections: Collection[str] = (),
    ) -> None:
        self.doc = doc
        self.path = path
        self.profile = profile
        self.action_names = set(action_names) if action_names is not None else None
        self.validate_action = validate_action
        # the gestures a recognizer is installed for (all the built-ins when none are given):
        # a layout binding a gesture whose plugin is blocked or missing is refused here, at
        # its place, as `run` would refuse it
        self.specs: dict[str, dict[str, OptionSpec] | None] = (
            dict(GESTURE_OPTIONS)
            if recognizer_types is None
            else {g: spec for g, spec in GESTURE_OPTIONS.items() if g in recognizer_types}
        )
        #: sections plugins claimed (a plugin cannot take over a layout's own key)
        self.sections = frozenset(plugin_sections) - LAYOUT_KEYS
        for name, entry in (recognizer_types or {}).items():
            if name in GESTURE_OPTIONS:
                continue  # a built-in gesture: its options are its contract
            load = getattr(entry, "load", None)
            if callable(load):
                cls = load()
            else:
                from hapticdesk.registry import resolve

                cls = resolve(entry)
            self.specs[name] = getattr(cls, "option_specs", None)
        self.scale = 1.0
        self.units = "m"
        self.warnings: list[str] = []

    # -- top level ---------------------------------------------------------------------------
    def read(self) -> Layout:
        doc = self.doc
        check_keys(doc, allowed_top_keys(self.sections), "the layout")
        self._desk_name()
        self._named_layouts()
        desk = self._desk()
        self.units = choice(doc, "units", tuple(UNITS), "the layout", default="m")
        self.scale = UNITS[self.units]
        regions = (
            RegionReader(desk, self.scale, self.units, self.warnings).read(
                doc["regions"], doc.where("regions")
            )
            if "regions" in doc
            else {}
        )
        settings = self._settings()
        templates = (
            TemplateReader(self.path.parent, self.scale).read(
                doc["templates"], doc.where("templates")
            )
            if "templates" in doc
            else {}
        )
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

    def _builtin_templates(self, has_user_templates: bool) -> bool:
        """`builtin_templates: false` leaves only the layout's own templates."""
        value = as_flag(self.doc.get("builtin_templates", True))
        where = self.doc.where("builtin_templates")
        if not isinstance(value, bool):
            raise ConfigError(where, f"`builtin_templates` is true or false, found {value!r}")
        if not value and not has_user_templates:
            raise ConfigError(where, "`builtin_templates: false` needs shapes under `templates:`")
        return value

    def _named_layouts(self) -> None:
        """``layouts: {evening: evening.yaml}``: the layouts a running desk can switch to
        (``{"layout": "evening"}`` on its control channel); files relative to this one."""
        if "layouts" not in self.doc:
            return
        m = require_mapping(self.doc["layouts"], self.doc.where("layouts"), "`layouts`")
        for name, value in m.items():
            if not isinstance(name, str) or not DESK_NAME.fullmatch(name):
                raise ConfigError(
                    m.where(name, of_key=True),
                    f"a name in `layouts` must be letters, digits, _ and -, found {name!r}",
                )
            if name == "default":
                raise ConfigError(
                    m.where(name, of_key=True),
                    "`default` is the layout the run started with; choose another name",
                )
            if not isinstance(value, str) or not value:
                raise ConfigError(
                    m.where(name), f"`layouts.{name}` must be a layout file path, found {value!r}"
                )
            path = Path(value).expanduser()
            if not path.is_absolute():
                path = self.path.parent / path
            check_confined(path, f"`layouts.{name}`", m.where(name))  # (before it is looked at)
            if not path.is_file():
                raise ConfigError(m.where(name), f"`layouts.{name}`: no such file {path}")

    def _desk_name(self) -> None:
        if "desk_name" not in self.doc:
            return
        name = self.doc["desk_name"]
        if not isinstance(name, str) or not DESK_NAME.fullmatch(name):
            raise ConfigError(
                self.doc.where("desk_name"),
                "`desk_name` must be letters, digits, _ and - (it goes into topics and "
                f"messages), found {name!r}",
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

    # -- bindings ----------------------------------------------------------------------------
    def _bindings(
        self, regions: dict[str, Region]
    ) -> tuple[list[Binding], dict[tuple[str, str | None], dict[str, tuple[Any, Position, int]]]]:
        raw = self.doc.get("bindings", MarkedList())
        if not isinstance(raw, MarkedList):
            raise ConfigError(
                self.doc.where("bindings"),
                f"`bindings` must be a list of bindings (`[]` for none yet), found {raw!r}",
            )
        if not raw:  # a layout being made (`hapticdesk init --blank`): it runs, doing nothing
            self.warnings.append(
                f"{self.doc.where('bindings')}: no bindings yet: no gesture does anything; "
                "bind one, e.g. in the browser: hapticdesk ui --layout "
                f"{self.path.name}"
            )
        bindings = []
        # (gesture, region) -> option -> (value, where, binding index) set explicitly on a binding
        explicit: dict[tuple[str, str | None], dict[str, tuple[Any, Position, int]]] = {}
        for i, item in enumerate(raw):
            what = f"binding {i + 1}"
            m = require_mapping(item, raw.where(i), what)
            named = m.get("gesture")
            if isinstance(named, str) and named in GESTURE_OPTIONS and named not in self.specs:
                raise ConfigError(
                    m.where("gesture"),
                    f"no recognizer for gesture `{named}` is installed (is its plugin "
                    "missing, or blocked by HAPTICDESK_BLOCK_PLUGINS?); installed: "
                    f"{', '.join(sorted(self.specs)) or 'none'}",
                )
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
        if not isinstance(region, str):
            raise ConfigError(
                m.where("region"),
                f"`region` of {what} is one region's name (one of: {names}), found {region!r}",
            )
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
                # a plugin's check may warn (warnings.warn(LayoutWarning)): a layout warning
                with warnings.catch_warnings(record=True) as said:
                    warnings.simplefilter("always", LayoutWarning)
                    self.validate_action(use.name, use.options, use.position)
                for w in said:
                    if issubclass(w.category, LayoutWarning):
                        self.warnings.append(str(w.message))
                    else:  # (any other warning goes on as it came)
                        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
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
