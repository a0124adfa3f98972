"""The ``sim`` source: a simulated desk playing a scripted scene.

    hapticdesk run --layout L --source sim:examples/scenes/demo.yaml --speed 1

The simulator (:mod:`hapticdesk.sim`, imported only when used) computes the sensors'
readings; blocks are paced by sample time like a replay (``--speed 0``: as fast as possible).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

from hapticdesk.errors import ConfigError
from hapticdesk.hookspecs import hookimpl

if TYPE_CHECKING:  # the hooks are loaded for every command, even `--help`: no numpy here
    from hapticdesk.files.profile import DeskProfile
    from hapticdesk.runtime.source import Source


def open_sim(
    argument: str,
    profile: DeskProfile,
    *,
    speed: float = 1.0,
    seed: int | None = None,
    **options: Any,
) -> Source:
    """``sim:SCENE.yaml`` on ``profile`` (``seed`` None: the scene's own)."""
    if not argument:
        raise ConfigError("--source", "sim needs a scene file: sim:SCENE.yaml")
    if not Path(argument).expanduser().is_file():
        raise ConfigError("--source", f"sim: no such scene file {argument}")
    from hapticdesk.sim import SimSource, load_scene

    scene = load_scene(Path(argument).expanduser())
    return SimSource(profile, scene, seed=seed).paced(speed)


@hookimpl
def register_sources(register: Any) -> None:
    register("sim", open_sim, "a simulated desk playing a scene file, at --speed")
