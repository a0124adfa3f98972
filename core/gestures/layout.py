"""Layouts: which parts of the desk are buttons, sliders and drawing areas, and what each
gesture there does (docs/reference/layout.md).

This module is the model: :class:`Layout`, its :class:`Binding` and :class:`ActionUse`
records; it reads no file. Loading (``layout_reader.load_layout``, the one entry point, with
``layout_regions`` and ``layout_templates``) reads and validates the YAML and reports every
mistake as ``file:line:column``, what was found and what is allowed.

``desk_name:`` is the desk's name in what actions send (``{desk}`` in templates, MQTT
topics). Any other top-level section belongs to the plugin that claimed it
(``register_layout_sections``): it is kept raw in :attr:`Layout.raw` and handed to that
plugin's validator while loading, so ``check`` refuses what ``run`` would.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hapticdesk.errors import Position
from hapticdesk.files.marked_values import MarkedDict
from hapticdesk.files.profile import DeskProfile
from hapticdesk.gestures.event import GestureEvent
from hapticdesk.gestures.options import GESTURE_OPTIONS, defaults
from hapticdesk.gestures.regions import Region

#: length units a layout may be written in, in metres
UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001}
#: the folder beside the layout that `hapticdesk strokes record` fills by default
DEFAULT_TEMPLATE_DIR = "strokes"


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
            # the tier itself (no phase), its repeats when asked for; never end or cancel
            phases = (None, "repeat") if o.get("repeat") else (None,)
            return event.phase in phases and abs(hold - o["hold_s"]) < 1e-9
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

    @property
    def desk_name(self) -> str:
        """The desk's name in what actions send: ``desk_name:``, else the profile's name with
        anything but letters, digits, _ and - replaced by _."""
        name = self.raw.get("desk_name")
        if isinstance(name, str):
            return name
        return re.sub(r"[^A-Za-z0-9_-]", "_", self.desk.name)

    @property
    def named_layouts(self) -> dict[str, Path]:
        """``layouts:``: name -> layout file a running desk can switch to (checked on load)."""
        value = self.raw.get("layouts")
        if not isinstance(value, dict):
            return {}
        return {
            str(name): (self.path.parent / Path(str(file)).expanduser())
            for name, file in value.items()
        }

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


def builtin_shape_names() -> set[str]:
    """Names of the shipped stroke templates (the file names under templates/)."""
    from importlib import resources

    root = resources.files("hapticdesk.gestures.strokes").joinpath("templates")
    if not root.is_dir():
        return set()
    return {Path(str(p)).stem for p in root.iterdir() if str(p).endswith(".json")}
