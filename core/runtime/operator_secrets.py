"""Secrets are the operator's: what a layout may not add or change once the desk runs.

Whoever starts the desk (``hapticdesk run``, ``ui``, a systemd unit) decides what it reads
from the environment or from files, which programs it runs and which connection carries its
credentials. A layout that arrives later — saved from the browser UI, switched to or reloaded
over MQTT (``<prefix>/set``), reloaded on SIGHUP — is compared with the layouts the desk
started with, and refused, at its place, when it adds or changes any of:

- an action use whose options read the environment or a file: a mapping with ``env:`` or
  ``file:`` (an ``http`` header ``{env: HA_TOKEN}``), or a key ending ``_env`` or ``_file``,
  in any action's options (so a third party's action is held the same way without asking);
  its whole use is held — options and trigger — because the same header sent to another URL
  is the secret sent elsewhere;
- a use of an action registered ``operator_only`` (``exec``: a program reads anything);
- a layout section registered ``operator_only`` (``mqtt:``: the broker, its password and TLS
  files), or any section that reads the environment or a file;
- another layout file named under ``layouts:``.

One page had saved an ``http`` action whose header was ``{env: MQTT_PASSWORD}`` and every
tap then sent the password to a URL of its choosing (issue 30, item 1).

What the desk started with are its layout and the layouts it names, read when it starts
(:meth:`OperatorSecrets.from_start`); a part held by any of them may be kept as it is, moved
from one of them to another, or removed.
"""

from __future__ import annotations

import collections
import json
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hapticdesk.errors import ConfigError, Position
from hapticdesk.files.marked_values import MarkedDict, MarkedList

#: the keys of a binding that say when it fires (everything but what it does)
_NOT_TRIGGER = ("do", "description")


@dataclass(frozen=True)
class HeldPart:
    """One part of a layout only the operator may add or change."""

    key: str  # what it is, comparable across two loads (JSON)
    where: Position | str  # where it stands in its layout
    what: str  # what it does, for the error ("`http` reads the environment variable HA_TOKEN")


def reads_of(value: Any) -> list[str]:
    """What ``value`` (an action's options, a section) reads from the environment or from
    files, as phrases: ``the environment variable HA_TOKEN``, ``the file token.txt``."""
    found: list[str] = []
    if isinstance(value, Mapping):
        for key, item in value.items():
            name = str(key)
            if name == "env" or name.endswith("_env"):
                found.append(f"the environment variable {item}")
            elif name == "file" or name.endswith("_file"):
                found.append(f"the file {item}")
            else:
                found += reads_of(item)
    elif isinstance(value, list | tuple):
        for item in value:
            found += reads_of(item)
    return found


def held_parts(doc: Mapping[str, Any], folder: Path, registry: Any) -> list[HeldPart]:
    """The parts of the layout ``doc`` (its top-level mapping, as read from its file in
    ``folder``) that only the operator may add or change (see the module docstring)."""
    parts: list[HeldPart] = []
    bindings = doc.get("bindings")
    for i, binding in enumerate(bindings if isinstance(bindings, list) else []):
        if not isinstance(binding, Mapping):
            continue
        trigger = {k: v for k, v in binding.items() if k not in _NOT_TRIGGER}
        for name, options, where in _uses(binding):
            record = registry.actions.get(name)
            reads = reads_of(options)
            if reads or (record is not None and record.operator_only):
                what = f"`{name}` reads {', '.join(reads)}" if reads else f"`{name}` runs programs"
                key = _key(["action", trigger, name, options, str(folder) if reads else ""])
                parts.append(HeldPart(key, where or _where(bindings, i), what))
    for name, section in getattr(registry, "layout_sections", {}).items():
        if name not in doc:
            continue
        reads = reads_of(doc[name])
        if reads or section.operator_only:
            what = f"`{name}:`" + (f" reads {', '.join(reads)}" if reads else " (the connection)")
            parts.append(HeldPart(_key(["section", name, doc[name]]), _where(doc, name), what))
    layouts = doc.get("layouts")
    if isinstance(layouts, Mapping):
        for name, file in layouts.items():
            path = (folder / Path(str(file)).expanduser()).resolve()
            what = f"`layouts: {{{name}: {file}}}` names another layout file (it may run programs)"
            parts.append(HeldPart(_key(["layouts", str(path)]), _where(layouts, name), what))
    return parts


def _uses(binding: Mapping[str, Any]) -> Iterable[tuple[str, Any, Position | None]]:
    """(action name, options, position) of each action a raw binding's ``do`` names."""
    value = binding.get("do")
    items = value if isinstance(value, list) else [value]
    for item in items:
        if isinstance(item, str):
            yield item, None, None
        elif isinstance(item, Mapping):
            for name, options in item.items():
                where = item.where(name) if isinstance(item, MarkedDict) else None
                yield str(name), options, where


def _where(container: Any, key: Any) -> Position | str:
    if isinstance(container, MarkedDict):
        return container.where(key)
    if isinstance(container, MarkedList):
        return container.where(key)
    return "the layout"


def _key(value: Any) -> str:
    return json.dumps(value, sort_keys=True, default=str)


class OperatorSecrets:
    """The held parts of the layouts a desk started with, and the check of a new layout."""

    def __init__(self, started: Iterable[list[HeldPart]]) -> None:
        # a part may be used as many times as the layout that used it most often did
        self.allowed: collections.Counter[str] = collections.Counter()
        for parts in started:
            for key, count in collections.Counter(p.key for p in parts).items():
                self.allowed[key] = max(self.allowed[key], count)

    @classmethod
    def from_start(
        cls,
        doc: Mapping[str, Any],
        path: Path,
        registry: Any,
        named: Mapping[str, Path] | None = None,
    ) -> OperatorSecrets:
        """What a desk starts with: its layout (``doc`` read from ``path``) and the layout
        files it names (read now; one that cannot be read holds nothing)."""
        from hapticdesk.files.yamlfile import load_marked_yaml

        started = [held_parts(doc, Path(path).parent, registry)]
        for file in (named or {}).values():
            try:
                other = load_marked_yaml(file)
            except ConfigError:
                continue
            if isinstance(other, Mapping):
                started.append(held_parts(other, Path(file).parent, registry))
        return cls(started)

    def refusal(
        self, doc: Mapping[str, Any], path: Path, registry: Any, arrived: str, remedy: str
    ) -> ConfigError | None:
        """The error for the layout ``doc`` (read from ``path``) when it adds or changes a
        held part, else None. ``arrived``: how it came (``the page``, ``a reload``);
        ``remedy``: what the operator does instead."""
        left = collections.Counter(self.allowed)
        for part in held_parts(doc, Path(path).parent, registry):
            if left[part.key] > 0:
                left[part.key] -= 1
                continue
            return ConfigError(
                part.where,
                f"{part.what}: {arrived} may not add or change what reads the environment or "
                "a file, runs programs, holds a connection or names other layouts (secrets are "
                f"the operator's, fixed when the desk starts); {remedy}",
            )
        return None
