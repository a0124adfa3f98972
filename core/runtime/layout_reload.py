"""A running desk's layout replaced: read, checked and built beside the running one, swapped in
between two blocks once the touch in progress has ended.

A reload (SIGHUP, ``reload`` or ``layout NAME`` on MQTT, a save from the browser UI) keeps the
estimator, its zero, the source, the event sinks and the shared connections; it brings a new
gesture engine and new action lanes. What the operator alone may add or change (programs run,
secrets read, connections) is refused (:mod:`.operator_secrets`), as is another desk.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from hapticdesk.gestures.event import GestureEvent
from hapticdesk.runtime.assembly import Assembly, build_routes, load_switch_layout
from hapticdesk.runtime.dispatcher import Route
from hapticdesk.runtime.operator_secrets import OperatorSecrets

if TYPE_CHECKING:
    from hapticdesk.gestures.engine import GestureEngine
    from hapticdesk.gestures.layout import Layout

log = logging.getLogger("hapticdesk.runtime.service")

#: the longest a reloaded layout waits (sample time) for the touch in progress to end
MAX_SWAP_WAIT_S = 30.0
#: what a refusal names as the way the layout came
RELOAD_WAYS = "a reload (SIGHUP, `reload` or `layout` on MQTT, a save from the browser UI)"


@dataclass
class WaitingLayout:
    """A reloaded layout, built and checked, waiting for the running engine to be idle."""

    layout: Layout
    engine: GestureEngine
    routes: list[Route]
    asked_t: float | None  # the sample time of the reload


class LayoutReloads:
    """The reloads of one run's layout (module docstring); ``emit`` sends the gesture events
    the running engine still decides when it is replaced."""

    def __init__(
        self,
        scene: Assembly,
        operator_secrets: OperatorSecrets,
        emit: Callable[[list[GestureEvent]], None],
        drain_timeout_s: float,
    ) -> None:
        self.scene = scene
        self.operator_secrets = operator_secrets
        self.emit = emit
        self.drain_timeout_s = drain_timeout_s
        #: a reloaded layout built and waiting for the touch in progress to end
        self.waiting: WaitingLayout | None = None

    def prepare(self, path: Path, name: str | None, asked_t: float | None) -> str:
        """Load ``path`` and build its engine and actions, to take over at :meth:`take`; a
        line saying what was done (ConfigError: the running layout stays)."""
        layout = self._load_checked(path)
        engine, routes, before = self._build(layout, path)
        what = f"layout `{name}` ({path})" if name else f"reloaded {path}"
        line = f"{what}: {len(layout.bindings)} bindings; the zero and connections are kept"
        # shared connections were opened from the first layout's sections and are kept
        changed = [
            f"`{section}:`"
            for section in self.scene.registry.layout_sections
            if before.get(section) != layout.raw.get(section)
        ]
        if changed:
            line += (
                f" ({', '.join(changed)} changed: its connection settings take effect at the "
                "next start)"
            )
        self.drop()  # a newer layout replaces one still waiting
        self.waiting = WaitingLayout(layout, engine, routes, asked_t)
        return line

    def take(self, t_last: float | None) -> bool:
        """Swap in the waiting layout, if any, once the running engine is idle: a touch
        finishes under the layout it began in (a reload during a 3 s hold had fired a second
        long press, and a toggle bound to it twice). A touch still held
        :data:`MAX_SWAP_WAIT_S` of sample time after the reload is cancelled (phase `cancel`,
        never a release) and the new layout taken. True when swapped (or nothing waited)."""
        waiting, scene = self.waiting, self.scene
        if waiting is None:
            return True
        if not scene.engine.idle:
            asked = waiting.asked_t
            if asked is None or t_last is None or t_last - asked < MAX_SWAP_WAIT_S:
                return False
            log.warning(
                "control: a touch was still held %g s after the reload; it is cancelled and "
                "the new layout taken",
                MAX_SWAP_WAIT_S,
            )
            self.emit(scene.engine.cancel(t_last))
            waiting.engine.join_contact()  # (the held finger is nobody's new touch)
        if t_last is not None:  # what the old layout was deciding is decided
            self.emit(scene.engine.flush(t_last))
        scene.estimator.use_second_finger(
            scene.profile.estimation.second_finger or waiting.engine.needs_second_finger
        )
        scene.dispatcher.replace_routes(waiting.routes, self.drain_timeout_s)
        scene.engine, scene.layout = waiting.engine, waiting.layout
        self.waiting = None
        return True

    def drop(self) -> None:
        """Forget a layout still waiting (its actions' lanes closed)."""
        if self.waiting is not None:
            for route in self.waiting.routes:
                for lane in route.lanes:
                    lane.close(0.0)
            self.waiting = None

    def _load_checked(self, path: Path) -> Layout:
        """The layout at ``path``, refused when it changes what is the operator's alone or
        is for another desk."""
        scene, context = self.scene, self.scene.context
        layout, _ = load_switch_layout(
            path, scene.registry, scene.desk_override, scene.profile, context.desk_name
        )
        refused = self.operator_secrets.refusal(
            layout.raw, Path(path), scene.registry, RELOAD_WAYS, "restart the desk to use it"
        )
        if refused is not None:
            raise refused
        for warning in layout.warnings:
            log.warning("%s", warning)
        return layout

    def _build(
        self, layout: Layout, path: Path
    ) -> tuple[GestureEngine, list[Route], dict[str, Any]]:
        """The layout's engine and routes, the actions' context moved to it; and the settings
        of the layout before (the context is put back when building fails)."""
        from hapticdesk.gestures.engine import GestureEngine  # (the recognizers: at a reload only)

        scene, context = self.scene, self.scene.context
        before = (context.layout, context.settings, context.layout_path)
        context.layout, context.settings, context.layout_path = layout, layout.raw, Path(path)
        try:
            routes = (
                build_routes(layout, scene.registry, context, scene.action_timeout_s)
                if scene.actions
                else []
            )
            engine = GestureEngine(
                layout,
                recognizer_types=scene.registry.recognizer_types(),
                position_delay_s=scene.estimator.position_delay_s,
            )
        except BaseException:
            context.layout, context.settings, context.layout_path = before
            raise
        return engine, routes, dict(before[1])
