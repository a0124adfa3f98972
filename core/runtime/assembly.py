"""What a run is made of: a layout, a desk and a source spec built into an :class:`Assembly`
(source, estimator, gesture engine, dispatcher with its routes), importing only what the
layout uses (no paho without MQTT, no python-can without a CAN source). Everything
plugin-specific (the desk's MQTT topics, a layout's ``mqtt:`` section) comes through the
registry's hooks; this module names no plugin. :mod:`.service` runs it.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hapticdesk.errors import ConfigError
from hapticdesk.files.profile import DeskProfile
from hapticdesk.files.profile_reader import load_profile
from hapticdesk.registry import Registry
from hapticdesk.runtime.binding_events import check_bindings
from hapticdesk.runtime.control import ControlQueue
from hapticdesk.runtime.dispatcher import ActionContext, Dispatcher, Route
from hapticdesk.runtime.isolation import ProcessAction, action_use_validator, split_isolation
from hapticdesk.runtime.lane import Lane
from hapticdesk.runtime.observe import ContactObservers
from hapticdesk.runtime.source import Source
from hapticdesk.runtime.source_spec import open_source

log = logging.getLogger(__name__)


@dataclass
class Assembly:
    """Everything a run is made of, built and checked, nothing started but the actions.

    Called an assembly (not a scene) because a *scene* is the simulator's script of what a
    person does on the desk (:mod:`hapticdesk.sim.scene`); this is the desk profile, the
    layout and the parts built from them for one run.
    """

    profile: DeskProfile
    layout: Any  # hapticdesk.gestures.layout.Layout
    registry: Registry
    source: Source
    estimator: Any  # hapticdesk.estimator.ContactEstimator
    engine: Any  # hapticdesk.gestures.GestureEngine
    dispatcher: Dispatcher
    context: ActionContext
    #: the layout file the run started with (``default`` among its named layouts)
    layout_path: Path | None = None
    # ``--desk`` (or a C3D replay's plate): a reloaded layout is read with it too
    desk_override: str | DeskProfile | None = None
    action_timeout_s: float | None = None
    #: commands for the running desk (re-tare, pause, reload …), applied between blocks
    control: ControlQueue = field(default_factory=ControlQueue)
    actions: bool = True  # False: gestures are recognised, the layout's actions not run
    #: plugins' contact sinks (``contact_sink`` hook), called once per block
    observers: ContactObservers = field(default_factory=lambda: ContactObservers([]))

    def close(self) -> None:
        """Release what was built without running."""
        _release(self.source, self.dispatcher, self.context)


def _release(source: Source, dispatcher: Dispatcher, context: ActionContext) -> None:
    source.close()
    dispatcher.close(0.0)
    context.close_resources(0.0)


#: the former name of :class:`Assembly`
Scene = Assembly


def load_scene_layout(
    layout_path: str | Path,
    registry: Registry,
    desk: str | DeskProfile | None = None,
    *,
    text: str | None = None,
) -> tuple[Any, DeskProfile]:
    """The layout, validated against the installed actions, recognizers and the sections
    plugins claim, each action use checked against the events its binding can make
    (``hapticdesk check`` and ``run`` both load through here), and its desk.
    ``text``: the layout's YAML when it is not the file's (an edit checked before saving)."""
    from hapticdesk.gestures.layout_reader import load_layout

    profile = load_profile(desk) if isinstance(desk, str) else desk
    layout = load_layout(
        layout_path,
        profile=profile,
        action_names=registry.action_names,
        validate_action=action_use_validator(registry),
        recognizer_types=registry.recognizer_types(),
        validate_section=registry.validate_section,
        section_names=list(registry.layout_sections),
        text=text,
    )
    # each action tried on every event its binding can make (a template too costly for a
    # tap on one region, which the sample event never rendered, is refused here, not at run)
    check_bindings(layout, registry)
    return layout, layout.desk


def load_switch_layout(
    path: str | Path,
    registry: Registry,
    desk: str | DeskProfile | None,
    running: DeskProfile,
    desk_name: str,
) -> tuple[Any, DeskProfile]:
    """The layout at ``path`` loaded as a running desk takes it over (a reload, a switch to
    one of its ``layouts:``): loaded as :func:`load_scene_layout` does, with the run's
    ``desk`` override, and refused when it is for another desk than ``running`` or names
    another ``desk_name`` (the estimator, topics and identity are the run's)."""
    layout, profile = load_scene_layout(path, registry, desk)
    if desk_key(profile) != desk_key(running):
        raise ConfigError(
            str(path),
            f"the layout is for desk `{profile.name}` but this run senses desk "
            f"`{running.name}`; a new desk needs a restart",
        )
    if layout.desk_name != desk_name:
        raise ConfigError(
            str(path),
            f"the layout names the desk `{layout.desk_name}` but this run is "
            f"`{desk_name}` (its topics and identity); a new name needs a restart",
        )
    return layout, profile


def desk_key(profile: DeskProfile) -> tuple[Any, ...]:
    """What makes two profiles the same desk for a running estimator."""
    return (profile.name, profile.sample_rate_hz, tuple(s.name for s in profile.sensors))


def check_named_layouts(layout: Any, registry: Registry, desk: str | DeskProfile | None) -> None:
    """Each layout ``layout`` names under ``layouts:``, loaded as the running desk would load
    it when switched to (:func:`load_switch_layout`); a ConfigError at its name in
    ``layouts:`` that quotes the named file's own error. The reader checks only that the
    files exist, so `check` said OK and `run` started with a named layout a switch then
    refused, hours later, over MQTT."""
    for name, path in layout.named_layouts.items():
        try:
            load_switch_layout(path, registry, desk, layout.desk, layout.desk_name)
        except ConfigError as err:
            raise ConfigError(
                layout.raw["layouts"].where(name),
                f"`layouts.{name}` would be refused when the desk switches to it: {err}",
            ) from None


def build_scene(
    layout_path: str | Path,
    source_spec: str,
    registry: Registry,
    *,
    desk: str | DeskProfile | None = None,
    speed: float = 1.0,
    overrides: Mapping[str, Mapping[str, Any]] | None = None,
    action_timeout_s: float | None = None,
    actions: bool = True,
) -> Assembly:
    """Load the layout and desk, open the source, build every action and every plugin's event
    sink (ConfigError if wrong). ``overrides``: command-line values over a plugin's layout
    section, by section name (``run --mqtt URL`` gives ``{"mqtt": {"broker": URL}}``).
    ``actions=False`` recognises gestures without running the layout's actions or plugins'
    event sinks (a preview: nothing leaves the machine; the caller may add its own sink)."""
    layout, profile = load_scene_layout(layout_path, registry, desk)
    check_named_layouts(layout, registry, desk)  # (at the start, as `check` does)
    for warning in layout.warnings:
        log.warning("%s", warning)
    source = open_source(source_spec, profile, registry, speed=speed)
    context = ActionContext(
        layout.desk_name,
        layout_path=Path(layout_path),
        settings=layout.raw,
        overrides=overrides,
        profile=profile,
        layout=layout,
    )
    dispatcher = Dispatcher()
    try:
        observers = ContactObservers([])
        if actions:  # a preview (actions=False) sends nothing: no actions, no plugins' sinks
            observers = _wire_actions(
                dispatcher, profile, layout, registry, context, action_timeout_s
            )
        estimator, engine = _estimator_and_engine(profile, layout, registry)
    except BaseException:
        _release(source, dispatcher, context)
        raise
    return Assembly(
        profile,
        layout,
        registry,
        source,
        estimator,
        engine,
        dispatcher,
        context,
        layout_path=Path(layout_path),
        desk_override=desk,
        action_timeout_s=action_timeout_s,
        actions=actions,
        observers=observers,
    )


def _estimator_and_engine(desk: DeskProfile, layout: Any, registry: Registry) -> tuple[Any, Any]:
    """The desk's contact estimator and the layout's gesture engine (the estimator tracks a
    second finger when the desk or a bound gesture needs one)."""
    from hapticdesk.estimator import ContactEstimator  # (numba and the recognizers: a run only)
    from hapticdesk.gestures.engine import GestureEngine

    estimator = ContactEstimator(desk)
    engine = GestureEngine(
        layout,
        recognizer_types=registry.recognizer_types(),
        position_delay_s=estimator.position_delay_s,
    )
    estimator.use_second_finger(desk.estimation.second_finger or engine.needs_second_finger)
    return estimator, engine


def _wire_actions(
    dispatcher: Dispatcher,
    desk: DeskProfile,
    layout: Any,
    registry: Registry,
    context: ActionContext,
    action_timeout_s: float | None,
) -> ContactObservers:
    """The layout's actions and every plugin's event sink into ``dispatcher``; the plugins'
    contact sinks returned."""
    for route in build_routes(layout, registry, context, action_timeout_s):
        dispatcher.add_route(route)
    for plugin, sink in registry.event_sinks(desk=desk, layout=layout, context=context):
        dispatcher.add_sink(Lane(f"every event → {plugin}", sink, timeout_s=action_timeout_s))
    return ContactObservers(registry.contact_sinks(desk=desk, layout=layout, context=context))


def build_routes(
    layout: Any, registry: Registry, context: ActionContext, timeout_s: float | None
) -> list[Route]:
    """A route (with its actions' lanes, started) for each binding of ``layout``; when one
    action cannot be built, the lanes built so far are closed and the ConfigError raised."""
    routes: list[Route] = []
    try:
        _add_routes(routes, layout, registry, context, timeout_s)
    except BaseException:
        for route in routes:
            for lane in route.lanes:
                lane.close(0.0)
        raise
    return routes


def _add_routes(
    routes: list[Route],
    layout: Any,
    registry: Registry,
    context: ActionContext,
    timeout_s: float | None,
) -> None:
    for binding in layout.bindings:
        where = f" in {binding.region}" if binding.region else ""
        label = f"binding {binding.index + 1} ({binding.gesture}{where})"
        route = Route(label, binding.matches)
        routes.append(route)
        names = [use.name for use in binding.actions]
        for k, use in enumerate(binding.actions):
            lane = f"{label} → {use.name}" + (f" #{k + 1}" if names.count(use.name) > 1 else "")
            factory = registry.action(use.name, use.position).load()
            options, isolation = split_isolation(use.options, use.position)
            try:
                if isolation is None:
                    action = factory(options, context)
                else:  # `isolation: process`: built and called in a child process
                    action = ProcessAction(
                        lane,
                        registry.actions[use.name].factory,
                        options,
                        desk=context.desk_name,
                        layout_path=context.layout_path,
                        settings=context.settings,
                        isolation=isolation,
                    )
            except ConfigError:
                raise
            except Exception as err:  # a plugin failing to build its action
                raise ConfigError(
                    use.position,
                    f"action `{use.name}` (plugin `{registry.actions[use.name].plugin}`) could "
                    f"not be set up: {type(err).__name__}: {err}",
                ) from err
            route.lanes.append(Lane(lane, action, timeout_s=timeout_s))


# --- the run ----------------------------------------------------------------------------------
