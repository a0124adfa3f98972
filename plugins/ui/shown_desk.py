"""The desk the page shows and edits: its layout file, the run attached, and how it is drawn.

A :class:`ShownDesk` is what every endpoint of the UI works on: the layout file (loaded as
``check`` loads it), the desk profile overriding its ``desk:``, the registry of the run, the
run itself once attached, and what the operator started the desk with (the baseline a save
from the page is compared with, and the folders a page's layout may read). Its
:meth:`~ShownDesk.message` is the page's picture of the desk: outline, surfaces, sensors,
regions in metres (:func:`desk_message`).
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any

from hapticdesk.errors import ConfigError
from hapticdesk.files.yamlfile import load_marked_yaml
from hapticdesk.plugin_loading import load_registry
from hapticdesk.plugins.mqtt.demo import examples_dir
from hapticdesk.plugins.ui.guard import operator_reads
from hapticdesk.registry import Registry
from hapticdesk.runtime.assembly import load_scene_layout
from hapticdesk.runtime.operator_secrets import OperatorSecrets

if TYPE_CHECKING:
    from hapticdesk.files.profile import DeskProfile
    from hapticdesk.gestures.layout import Layout
    from hapticdesk.runtime.service import Runtime


class ShownDesk:
    """The layout file ``layout_path`` shown on ``desk`` (a profile over its ``desk:``, or
    None), with the ``runtime`` attached (None while nothing runs). ``read_only``: the shipped
    demo layout, shown and never written."""

    def __init__(
        self,
        layout_path: Path,
        registry: Registry | None,
        desk: DeskProfile | None = None,
        read_only: bool = False,
    ) -> None:
        self.layout_path = Path(layout_path)
        self._registry = registry
        self.desk = desk
        self.read_only = read_only
        self.runtime: Runtime | None = None
        # the layout as the operator started with it: what a page may not add to or change
        # (read now; its held parts are made once the run's registry is known)
        try:
            self._started_doc: Any = load_marked_yaml(self.layout_path)
        except ConfigError:
            self._started_doc = None
        self._secrets: OperatorSecrets | None = None

    @property
    def registry(self) -> Registry:
        """The run's registry (the installed plugins' when none was given)."""
        if self._registry is None:
            self._registry = load_registry()
        return self._registry

    @registry.setter
    def registry(self, value: Registry) -> None:
        self._registry = value

    def load(self, text: str | None = None) -> tuple[Layout, DeskProfile]:
        """``text`` (a layout the page sent; the request's reads are confined) or, without
        it, the layout file (read as the operator's), loaded as `check` would load the
        layout file; ConfigError at its first problem."""
        if text is None:
            return operator_reads(load_scene_layout, self.layout_path, self.registry, self.desk)
        return load_scene_layout(self.layout_path, self.registry, self.desk, text=text)

    def message(self, layout: Layout | None = None) -> dict[str, Any]:
        """The desk message: of ``layout`` (one just saved, which the sensing thread swaps in
        at its next block), else of what runs, else of the layout file; a ``notice`` saying
        why when the file does not load."""
        runtime = self.runtime
        try:
            if layout is not None:
                profile = runtime.scene.profile if runtime is not None else layout.desk
                message = desk_message(profile, layout, live=runtime is not None)
            elif runtime is not None:
                message = desk_message(runtime.scene.profile, runtime.scene.layout, live=True)
            else:
                layout, profile = self.load()
                message = desk_message(profile, layout, live=False)
        except ConfigError as err:
            return {"type": "notice", "kind": "layout", "message": str(err)}
        # whether the running desk runs its layout's actions (false for `hapticdesk ui`
        # without --actions: the page says so), null when nothing runs
        message["actions"] = None if runtime is None else bool(runtime.scene.actions)
        return message

    def operator_secrets(self) -> OperatorSecrets:
        """What only the operator may add or change, from the layout file as this server
        started with it (not as the last save left it) and the layouts it names."""
        if self._secrets is None:
            doc = self._started_doc if isinstance(self._started_doc, dict) else {}
            named = {}
            layouts = doc.get("layouts")
            if isinstance(layouts, dict):
                named = {
                    str(k): self.layout_path.parent / Path(str(v)).expanduser()
                    for k, v in layouts.items()
                }
            self._secrets = operator_reads(
                OperatorSecrets.from_start, doc, self.layout_path, self.registry, named
            )
        return self._secrets

    def read_roots(self) -> list[Path]:
        """The folders a layout from the page may read: the layout's, its desk profile's (of
        the file as it is now, before any page touched it), the shipped profiles and examples
        (a page's `desk: /etc/passwd` had been read and quoted back in the error)."""
        roots = [self.layout_path.parent, examples_dir()]
        roots.append(Path(str(resources.files("hapticdesk.profiles"))))
        try:
            _, profile = self.load()
            if profile.path is not None:
                roots.append(Path(profile.path).parent)
        except ConfigError:
            pass
        return roots


def desk_message(profile: DeskProfile, layout: Layout, *, live: bool) -> dict[str, Any]:
    """The WebSocket's first message: the desk's outline, surfaces and regions in metres."""
    import numpy as np

    surfaces = [
        {
            "name": s.name,
            "horizontal": abs(float(np.dot(s.normal, [0.0, 0.0, 1.0]))) > 0.99,
            "height": float(s.origin[2]),
            "polygon": np.round(s.polygon, 5).tolist(),
        }
        for s in profile.surfaces
    ]
    regions = [
        {
            "name": name,
            "kind": r.kind,
            "surface": r.surface,
            "outline": np.round(r.outline, 5).tolist(),
            "center": None if r.center is None else np.round(r.center, 5).tolist(),
            "radius": float(r.radius),
            "axis": None if r.axis is None else np.round(r.axis, 5).tolist(),
        }
        for name, r in layout.regions.items()
    ]
    bindings = [
        {
            "gesture": b.gesture,
            "region": b.region,
            "actions": [u.name for u in b.actions],
            "line": b.position.line,
        }
        for b in layout.bindings
    ]
    top = profile.surfaces[0].polygon if profile.surfaces else np.zeros((0, 2))
    return {
        "type": "desk",
        "name": profile.name,
        "live": live,
        "units": layout.units,
        "layout": str(layout.path),
        "outline": np.round(top, 5).tolist(),
        "surfaces": surfaces,
        "sensors": [
            {"name": s.name, "x": float(s.position[0]), "y": float(s.position[1])}
            for s in profile.sensors
        ],
        "regions": regions,
        "bindings": bindings,
        "templates": sorted(layout.templates),
    }
