"""The gesture events a binding can make, to check its actions before anything runs.

``check`` (and every load of a layout: ``run``, a reload, the browser UI's save) hands each
action use these events (:meth:`Registry.check_action_events`), so an action can try its
options on everything its binding will give it: a template that is cheap for the sample
event but blows up for ``region == 'b5'``, a ``value`` of 1 or a press's ``hard`` level is
refused at its place instead of at the first such touch.

The events are a base event of the binding's gesture in its region, and, one field at a time,
each value that field can take for that gesture (its phases, levels, directions, shapes, the
region's corners, forces from none to a kilonewton). Fields the gesture never carries stay
None, as they will at run time. A plugin's gesture, whose fields are not known here, gets
every field varied.
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np

from hapticdesk.gestures.event import GestureEvent
from hapticdesk.runtime.isolation import split_isolation

if TYPE_CHECKING:
    from hapticdesk.gestures.layout import Layout
    from hapticdesk.registry import Registry

#: what each built-in gesture's events carry (besides t, gesture, region, x, y)
GESTURE_FIELDS: dict[str, tuple[str, ...]] = {
    "tap": ("force_n",),
    "double_tap": ("force_n",),
    "two_finger_tap": ("force_n",),
    "long_press": ("phase", "hold_s", "force_n"),
    "press": ("level", "force_n"),
    "force": ("value", "phase", "force_n"),
    "slide": ("value", "phase"),
    "swipe": ("direction",),
    "stroke": ("shape", "score"),
}
#: the phases each continuous gesture's events carry (None: none given)
GESTURE_PHASES: dict[str, tuple[str | None, ...]] = {
    "long_press": (None, "end", "cancel", "repeat"),
    "force": ("begin", "update", "end", "cancel"),
    "slide": ("begin", "update", "end", "cancel"),
}
_ALL_FIELDS = ("shape", "score", "direction", "value", "level", "phase", "hold_s", "force_n")
_DIRECTIONS = (
    "right", "up_right", "up", "up_left", "left", "down_left", "down", "down_right",
)  # fmt: skip
_EXTRAS: dict[str, dict[str, Any]] = {
    "two_finger_tap": {"x2": 0.0, "y2": 0.0},
    "swipe": {"distance": 0.1},
    "long_press": {"duration_s": 1.0},
}


def possible_events(binding: Any, layout: Any) -> list[GestureEvent]:
    """Events ``binding`` (of ``layout``) can make: a base event and, one field at a time,
    every value the field takes for its gesture (see the module docstring)."""
    gesture = binding.gesture
    carried = GESTURE_FIELDS.get(gesture, _ALL_FIELDS)
    regions = [binding.region] if binding.region is not None else [*layout.regions, None]
    choices = _field_values(binding, layout, gesture)
    base_fields = {name: choices[name][0] for name in carried}
    events: list[GestureEvent] = []
    for region in regions[:16]:
        for x, y in _places(layout, region):
            events.append(
                GestureEvent(
                    0.0, gesture, region, x, y, extra=dict(_EXTRAS.get(gesture, {})), **base_fields
                )
            )
    base = events[0]
    events.append(replace(base, t=86_400.0))
    for name in carried:
        for value in choices[name][1:]:
            events.append(replace(base, **{name: value}))
    return events


def _field_values(binding: Any, layout: Any, gesture: str) -> dict[str, list[Any]]:
    """Each field's values for this binding, the first its base value."""
    options = binding.options or {}
    levels = options.get("levels") or {}
    level_names = list(levels) if isinstance(levels, dict) else []
    wanted = options.get("level")
    if isinstance(wanted, str):
        level_names = [wanted, *level_names]
    shapes = options.get("shape")
    shape_names = list(shapes) if isinstance(shapes, list | tuple) else [shapes] if shapes else []
    shape_names += [*getattr(layout, "templates", {})] or ["circle"]
    holds = options.get("hold_s")
    hold_values = list(holds) if isinstance(holds, list | tuple) else [holds] if holds else []
    directions = options.get("direction")
    wanted_directions = (
        list(directions)
        if isinstance(directions, list | tuple)
        else [directions]
        if directions
        else []
    )
    phases = GESTURE_PHASES.get(gesture, (None, "begin", "update", "end", "cancel", "repeat"))
    return {
        "value": [0.5, 0.0, 1.0],
        "force_n": [5.0, 0.0, 2.0, 1000.0],
        "phase": list(phases),
        "level": [*level_names, "light"][:17],
        "direction": [*wanted_directions, *_DIRECTIONS],
        "shape": shape_names[:17],
        "score": [0.9, 0.0, 1.0],
        "hold_s": [*(float(h) for h in hold_values), 0.5, 60.0][:17],
    }


def _places(layout: Any, region: str | None) -> list[tuple[float, float]]:
    """A region's centre and the corners of its outline's bounding box (the desk's top
    surface for an event outside every region)."""
    shape = layout.regions.get(region) if region is not None else None
    if shape is not None:
        outline = np.asarray(shape.outline, dtype=float)
    elif layout.desk.surfaces:
        outline = np.asarray(layout.desk.surfaces[0].polygon, dtype=float)
    else:
        return [(0.0, 0.0)]
    if outline.ndim != 2 or len(outline) == 0:
        return [(0.0, 0.0)]
    low, high = outline.min(axis=0), outline.max(axis=0)
    centre = (low + high) / 2
    return [
        (float(centre[0]), float(centre[1])),
        (float(low[0]), float(low[1])),
        (float(high[0]), float(high[1])),
    ]


def check_bindings(layout: Layout, registry: Registry) -> None:
    """Hand every action use of ``layout`` the events its binding can make
    (:meth:`Registry.check_action_events`, with the action's own options: the isolation keys
    are the runtime's); ConfigError at the first use that refuses."""
    for binding in layout.bindings:
        uses = [use for use in binding.actions if use.name in registry.actions]
        if not uses:
            continue
        events = possible_events(binding, layout)
        for use in uses:
            own, _ = split_isolation(use.options, use.position)
            registry.check_action_events(use.name, own, use.position, events, layout.desk_name)
