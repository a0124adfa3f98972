"""Building the plugin registry: the hooks, the built-ins, the entry points, in that order.

This joins the base registry (:mod:`hapticdesk.registry`) with the hooks
(:mod:`hapticdesk.hookspecs`), which name the runtime's parts in their types, so it sits above
the runtime: commands call it; the runtime is handed the registry it builds.
"""

from __future__ import annotations

import os
from collections.abc import Iterable

from hapticdesk import hookspecs
from hapticdesk.registered import PluginError
from hapticdesk.registry import BLOCK_ENV, DISABLE_AUTOLOAD_ENV, Registry


def load_registry(
    *,
    entry_points: bool | None = None,
    strict: bool = False,
    plugins: Iterable[tuple[str, object]] = (),
    defaults: bool = True,
    conflicts_fatal: bool = True,
    blocked: Iterable[str] = (),
) -> Registry:
    """Build the registry: built-ins, then entry points, then ``plugins`` (name, object) pairs.

    ``entry_points`` None loads them unless the environment variable
    ``HAPTICDESK_DISABLE_PLUGIN_AUTOLOAD`` is set. Tests pass ``entry_points=False`` (or set
    the variable for the command line) so whatever is installed on the machine cannot change
    their outcome, and add their own plugins through ``plugins``. A name registered by two
    plugins raises :class:`~hapticdesk.registered.PluginError` unless ``conflicts_fatal`` is
    False (``hapticdesk plugins`` lists it as an error instead). ``blocked``: plugin names never
    to load (a built-in from :data:`~hapticdesk.registry.DEFAULT_PLUGINS` that a third-party
    plugin replaces; two plugins may not register the same name), added to those named in the
    environment variable ``HAPTICDESK_BLOCK_PLUGINS`` (comma-separated), which is how a person
    installing such a replacement turns the built-in off for every command.
    """
    if entry_points is None:
        entry_points = not os.environ.get(DISABLE_AUTOLOAD_ENV)
    registry = Registry(hookspecs, strict=strict)
    from_env = os.environ.get(BLOCK_ENV, "").split(",")
    for name in [*blocked, *from_env]:
        if name.strip():
            registry.block(name.strip())
    if defaults:
        registry.load_default_plugins()
    if entry_points:
        registry.load_entry_points()
    for name, plugin in plugins:
        registry.add_plugin(plugin, name, origin="given by the caller")
    registry.collect()
    if registry.errors and conflicts_fatal:
        raise PluginError(registry.errors[0])
    return registry
