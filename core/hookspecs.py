"""The hooks a hapticdesk plugin can implement.

A plugin is a module (or any object) with functions marked ``@hookimpl``. Built-in plugins
(:data:`~hapticdesk.registry.DEFAULT_PLUGINS`) and third-party ones (the ``hapticdesk``
entry-point group) use the same hooks. A hookimpl may take fewer arguments than its spec, so
specs can grow without breaking plugins::

    from hapticdesk.hookspecs import hookimpl

    @hookimpl
    def register_actions(register):
        register("beep", Beep, "ring the terminal bell", validate=check_beep_options)

Registration hooks receive a ``register(...)`` callback and run once when the registry is
built (:func:`hapticdesk.registry.load_registry`). Observer hooks run once per ``run``; none
is called on the per-sample or per-gesture path (pluggy stops at the first exception there,
so the dispatcher calls actions itself, each in its own ``try``).
"""

from __future__ import annotations

from typing import Any

import pluggy

hookspec = pluggy.HookspecMarker("hapticdesk")
hookimpl = pluggy.HookimplMarker("hapticdesk")


@hookspec
def register_sources(register: Any) -> None:
    """Register source kinds, the ``KIND`` of ``--source KIND:ARGUMENT``.

    Called once while the registry is built, with ``register`` the callback to call as
    ``register(name, factory, description="")`` for each kind, where ``factory`` is a callable
    or a lazy ``"module:attr"`` string (imported only when a run uses that kind) and is called
    as ``factory(argument, profile, **options) -> hapticdesk.runtime.source.Source`` with
    ``argument`` the text after ``KIND:``, ``profile`` the
    :class:`~hapticdesk.files.profile.DeskProfile`, and ``options`` keyword options the
    factory may ignore (``speed``: replay speed, 1 = real time, 0 = as fast as possible). Bad
    arguments raise :class:`~hapticdesk.files.yamlfile.ConfigError`.
    """


@hookspec
def register_actions(register: Any) -> None:
    """Register actions, the keys under a binding's ``do:`` in a layout.

    Called once while the registry is built, with ``register`` the callback to call as
    ``register(name, factory, description="", validate=None, options=None)`` for each action:

    - ``factory(options, context) -> action``: ``options`` the action's mapping from the
      layout, ``context`` an :class:`~hapticdesk.runtime.dispatcher.ActionContext`. The action is a
      callable taking one :class:`~hapticdesk.gestures.event.GestureEvent`; it may have a
      ``close()`` method (called once at the end) and a ``timeout_s`` attribute (how long one
      call may take before the dispatcher gives up on it).
    - ``validate(options, position)``: raise :class:`~hapticdesk.files.yamlfile.ConfigError` naming
      ``file:line:column`` when the options are wrong, so ``hapticdesk check`` and ``run`` stop
      before anything starts. ``position`` is where the action stands in the layout.

    - ``options``: a form's schema of the options, ``{name: {"kind": "text" | "number" |
      "integer" | "bool" | "mapping" | "list", "help": str, "required": bool, "choices":
      [...]}}``
      (the browser UI's designer builds its forms from it; ``validate`` still decides).
    - ``check_events(options, position, events, desk)``: called after the layout loaded, with
      every :class:`~hapticdesk.gestures.event.GestureEvent` the use's binding can make
      (``desk`` the desk's name); raise ConfigError when the options break a limit for one of
      them (the built-ins render their templates for each:
      ``hapticdesk.plugins.templating:check_for_events``).
    - ``operator_only``: True when a use of the action is the operator's alone (``exec`` runs
      programs): a layout arriving through the browser UI, ``/set`` or a reload may not add
      or change one (docs/security.md). Options that read the environment or a file (a
      mapping with ``env:`` or ``file:``, a key ending ``_env`` or ``_file``) are held the
      same way for every action, without asking.

    ``factory``, ``validate`` and ``check_events`` may be lazy ``"module:attr"`` strings.
    """


@hookspec
def register_recognizers(register: Any) -> None:
    """Register gesture recognizers, the ``gesture:`` names a layout can bind.

    Called once while the registry is built, with ``register`` the callback to call as
    ``register(name, factory, description="")``, where ``factory`` (a class, or a lazy
    ``"module:attr"`` string) is a :class:`~hapticdesk.gestures.recognizer.Recognizer`
    subclass, as :class:`~hapticdesk.gestures.engine.GestureEngine` takes in its
    ``recognizer_types``; its ``option_specs`` let layouts validate the gesture's options.
    """


@hookspec
def startup(desk: Any, layout: Any, runtime: Any) -> None:
    """A run is about to start sensing.

    Called once per ``hapticdesk run`` or ``demo`` after the source, the estimator, the gesture
    engine and the actions are built, before the first block is read. ``desk`` is the
    :class:`~hapticdesk.files.profile.DeskProfile`, ``layout`` the loaded layout, ``runtime``
    the :class:`~hapticdesk.runtime.service.Runtime` for a plugin that watches the run from
    its own thread (the browser UI): ``runtime.live.sample`` is the latest contact sample
    (written once per block by the sensing thread, O(1)), ``runtime.scene.estimator.notices``
    what the estimator did on its own, ``runtime.scene.dispatcher.lanes`` the actions' counts,
    and ``runtime.reload()`` swaps in the saved layout without a new tare. Never
    block or do work on the sensing thread. An exception here is logged with the plugin's
    name (and is fatal under ``--strict``).
    """


