"""A layout's ``bindings:`` read and checked: each binding's gesture, region, options and
actions (``do:``), the recognizer settings of each (gesture, region) resolved from the
layout-wide ``settings:`` and the bindings' own, names (levels, directions, shapes, phases)
checked, and regions that bind the same gesture refused where they overlap. Part of
``layout_reader``."""

from __future__ import annotations

import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any, NamedTuple

from hapticdesk.errors import ConfigError, LayoutWarning, Position
from hapticdesk.files.marked_values import MarkedDict, MarkedList
from hapticdesk.files.validators import check_keys, choice, require_mapping
from hapticdesk.gestures.layout import ActionUse, Binding
from hapticdesk.gestures.options import (
    ANYWHERE_GESTURES,
    DIRECTIONS_4,
    DIRECTIONS_8,
    GESTURE_OPTIONS,
    PHASES,
    OptionSpec,
    read_option,
)
from hapticdesk.gestures.regions import Region, regions_overlap

BINDING_KEYS = frozenset({"gesture", "region", "do", "description"})

#: ``validate_action(name, options, position)``: raises ConfigError when the options are wrong
ValidateAction = Callable[[str, Any, Position], None]
#: (gesture, region) -> option -> (value, where, binding index), set explicitly on a binding
Explicit = dict[tuple[str, str | None], dict[str, tuple[Any, Position, int]]]


class ReadBindings(NamedTuple):
    """The bindings, their options resolved, and the recognizer settings per (gesture,
    region)."""

    bindings: list[Binding]
    region_options: dict[tuple[str, str | None], dict[str, Any]]


class BindingReader:
    """The ``bindings:`` of one layout (module docstring); each step raises ConfigError at
    the offending spot, layout warnings go to ``warnings``."""

    def __init__(
        self,
        doc: MarkedDict,
        path: Path,
        specs: dict[str, dict[str, OptionSpec] | None],
        scale: float,
        action_names: set[str] | None,
        validate_action: ValidateAction | None,
        warnings: list[str],
    ) -> None:
        self.doc = doc
        self.path = path
        self.specs = specs
        self.scale = scale
        self.action_names = action_names
        self.validate_action = validate_action
        self.warnings = warnings

    def read(
        self,
        regions: dict[str, Region],
        settings: dict[str, dict[str, Any]],
        shapes: set[str],
    ) -> ReadBindings:
        """The bindings over ``regions``, with ``settings`` (layout-wide, per gesture) and
        the stroke ``shapes`` known."""
        bindings, explicit = self._bindings(regions)
        region_options = self._resolve(bindings, explicit, settings)
        for b in bindings:
            self._check_binding(b, shapes)
        self._check_overlaps(bindings, regions)
        return ReadBindings(bindings, region_options)

    def _bindings(self, regions: dict[str, Region]) -> tuple[list[Binding], Explicit]:
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
        explicit: Explicit = {}
        bindings = [self._binding(i, raw, regions, explicit) for i in range(len(raw))]
        return bindings, explicit

    def _binding(
        self, i: int, raw: MarkedList, regions: dict[str, Region], explicit: Explicit
    ) -> Binding:
        """Binding ``i`` of ``raw``; the recognizer options it sets go into ``explicit``."""
        what = f"binding {i + 1}"
        m = require_mapping(raw[i], raw.where(i), what)
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
        options = self._options(i, m, gesture, region, what, explicit)
        actions = self._actions(m, what)
        return Binding(i, gesture, region, options, actions, m.where())

    def _options(
        self,
        i: int,
        m: MarkedDict,
        gesture: str,
        region: str | None,
        what: str,
        explicit: Explicit,
    ) -> dict[str, Any]:
        """The options binding ``i`` sets; one recognizer judges a (gesture, region), so the
        settings two bindings of it give must agree."""
        spec = self.specs[gesture]
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
        return options

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
        explicit: Explicit,
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
