"""What a plugin registers: one small typed record per name (STYLE.md 2).

A plugin's registration hook calls ``register(name, factory, description, …)``
(:mod:`hapticdesk.hookspecs`); the :class:`~hapticdesk.registry.Registry` keeps one of these
records per name, with the plugin that gave it. A factory may be a lazy ``"module:attr"`` text,
imported the first time a run uses it (:func:`hapticdesk.lazy_ref.resolve`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from hapticdesk.errors import ConfigError, Position
from hapticdesk.lazy_ref import resolve

#: the kinds of things a plugin registers, one registration hook each (``register_<kind>``)
KINDS = ("sources", "actions", "recognizers", "layout_sections", "commands")


class PluginError(ConfigError):
    """A plugin could not be loaded or registered something wrong."""

    def __init__(self, message: str) -> None:
        super().__init__(None, message)


@dataclass(frozen=True)
class Registered:
    """One named thing a plugin provides."""

    name: str
    factory: Any  # callable or "module:attr"
    description: str
    plugin: str

    def load(self) -> Any:
        """The factory, importing it on first use; import problems become a PluginError."""
        try:
            return resolve(self.factory)
        except (ImportError, AttributeError) as err:
            raise PluginError(
                f"`{self.name}` from plugin `{self.plugin}` cannot be loaded: "
                f"{type(err).__name__}: {err}"
            ) from err


@dataclass(frozen=True)
class SourceType(Registered):
    """A source kind: ``factory(argument, profile, **options) -> Source``."""

    def open(self, argument: str, profile: Any, **options: Any) -> Any:
        return self.load()(argument, profile, **options)


def _judged_by_plugin(
    validate: Callable[[], Any], position: Position | str, plugin: str, what: str
) -> None:
    """Run a plugin's validation: its ConfigError is the user's, any other exception a bug in
    the plugin, reported as the plugin's fault at the place being checked."""
    try:
        validate()
    except ConfigError:
        raise
    except Exception as err:  # a bug in the plugin, not the user's layout
        raise PluginError(
            f"{position}: plugin `{plugin}` crashed validating {what}: {type(err).__name__}: {err}"
        ) from err


@dataclass(frozen=True)
class ActionType(Registered):
    """An action: ``factory(options, context) -> callable(event)``; ``validate(options, pos)``."""

    validate: Any = None  # callable, "module:attr" or None
    #: the options a form may offer: name -> {"kind": text|number|integer|bool|mapping,
    #: "help": str, "required": bool, "choices": [...]} (the browser UI builds its forms
    #: from it); None when the plugin gave none. ``validate`` stays the judge.
    options: Any = None
    #: ``check_events(options, position, events, desk)``: checks the options against every
    #: event the binding can make (its templates rendered for each); callable, "module:attr"
    #: or None
    check_events: Any = None
    #: a use of this action is the operator's alone (it runs programs, or reads what it
    #: likes): a layout from the page, ``/set`` or a reload may not add or change one
    operator_only: bool = False

    def check(self, options: Any, position: Position | str) -> None:
        """Run the plugin's validation; a crash in it is reported as the plugin's fault."""
        self._judge(self.validate, "validator", position, options, position)

    def check_for_events(
        self, options: Any, position: Position | str, events: list[Any], desk: str
    ) -> None:
        """Run the plugin's ``check_events`` for the events a binding can make (if any)."""
        self._judge(self.check_events, "event check", position, options, position, events, desk)

    def _judge(self, ref: Any, what: str, position: Position | str, *args: Any) -> None:
        """Call the plugin's ``ref`` (None: nothing to do) with ``args``, as its judgement."""
        if ref is None:
            return
        try:
            judge = resolve(ref)
        except (ImportError, AttributeError) as err:
            raise PluginError(
                f"the {what} of action `{self.name}` from plugin `{self.plugin}` cannot be "
                f"loaded: {type(err).__name__}: {err}"
            ) from err
        _judged_by_plugin(lambda: judge(*args), position, self.plugin, f"action `{self.name}`")


@dataclass(frozen=True)
class RecognizerType(Registered):
    """A gesture recognizer the gesture engine can build."""


@dataclass(frozen=True)
class SectionType(Registered):
    """A top-level layout section a plugin owns: ``factory`` is its validator."""

    #: the section is the operator's alone (a connection and its credentials): a layout from
    #: the page, ``/set`` or a reload may not change it
    operator_only: bool = False

    def check(self, value: Any, position: Position | str, layout_path: Any) -> None:
        """Run the plugin's validation of the section; a crash is reported as the plugin's."""
        validator = self.load()
        _judged_by_plugin(
            lambda: validator(value, position, layout_path),
            position,
            self.plugin,
            f"section `{self.name}`",
        )


@dataclass(frozen=True)
class CommandType(Registered):
    """A ``hapticdesk`` sub-command: ``factory`` is a module with ``configure`` and ``run``."""


@dataclass
class PluginInfo:
    """What the ``plugins`` command shows for one plugin."""

    name: str
    version: str
    origin: str  # "built-in" or "entry point (distribution name)"
    hooks: list[str] = field(default_factory=list)
    provides: dict[str, list[str]] = field(default_factory=lambda: {k: [] for k in KINDS})

    def to_dict(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "version": self.version,
            "origin": self.origin,
            "hooks": list(self.hooks),
            **{k: list(v) for k, v in self.provides.items()},
        }


#: the record each kind's ``register`` makes
RECORD_TYPES: dict[str, type[Registered]] = {
    "sources": SourceType,
    "actions": ActionType,
    "recognizers": RecognizerType,
    "layout_sections": SectionType,
    "commands": CommandType,
}