@hookspec
def shutdown(desk: Any, layout: Any, report: Any) -> None:
    """A run has ended (its source finished, or SIGINT/SIGTERM).

    Called once after the dispatcher has flushed or given up on queued commands. ``desk`` is
    the :class:`~hapticdesk.files.profile.DeskProfile`, ``layout`` the loaded layout, ``report``
    the :class:`~hapticdesk.runtime.service.RunReport` (samples, gestures, action counts, commands
    not delivered). An exception here is logged with the plugin's name.
    """


@hookspec
def register_layout_sections(register: Any) -> None:
    """Register top-level layout sections a plugin owns (e.g. the MQTT plugin's ``mqtt:``).

    Called once while the registry is built, with ``register`` the callback to call as
    ``register(name, validate, description="")``. The layout accepts a top-level key only when
    it is the core's own or a plugin claimed it, and hands a claimed section, as written, to
    ``validate(value, position, layout_path)`` while it loads (so ``hapticdesk check`` and
    ``run`` refuse the same sections). ``operator_only=True`` (a keyword of ``register``)
    makes the section the operator's alone: a layout from the browser UI, ``/set`` or a reload
    may not change it (a connection's address and credentials). ``value`` is the section (a
    :class:`~hapticdesk.files.yamlfile.MarkedDict` for a mapping, with positions),
    ``position`` where it stands, ``layout_path`` the layout file (paths in the section are
    relative to its folder). Raise :class:`~hapticdesk.files.yamlfile.ConfigError` naming
    ``file:line:column``. ``validate`` may be a lazy ``"module:attr"`` string.
    """


@hookspec
def register_commands(register: Any) -> None:
    """Register ``hapticdesk`` sub-commands (e.g. ``demo``, which needs the MQTT plugin).

    Called once while the registry is built, with ``register`` the callback to call as
    ``register(name, module, description="")``, where ``module`` is a module (or its dotted
    name, imported only when the command runs) with ``configure(parser)`` and
    ``run(args) -> int``, like the core's own commands. A name the core already uses is an
    error.
    """


@hookspec
def event_sink(desk: Any, layout: Any, context: Any) -> Any:
    """A run is being built: return a callable to receive every gesture event, or None.

    Called once per ``hapticdesk run`` or ``demo`` after the layout is loaded and the actions
    are built, before anything senses. ``desk`` is the
    :class:`~hapticdesk.files.profile.DeskProfile`, ``layout`` the loaded layout, ``context``
    the run's :class:`~hapticdesk.runtime.dispatcher.ActionContext` (its ``desk_name``,
    shared resources and command-line ``overrides``). The returned callable takes one
    :class:`~hapticdesk.gestures.event.GestureEvent` and runs in its own dispatcher lane
    (off the sensing thread, with ``timeout_s`` and ``close()`` as for actions); the MQTT
    plugin publishes the desk's own topics from here. A
    :class:`~hapticdesk.files.yamlfile.ConfigError` raised here stops the run before it starts.
    """


@hookspec
def control_channel(control: Any, desk: Any, layout: Any, context: Any) -> None:
    """A run is about to start sensing: here is how to tell it things.

    Called once per ``hapticdesk run`` or ``demo``, just before ``startup``. ``control`` is
    the run's :class:`~hapticdesk.runtime.control.ControlQueue`: a plugin that listens on a
    network (the MQTT plugin's ``<prefix>/set``) keeps it and calls
    ``control.request(name, argument=None)`` from any thread for ``tare``, ``pause``,
    ``resume``, ``reload`` or ``layout NAME`` (:data:`~hapticdesk.runtime.control.COMMANDS`);
    :func:`~hapticdesk.runtime.control.parse_command` reads them from JSON. A request never
    blocks; it returns a :class:`concurrent.futures.Future` holding what was done or why not,
    applied by the sensing thread between two blocks. ``desk``, ``layout`` and ``context`` are
    as for ``event_sink``. An exception here is logged with the plugin's name (and is fatal
    under ``--strict``).
    """


@hookspec
def contact_sink(desk: Any, layout: Any, context: Any) -> Any:
    """A run is being built: return a callable to observe the contact state, or None.

    Called once per ``hapticdesk run`` or ``demo`` next to :func:`event_sink`, with the same
    ``desk``, ``layout`` and ``context``. The callable is
    called on the *sensing thread* once per block the source delivers (tens of times a
    second), with one :class:`~hapticdesk.runtime.observe.ContactSummary` (the block's last
    sample and the estimator's zero). It must return at once: keep the latest value, throttle,
    and hand slow work (publishing) to a queue, as the MQTT plugin's sensors do. A sink that
    raises is logged and dropped for the rest of the run; sensing goes on.
    """
