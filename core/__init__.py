"""hapticdesk: a desk on force/torque sensors as a touch and gesture surface.

The flow runs one way: source → estimator → gestures → dispatcher → actions (see
docs/architecture.md). Rooms: :mod:`hapticdesk.estimator` (contacts from wrenches),
:mod:`hapticdesk.gestures` (contacts to gesture events), :mod:`hapticdesk.runtime` (a run:
sources, dispatcher), :mod:`hapticdesk.files` (profiles, recordings, YAML), the plugin door
(:mod:`hapticdesk.hookspecs`, :mod:`hapticdesk.registry`), and the tools around them
(``sim``, ``canbus``, ``bench``, ``analysis``, ``commands``).

Modules that moved when the package was grouped by the flow stay importable by their old
names (:data:`MOVED`), so plugins and scripts written against them keep working.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import sys
from types import ModuleType

__version__ = "0.1.0"

#: old module name -> where it lives now
MOVED: dict[str, str] = {
    "hapticdesk.contacts": "hapticdesk.estimator.contacts",
    "hapticdesk.filters": "hapticdesk.estimator.filters",
    "hapticdesk.geometry": "hapticdesk.estimator.geometry",
    "hapticdesk.error_model": "hapticdesk.estimator.error_model",
    "hapticdesk.profile": "hapticdesk.files.profile",
    "hapticdesk.recording": "hapticdesk.files.recording",
    "hapticdesk.readers": "hapticdesk.recordings",
    "hapticdesk.files.readers": "hapticdesk.recordings",
    "hapticdesk.yamlfile": "hapticdesk.files.yamlfile",
    "hapticdesk.gestures.strokefile": "hapticdesk.files.strokefile",
    "hapticdesk.source": "hapticdesk.runtime.source",
    "hapticdesk.source_spec": "hapticdesk.runtime.source_spec",
    "hapticdesk.dispatcher": "hapticdesk.runtime.dispatcher",
    "hapticdesk.gestures.unistroke": "hapticdesk.gestures.strokes.unistroke",
    "hapticdesk.gestures.shapes": "hapticdesk.gestures.strokes.shapes",
}


class _MovedModuleFinder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Imports an old module name as the module that now holds it (the same object)."""

    def find_spec(
        self, fullname: str, path: object, target: object = None
    ) -> importlib.machinery.ModuleSpec | None:
        if fullname not in MOVED:
            return None
        return importlib.machinery.ModuleSpec(fullname, self)

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType:
        module = importlib.import_module(MOVED[spec.name])
        sys.modules[spec.name] = module
        return module

    def exec_module(self, module: ModuleType) -> None:
        """Nothing to run: the module was executed under its new name."""


if not any(isinstance(finder, _MovedModuleFinder) for finder in sys.meta_path):
    sys.meta_path.append(_MovedModuleFinder())
