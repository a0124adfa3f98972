"""Tests of the example plugin: validation with positions, a real run, and its entry point."""

from __future__ import annotations

import importlib.metadata
from pathlib import Path

import hapticdesk_notify
import pytest

from hapticdesk.errors import ConfigError
from hapticdesk.gestures.event import GestureEvent
from hapticdesk.gestures.layout_reader import load_layout
from hapticdesk.plugin_loading import load_registry
from hapticdesk.runtime.dispatcher import ActionContext

LAYOUT = """\
desk: kitamura2017
units: cm
regions:
  lamp: {rect: [-10, -10, 10, 10]}
bindings:
  - gesture: tap
    region: lamp
    do: {notify: %s}
"""


@pytest.fixture
def registry():
    # the plugin is given directly: tests do not depend on what else is installed
    return load_registry(entry_points=False, plugins=[("notify", hapticdesk_notify)])


def write_layout(tmp_path: Path, options: str) -> Path:
    path = tmp_path / "layout.yaml"
    path.write_text(LAYOUT % options)
    return path


def load(path: Path, registry):
    return load_layout(
        path, action_names=registry.action_names, validate_action=registry.validate_action
    )


def test_registered_by_the_plugin(registry):
    assert registry.actions["notify"].plugin == "notify"
    assert registry.plugins["notify"].provides["actions"] == ["notify"]


def test_a_missing_file_option_names_the_line(tmp_path, registry):
    path = write_layout(tmp_path, "{message: hi}")
    with pytest.raises(ConfigError) as err:
        load(path, registry)
    assert str(err.value).startswith(f"{path}:8:")
    assert "missing `file`" in str(err.value)


def test_a_bad_template_names_the_line_and_column(tmp_path, registry):
    path = write_layout(tmp_path, '{file: out.log, message: "{{ regoin }}"}')
    with pytest.raises(ConfigError) as err:
        load(path, registry)
    assert str(err.value).startswith(f"{path}:8:")
    assert "regoin" in str(err.value)


def test_appends_a_line_per_gesture(tmp_path, registry):
    layout = load(
        write_layout(tmp_path, '{file: taps.log, message: "{{ region }} {{ t }}"}'), registry
    )
    use = layout.bindings[0].actions[0]
    context = ActionContext("study", layout_path=layout.path)
    action = registry.actions["notify"].load()(use.options, context)
    for t in (1.5, 2.5):
        action(GestureEvent(t, "tap", "lamp", 0.0, 0.0))
    assert (tmp_path / "taps.log").read_text().splitlines() == ["lamp 1.5", "lamp 2.5"]


def test_installed_entry_point_is_found():
    """When the package is installed, hapticdesk finds it through its entry point."""
    try:
        dist = importlib.metadata.distribution("hapticdesk-example-plugin")
    except importlib.metadata.PackageNotFoundError:
        pytest.skip("install this package (pip install -e examples/plugin-example) to test it")
    registry = load_registry(entry_points=True)
    assert registry.actions["notify"].plugin == "notify"
    assert registry.plugins["notify"].version == dist.version
