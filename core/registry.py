"""The plugin registry: which sources, actions, recognizers, layout sections and commands exist,
and which plugin gave each.

Built-in plugins (:data:`DEFAULT_PLUGINS`) and third-party ones (entry-point group
``hapticdesk``) go through the same hooks. Each entry point is loaded on its own: one that
fails to import, or whose registration hook raises, is skipped with a warning naming it
(``strict=True`` makes that fatal). Two plugins registering the same name is always an error
naming both, since either choice would surprise someone.

Factories may be ``"module:attr"`` strings, imported the first time a run uses them, so a
scene imports only what it uses (python-can's ``BACKENDS`` habit). This is a base layer: it is
handed the hooks (:mod:`hapticdesk.hookspecs`, whose types name the runtime's parts) by
:func:`hapticdesk.plugin_loading.load_registry`, and imports nothing of the runtime.
"""

from __future__ import annotations

import importlib
import importlib.metadata
import logging
from types import ModuleType
from typing import Any

import pluggy

from hapticdesk import __version__
from hapticdesk.errors import ConfigError, Position
from hapticdesk.lazy_ref import is_loadable
from hapticdesk.registered import (
    KINDS,
    RECORD_TYPES,
    ActionType,
    CommandType,
    PluginError,
    PluginInfo,
    RecognizerType,
    Registered,
    SectionType,
    SourceType,
)

log = logging.getLogger(__name__)

ENTRY_POINT_GROUP = "hapticdesk"
#: set to 1 to load no third-party plugins (tests; like PYTEST_DISABLE_PLUGIN_AUTOLOAD)
DISABLE_AUTOLOAD_ENV = "HAPTICDESK_DISABLE_PLUGIN_AUTOLOAD"
#: comma-separated plugin names never to load, e.g. a built-in a third-party plugin replaces
BLOCK_ENV = "HAPTICDESK_BLOCK_PLUGINS"

#: built-in plugins, registered exactly like third-party ones
DEFAULT_PLUGINS: tuple[str, ...] = (
    "hapticdesk.plugins.recognizers",
    "hapticdesk.plugins.sim",
    "hapticdesk.plugins.replay",
    "hapticdesk.plugins.can",
    "hapticdesk.plugins.serial",
    "hapticdesk.plugins.log",
    "hapticdesk.plugins.exec",
    "hapticdesk.plugins.http",
    "hapticdesk.plugins.mqtt",
    "hapticdesk.plugins.ui",
)


