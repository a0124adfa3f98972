"""``--source KIND:ARGUMENT``: which source a run reads, looked up in the plugin registry.

``sim:SCENE.yaml``, ``replay:FILE`` (a recording or CAN log), ``can:INTERFACE:CHANNEL``, or
any kind a plugin registers. Only the chosen kind's module is imported.
"""

from __future__ import annotations

from typing import Any

from hapticdesk.errors import ConfigError
from hapticdesk.files.profile import DeskProfile
from hapticdesk.registry import Registry
from hapticdesk.runtime.source import Source


def parse_source_spec(spec: str) -> tuple[str, str]:
    """``"KIND:ARGUMENT"`` -> (kind, argument); the argument may hold more colons."""
    kind, sep, argument = spec.partition(":")
    if not sep or not kind:
        raise ConfigError(
            "--source",
            f"expected KIND:ARGUMENT (sim:scene.yaml, replay:rec.csv, can:socketcan:can0), "
            f"found {spec!r}",
        )
    return kind, argument


def open_source(spec: str, profile: DeskProfile, registry: Registry, **options: Any) -> Source:
    """Open the source ``spec`` names for ``profile``; ``options`` go to its factory."""
    kind, argument = parse_source_spec(spec)
    source = registry.source(kind).open(argument, profile, **options)
    if not isinstance(source, Source):
        raise ConfigError(
            "--source",
            f"the `{kind}` source of plugin `{registry.sources[kind].plugin}` returned "
            f"{type(source).__name__}, not a hapticdesk.runtime.source.Source",
        )
    names = list(source.sensor_names)
    if names != profile.sensor_names:
        source.close()
        raise ConfigError(
            "--source",
            f"the source's sensors ({', '.join(names)}) are not the desk's "
            f"({', '.join(profile.sensor_names)})",
        )
    return source
