"""Loading a layout: its YAML read and validated into the model of ``layout.py``
(:func:`load_layout`; the model imports no reader).

Loading validates everything a person can get wrong and reports ``file:line:column``, what
was found and what is allowed: unknown keys, unknown region, gesture, action or shape names,
values out of range, overlapping regions that bind the same gesture, a region off the desk.
Gesture settings resolve at three levels (options.py): built-in, layout-wide ``settings:``,
binding. Regions are read by ``layout_regions``, stroke templates by ``layout_templates``,
bindings by ``layout_bindings``.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Collection, Mapping
from pathlib import Path
from typing import Any

from hapticdesk.errors import ConfigError, Position
from hapticdesk.files.file_safety import check_confined
from hapticdesk.files.marked_values import MarkedDict, as_flag
from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.profile_reader import load_profile
from hapticdesk.files.validators import check_keys, choice, require_mapping
from hapticdesk.files.yamlfile import load_marked_yaml
from hapticdesk.gestures.layout import UNITS, Layout, builtin_shape_names
from hapticdesk.gestures.layout_bindings import BindingReader, ValidateAction
from hapticdesk.gestures.layout_regions import RegionReader
from hapticdesk.gestures.layout_templates import TemplateReader
from hapticdesk.gestures.options import (
    GESTURE_OPTIONS,
    OptionSpec,
    defaults,
    read_option,
)

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

#: ``validate_section(name, value, position, layout_path)``: a plugin's section
ValidateSection = Callable[[str, Any, Position, Path], None]


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
                from hapticdesk.lazy_ref import resolve

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
        shapes = (builtin_shape_names() if builtin else set()) | set(templates)
        bindings, region_options = BindingReader(
            self.doc,
            self.path,
            self.specs,
            self.scale,
            self.action_names,
            self.validate_action,
            self.warnings,
        ).read(regions, settings, shapes)
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


def load_layout(
    path: str | Path,
    profile: DeskProfile | None = None,
    action_names: Collection[str] | None = None,
    validate_action: ValidateAction | None = None,
    recognizer_types: Mapping[str, Any] | None = None,
    validate_section: ValidateSection | None = None,
    section_names: Collection[str] = (),
    text: str | None = None,
) -> Layout:
    """Load and validate a layout; raises :class:`ConfigError` on any problem.

    ``text``: the layout's YAML when it is not (yet) in the file, e.g. an edit being checked
    before it is saved; errors and relative paths still name ``path``.

    ``profile`` overrides the layout's ``desk:``. ``action_names``: the known actions (an
    unknown one is an error); ``validate_action(name, options, position)`` is called for
    every action use and may raise ConfigError. ``recognizer_types``: plugin gestures (name
    -> recognizer class, registry record or ``"module:Class"``, whose optional
    ``option_specs`` describe its options; a built-in gesture's options are its own whichever
    class recognizes it, so built-ins are not imported here). ``section_names``: top-level
    sections plugins claimed; each one present goes to ``validate_section``.
    """
    path = Path(path)
    doc = require_mapping(load_marked_yaml(path, text), str(path), "a layout")
    reader = LayoutReader(
        doc, path, profile, action_names, validate_action, recognizer_types, section_names
    )
    layout = reader.read()
    if validate_section is not None:
        for name in sorted(reader.sections & set(doc)):
            validate_section(name, doc[name], doc.where(name), path)
    return layout