class Registry:
    """Plugins and what they registered, checked against the hooks of ``specs`` (a module of
    hookspecs). Build it with :func:`hapticdesk.plugin_loading.load_registry`."""

    def __init__(self, specs: ModuleType, *, strict: bool = False) -> None:
        self.strict = strict
        self.manager = pluggy.PluginManager("hapticdesk")
        self.manager.add_hookspecs(specs)
        self.plugins: dict[str, PluginInfo] = {}
        self.warnings: list[str] = []
        self.errors: list[str] = []  # conflicts no plugin can be blamed alone for
        self.sources: dict[str, SourceType] = {}
        self.actions: dict[str, ActionType] = {}
        self.recognizers: dict[str, RecognizerType] = {}
        self.layout_sections: dict[str, SectionType] = {}
        self.commands: dict[str, CommandType] = {}

    # --- loading ------------------------------------------------------------------------------

    def block(self, name: str) -> None:
        """Never load the plugin called ``name`` (e.g. a built-in a third party replaces)."""
        self.manager.set_blocked(name)

    def add_plugin(
        self, plugin: object, name: str, *, version: str = __version__, origin: str = "built-in"
    ) -> bool:
        """Register one plugin object (a module or any object with hookimpls).

        Returns False (after a warning, or raises under ``strict``) when pluggy rejects it,
        e.g. for a hookimpl whose name or arguments match no hookspec.
        """
        if self.manager.is_blocked(name):
            return False
        if name in self.plugins:
            self._fail(f"two plugins are called `{name}` (the second: {origin})", "it is skipped")
            return False
        try:
            self.manager.register(plugin, name=name)
        except (pluggy.PluginValidationError, ValueError) as err:
            self._fail(f"plugin `{name}` ({origin}) is not a valid hapticdesk plugin: {err}")
            return False
        callers = self.manager.get_hookcallers(plugin) or []
        unknown = sorted(hook.name for hook in callers if not hook.has_spec())
        if unknown:  # pluggy accepts these silently; a typo would never be called
            self.manager.unregister(plugin)
            known = ", ".join(self.hook_names())
            self._fail(
                f"plugin `{name}` ({origin}) is not a valid hapticdesk plugin: it implements "
                f"{', '.join(unknown)}, which hapticdesk does not have; hooks: {known}"
            )
            return False
        hooks = sorted(hook.name for hook in callers)
        self.plugins[name] = PluginInfo(name, version, origin, hooks)
        return True

    def load_default_plugins(self) -> None:
        """Import and register every module in :data:`DEFAULT_PLUGINS`."""
        for dotted in DEFAULT_PLUGINS:
            if self.manager.is_blocked(dotted):
                continue
            try:
                module = importlib.import_module(dotted)
            except Exception as err:  # a broken install; say which module
                self._fail(f"built-in plugin `{dotted}` failed to import: {err}")
                continue
            self.add_plugin(module, dotted)

    def load_entry_points(self) -> None:
        """Load every entry point of the ``hapticdesk`` group, each on its own."""
        for ep in sorted(
            importlib.metadata.entry_points(group=ENTRY_POINT_GROUP), key=lambda e: e.name
        ):
            dist = getattr(ep, "dist", None)
            dist_name = dist.metadata["Name"] if dist is not None else "unknown distribution"
            version = dist.version if dist is not None else "unknown"
            origin = f"entry point of {dist_name}"
            try:
                plugin = ep.load()
            except Exception as err:  # anything a third-party import can raise
                self._fail(
                    f"plugin `{ep.name}` ({origin}, {ep.value}) failed to load: "
                    f"{type(err).__name__}: {err}",
                    "it is skipped",
                )
                continue
            self.add_plugin(plugin, ep.name, version=version, origin=origin)

    def collect(self) -> None:
        """Call the registration hooks of every plugin and build the name tables.

        A plugin whose hook raises is skipped with a warning (fatal under ``strict``); a name
        registered twice keeps the first and records an error naming both plugins in
        :attr:`errors` (:func:`load_registry` raises it unless asked to list it).
        """
        for kind in KINDS:
            table: dict[str, Registered] = getattr(self, kind)
            hook = getattr(self.manager.hook, f"register_{kind}")
            # registration order: built-ins first, then entry points by name
            for impl in sorted(hook.get_hookimpls(), key=self._plugin_order):
                found: list[Registered] = []
                register = self._registrar(kind, impl.plugin_name, found)
                try:
                    self._call_impl(impl, register=register)
                except PluginError:
                    raise
                except Exception as err:
                    self._fail(
                        f"plugin `{impl.plugin_name}` failed in register_{kind}: "
                        f"{type(err).__name__}: {err}",
                        f"its {kind} are skipped",
                    )
                    continue
                for record in found:
                    if record.name in table:
                        what = kind[:-1].replace("_", " ")
                        self.errors.append(
                            f"{what} `{record.name}` is registered by both plugin "
                            f"`{table[record.name].plugin}` and plugin `{record.plugin}`; "
                            "uninstall or disable one of them"
                        )
                        continue
                    table[record.name] = record
                    self.plugins[impl.plugin_name].provides[kind].append(record.name)

    @staticmethod
    def _registrar(kind: str, plugin: str, found: list[Registered]) -> Any:
        """The ``register`` callback one plugin's registration hook receives."""
        record_type = RECORD_TYPES[kind]
        what = kind[:-1].replace("_", " ")

        def register(name: str, factory: Any, description: str = "", **extra: Any) -> None:
            if not isinstance(name, str) or not name.isidentifier():
                raise PluginError(
                    f"plugin `{plugin}` registered {what} name {name!r}; "
                    "names must be identifiers (letters, digits, _)"
                )
            if not is_loadable(factory):
                raise PluginError(
                    f"plugin `{plugin}` registered {what} `{name}` with factory {factory!r}; "
                    "expected a callable or a 'module:attr' string"
                )
            found.append(record_type(name, factory, str(description), plugin, **extra))

        return register

    # --- use ----------------------------------------------------------------------------------

    def action(self, name: str, position: Position | str | None = None) -> ActionType:
        """The action called ``name``, or a ConfigError listing the installed ones."""
        try:
            return self.actions[name]
        except KeyError:
            raise ConfigError(
                position,
                f"unknown action `{name}`; installed actions: {', '.join(sorted(self.actions))}",
            ) from None

    def source(self, kind: str, where: Position | str | None = "--source") -> SourceType:
        """The source kind called ``kind``, or a ConfigError listing the installed ones."""
        try:
            return self.sources[kind]
        except KeyError:
            raise ConfigError(
                where,
                f"unknown source kind `{kind}`; installed: {', '.join(sorted(self.sources))} "
                "(as KIND:ARGUMENT, e.g. sim:scene.yaml, replay:rec.csv, can:socketcan:can0)",
            ) from None

    @property
    def action_names(self) -> list[str]:
        return sorted(self.actions)

    def validate_action(self, name: str, options: Any, position: Position | str) -> None:
        """Validate one action use of a layout: ``options`` the action's own (unknown name or
        bad options: ConfigError)."""
        self.action(name, position).check(options, position)

    def check_action_events(
        self, name: str, options: Any, position: Position | str, events: list[Any], desk: str
    ) -> None:
        """Check one action use against the events its binding can make (ConfigError if one
        would break a limit: a template too costly for one of them); ``options`` the
        action's own."""
        self.action(name, position).check_for_events(options, position, events, desk)

    def recognizer_types(self) -> dict[str, RecognizerType]:
        """Recognizers by gesture name, not imported: the gesture engine and the layout load
        only the ones a layout uses (:meth:`Registered.load`)."""
        return dict(self.recognizers)

    def validate_section(self, name: str, value: Any, position: Position, layout_path: Any) -> None:
        """Hand a layout's top-level section to the plugin that claimed it (ConfigError if bad)."""
        self.layout_sections[name].check(value, position, layout_path)

    def event_sinks(self, **kwargs: Any) -> list[tuple[str, Any]]:
        """(plugin name, callable) for every plugin whose ``event_sink`` hook returns one.

        A :class:`ConfigError` from a plugin stops the run (its section or flag is wrong);
        any other failure is reported naming the plugin, as a ConfigError too, since the run
        would silently lack what the plugin promised (the desk's MQTT topics).
        """
        return self._sinks("event_sink", **kwargs)

    def contact_sinks(self, **kwargs: Any) -> list[tuple[str, Any]]:
        """(plugin name, callable) for every plugin whose ``contact_sink`` hook returns one
        (errors as for :meth:`event_sinks`)."""
        return self._sinks("contact_sink", **kwargs)

    def _sinks(self, hook_name: str, **kwargs: Any) -> list[tuple[str, Any]]:
        sinks: list[tuple[str, Any]] = []
        hook = getattr(self.manager.hook, hook_name)
        for impl in sorted(hook.get_hookimpls(), key=self._plugin_order):
            try:
                sink = self._call_impl(impl, **kwargs)
            except ConfigError:
                raise
            except Exception as err:
                why = f"{type(err).__name__}: {err}"
                raise PluginError(
                    f"plugin `{impl.plugin_name}` failed in {hook_name}: {why}"
                ) from err
            if sink is not None:
                sinks.append((impl.plugin_name, sink))
        return sinks

    def notify(self, hook_name: str, **kwargs: Any) -> None:
        """Call an observer hook on every plugin, each in its own ``try``."""
        hook = getattr(self.manager.hook, hook_name)
        for impl in sorted(hook.get_hookimpls(), key=self._plugin_order):
            try:
                self._call_impl(impl, **kwargs)
            except Exception as err:
                message = (
                    f"plugin `{impl.plugin_name}` failed in {hook_name}: "
                    f"{type(err).__name__}: {err}"
                )
                if self.strict:
                    raise PluginError(message) from err
                log.warning("%s", message)
                self.warnings.append(message)

    def hook_names(self) -> list[str]:
        """Every hook a plugin can implement (those of the registry's hookspecs)."""
        hooks = vars(self.manager.hook).items()
        return sorted(name for name, caller in hooks if caller.has_spec())

    # --- internals ----------------------------------------------------------------------------

    def _plugin_order(self, impl: Any) -> int:
        return list(self.plugins).index(impl.plugin_name)

    @staticmethod
    def _call_impl(impl: Any, **kwargs: Any) -> Any:
        # hookimpls may take fewer arguments than the spec (pluggy's rule, kept when we call
        # each implementation on its own)
        return impl.function(*[kwargs[name] for name in impl.argnames])

    def _fail(self, message: str, consequence: str = "") -> None:
        """A plugin problem: fatal under ``strict``, else a warning saying what is skipped."""
        if self.strict:
            raise PluginError(f"{message} (fatal because of --strict)")
        if consequence:
            message = f"{message}; {consequence}"
        log.warning("%s", message)
        self.warnings.append(message)
