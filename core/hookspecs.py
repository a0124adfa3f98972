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
built (:func:`hapticdesk.plugin_loading.load_registry`). Observer hooks run once per ``run``;
none is called on the per-sample or per-gesture path (pluggy stops at the first exception
there, so the dispatcher calls actions itself, each in its own ``try``).

The arguments' types are the plugin contract. They are imported for the type checker only, so
this module stays light (``hapticdesk --help`` loads every plugin's hook module). A plugin
watching a run gets it as a :class:`RunView`: what of the
:class:`~hapticdesk.runtime.service.Runtime` a plugin may use, said here as a protocol (the
runtime's own module reaches the gesture engine, which loads the built-in plugins through
:mod:`hapticdesk.plugin_loading`, which imports this module: naming the class would close a
circle).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING, Any, Protocol

import pluggy

if TYPE_CHECKING:
    import numpy as np

    from hapticdesk.errors import Position
    from hapticdesk.estimator import ContactEstimator
    from hapticdesk.files.profile import DeskProfile
    from hapticdesk.gestures.event import GestureEvent
    from hapticdesk.gestures.layout import Layout
    from hapticdesk.gestures.recognizer import Recognizer
    from hapticdesk.registry import Registry
    from hapticdesk.runtime.control import ControlQueue
    from hapticdesk.runtime.dispatcher import Action, ActionContext, Dispatcher
    from hapticdesk.runtime.live_status import LiveStatus
    from hapticdesk.runtime.observe import ContactSummary
    from hapticdesk.runtime.run_report import RunReport
    from hapticdesk.runtime.source import Source

hookspec = pluggy.HookspecMarker("hapticdesk")
hookimpl = pluggy.HookimplMarker("hapticdesk")


# --- what the registration hooks register --------------------------------------------------


class SourceFactory(Protocol):
    """``factory(argument, profile, **options) -> Source`` (see :func:`register_sources`)."""

    def __call__(self, argument: str, profile: DeskProfile, /, **options: Any) -> Source: ...


#: ``factory(options, context) -> action``: ``options`` as the layout gives them
ActionFactory = Callable[[Any, "ActionContext"], "Action"]
#: ``validate(options, position)``: raises ConfigError when the options are wrong
ActionValidator = Callable[[Any, "Position | str"], None]
#: ``check_events(options, position, events, desk)``
EventCheck = Callable[[Any, "Position | str", "list[GestureEvent]", str], None]
#: ``validate(value, position, layout_path)`` of a layout section a plugin claimed
SectionValidator = Callable[[Any, "Position | str", "Path | None"], None]
#: an action's options as a form offers them: name -> {"kind", "help", "required", "choices"}
OptionForm = Mapping[str, Mapping[str, Any]]


class RegisterSource(Protocol):
    """The ``register`` callback of :func:`register_sources`."""

    def __call__(
        self, name: str, factory: SourceFactory | str, /, description: str = ""
    ) -> None: ...


class RegisterAction(Protocol):
    """The ``register`` callback of :func:`register_actions`."""

    def __call__(
        self,
        name: str,
        factory: ActionFactory | str,
        /,
        description: str = "",
        *,
        validate: ActionValidator | str | None = None,
        options: OptionForm | None = None,
        check_events: EventCheck | str | None = None,
        operator_only: bool = False,
    ) -> None: ...


class RegisterRecognizer(Protocol):
    """The ``register`` callback of :func:`register_recognizers`."""

    def __call__(
        self, name: str, factory: type[Recognizer] | str, /, description: str = ""
    ) -> None: ...


class RegisterSection(Protocol):
    """The ``register`` callback of :func:`register_layout_sections`."""

    def __call__(
        self,
        name: str,
        validate: SectionValidator | str,
        /,
        description: str = "",
        *,
        operator_only: bool = False,
    ) -> None: ...


class RegisterCommand(Protocol):
    """The ``register`` callback of :func:`register_commands`."""

    def __call__(self, name: str, module: ModuleType | str, /, description: str = "") -> None: ...


# --- what a plugin watching a run may use of it ----------------------------------------------

#: ``tap(t, readings)``: a block's sample times and raw readings, on the sensing thread
BlockTap = Callable[["np.ndarray", "np.ndarray"], object]


class RunParts(Protocol):
    """The parts of a running desk a plugin may read (an
    :class:`~hapticdesk.runtime.assembly.Assembly` is one)."""

    @property
    def profile(self) -> DeskProfile: ...
    @property
    def layout(self) -> Layout: ...
    @property
    def registry(self) -> Registry: ...
    @property
    def context(self) -> ActionContext: ...
    @property
    def estimator(self) -> ContactEstimator: ...
    @property
    def dispatcher(self) -> Dispatcher: ...
    @property
    def actions(self) -> bool: ...


class RunView(Protocol):
    """What a plugin watching a run may use of it (a
    :class:`~hapticdesk.runtime.service.Runtime` is one)."""

    #: callables given every block's ``(t, readings)`` on the sensing thread; replace it whole
    block_taps: tuple[BlockTap, ...]

    @property
    def live(self) -> LiveStatus: ...
    @property
    def scene(self) -> RunParts: ...
    def reload(self, timeout_s: float = 10.0) -> str: ...


def hookspec_names() -> list[str]:
    """Every hook a plugin can implement."""
    return sorted(name for name, value in globals().items() if hasattr(value, "hapticdesk_spec"))


@hookspec
def register_sources(register: RegisterSource) -> None:
    """Register source kinds, the ``KIND`` of ``--source KIND:ARGUMENT``.

    Called once while the registry is built, with ``register`` the callback
    (:class:`RegisterSource`) to call as ``register(name, factory, description="")`` for each kind,
    where ``factory`` is a callable or a lazy ``"module:attr"`` string (imported only when a run
    uses that kind) and is called as ``factory(argument, profile, **options) ->
    hapticdesk.runtime.source.Source`` with ``argument`` the text after ``KIND:``, ``profile`` the
    :class:`~hapticdesk.files.profile.DeskProfile`, and ``options`` keyword options the factory may
    ignore (``speed``: replay speed, 1 = real time, 0 = as fast as possible). Bad arguments raise
    :class:`~hapticdesk.errors.ConfigError`.
    """


@hookspec
def register_actions(register: RegisterAction) -> None:
    """Register actions, the keys under a binding's ``do:`` in a layout.

    Called once while the registry is built, with ``register`` the callback to call as
    ``register(name, factory, description="", *, validate=None, options=None, check_events=None,
    operator_only=False)`` for each action:

    - ``factory(options, context) -> action``: ``options`` the action's mapping from the
      layout, ``context`` an :class:`~hapticdesk.runtime.dispatcher.ActionContext`. The action is a
      callable taking one :class:`~hapticdesk.gestures.event.GestureEvent`; it may have a
      ``close()`` method (called once at the end) and a ``timeout_s`` attribute (how long one
      call may take before the dispatcher gives up on it).
    - ``validate(options, position)``: raise :class:`~hapticdesk.errors.ConfigError` naming
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
def register_recognizers(register: RegisterRecognizer) -> None:
    """Register gesture recognizers, the ``gesture:`` names a layout can bind.

    Called once while the registry is built, with ``register`` the callback
    (:class:`RegisterRecognizer`) to call as ``register(name, factory, description="")``, where
    ``factory`` (a class, or a lazy ``"module:attr"`` string) is a
    :class:`~hapticdesk.gestures.recognizer.Recognizer` subclass, as
    :class:`~hapticdesk.gestures.engine.GestureEngine` takes in its ``recognizer_types``; its
    ``option_specs`` let layouts validate the gesture's options.
    """


@hookspec
def startup(desk: DeskProfile, layout: Layout, runtime: RunView) -> None:
    """A run is about to start sensing.

    Called once per ``hapticdesk run`` or ``demo`` after the source, the estimator, the gesture
    engine and the actions are built, before the first block is read. ``desk`` is the
    :class:`~hapticdesk.files.profile.DeskProfile`, ``layout`` the loaded layout, ``runtime``
    the :class:`~hapticdesk.runtime.service.Runtime` (what a plugin may use of it:
    :class:`RunView`) for a plugin that watches the run from its own thread (the browser UI):
    ``runtime.live.sample`` is the latest contact sample (a
    :class:`~hapticdesk.runtime.live_status.LiveSample`, written once per block by the sensing
    thread, O(1)), ``runtime.scene.estimator.notices`` what the estimator did on its own,
    ``runtime.scene.dispatcher.routes`` the actions' lanes and their counts, ``block_taps``
    callables given each block's raw readings on the sensing thread, and ``runtime.reload()``
    swaps in the saved layout without a new tare. Never
    block or do work on the sensing thread. An exception here is logged with the plugin's
    name (and is fatal under ``--strict``).
    """


@hookspec
def shutdown(desk: DeskProfile, layout: Layout, report: RunReport) -> None:
    """A run has ended (its source finished, or SIGINT/SIGTERM).

    Called once after the dispatcher has flushed or given up on queued commands. ``desk`` is
    the :class:`~hapticdesk.files.profile.DeskProfile`, ``layout`` the loaded layout, ``report``
    the :class:`~hapticdesk.runtime.run_report.RunReport` (samples, gestures, action counts,
    commands not delivered). An exception here is logged with the plugin's name.
    """


@hookspec
def register_layout_sections(register: RegisterSection) -> None:
    """Register top-level layout sections a plugin owns (e.g. the MQTT plugin's ``mqtt:``).

    Called once while the registry is built, with ``register`` the callback
    (:class:`RegisterSection`) to call as ``register(name, validate, description="")``. The layout
    accepts a top-level key only when it is the core's own or a plugin claimed it, and hands a
    claimed section, as written, to ``validate(value, position, layout_path)`` while it loads (so
    ``hapticdesk check`` and ``run`` refuse the same sections). ``operator_only=True`` (a keyword of
    ``register``) makes the section the operator's alone: a layout from the browser UI, ``/set`` or
    a reload may not change it (a connection's address and credentials). ``value`` is the section (a
    :class:`~hapticdesk.files.marked_values.MarkedDict` for a mapping, with positions), ``position``
    where it stands, ``layout_path`` the layout file (paths in the section are relative to its
    folder). Raise :class:`~hapticdesk.errors.ConfigError` naming ``file:line:column``.
    ``validate`` may be a lazy ``"module:attr"`` string.
    """


@hookspec
def register_commands(register: RegisterCommand) -> None:
    """Register ``hapticdesk`` sub-commands (e.g. ``demo``, which needs the MQTT plugin).

    Called once while the registry is built, with ``register`` the callback
    (:class:`RegisterCommand`) to call as ``register(name, module, description="")``, where
    ``module`` is a module (or its dotted name, imported only when the command runs) with
    ``configure(parser)`` and ``run(args) -> int``, like the core's own commands. A name the core
    already uses is an error.
    """


@hookspec
def event_sink(
    desk: DeskProfile, layout: Layout, context: ActionContext
) -> Callable[[GestureEvent], object] | None:
    """A run is being built: return a callable to receive every gesture event, or None.

    Called once per ``hapticdesk run`` or ``demo`` after the layout is loaded and the actions
    are built, before anything senses. ``desk`` is the
    :class:`~hapticdesk.files.profile.DeskProfile`, ``layout`` the loaded layout, ``context``
    the run's :class:`~hapticdesk.runtime.dispatcher.ActionContext` (its ``desk_name``,
    shared resources and command-line ``overrides``). The returned callable takes one
    :class:`~hapticdesk.gestures.event.GestureEvent` and runs in its own dispatcher lane
    (off the sensing thread, with ``timeout_s`` and ``close()`` as for actions); the MQTT
    plugin publishes the desk's own topics from here. A
    :class:`~hapticdesk.errors.ConfigError` raised here stops the run before it starts.
    """


@hookspec
def control_channel(
    control: ControlQueue, desk: DeskProfile, layout: Layout, context: ActionContext
) -> None:
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
def contact_sink(
    desk: DeskProfile, layout: Layout, context: ActionContext
) -> Callable[[ContactSummary], object] | None:
    """A run is being built: return a callable to observe the contact state, or None.

    Called once per ``hapticdesk run`` or ``demo`` next to :func:`event_sink`, with the same
    ``desk``, ``layout`` and ``context``. The callable is
    called on the *sensing thread* once per block the source delivers (tens of times a
    second), with one :class:`~hapticdesk.runtime.observe.ContactSummary` (the block's last
    sample and the estimator's zero). It must return at once: keep the latest value, throttle,
    and hand slow work (publishing) to a queue, as the MQTT plugin's sensors do. A sink that
    raises is logged and dropped for the rest of the run; sensing goes on.
    """
