"""One door: the core reaches plugins only through the registry's hooks (STYLE.md 15, 16)."""

from __future__ import annotations

import ast
from pathlib import Path
from types import SimpleNamespace

import pytest

from hapticdesk.errors import ConfigError
from hapticdesk.hookspecs import hookimpl
from hapticdesk.plugin_loading import load_registry
from hapticdesk.registry import DEFAULT_PLUGINS
from hapticdesk.runtime.assembly import build_scene

CORE = Path(__file__).resolve().parents[2] / "core"


def _plugin_mentions(path: Path) -> list[str]:
    """Imports of, and texts naming, a hapticdesk.plugins module in one core file."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        names: list[str] = []
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            names = [node.module or ""]
        elif isinstance(node, ast.Constant) and isinstance(node.value, str):
            if node.value.startswith("hapticdesk.plugins"):
                names = [node.value]
        found += [f"{path.name}:{node.lineno}: {n}" for n in names if "hapticdesk.plugins" in n]
    return found


def test_the_core_names_plugins_only_in_the_table_of_built_ins():
    mentions = [m for p in sorted(CORE.rglob("*.py")) for m in _plugin_mentions(p)]
    expected = [m for m in mentions if m.startswith("registry.py:")]
    assert [m.split(": ")[1] for m in expected] == list(DEFAULT_PLUGINS)
    assert mentions == expected


def test_a_plugin_whose_event_sink_crashes_stops_the_run_naming_it(tmp_path, paper_desk):
    def event_sink(context):
        raise RuntimeError("no sink today")

    plugin = SimpleNamespace(event_sink=hookimpl(event_sink))
    registry = load_registry(entry_points=False, plugins=[("sinky", plugin)])
    layout = tmp_path / "layout.yaml"
    layout.write_text(
        "desk: kitamura2017\nregions: {b: {rect: [-0.3, -0.2, -0.1, 0]}}\n"
        "bindings: [{gesture: tap, region: b, do: log}]\n"
    )
    scene = Path(__file__).resolve().parents[2] / "examples" / "scenes" / "demo.yaml"
    with pytest.raises(ConfigError, match="plugin `sinky` failed in event_sink: RuntimeError"):
        build_scene(layout, f"sim:{scene}", registry, speed=0)
