"""Plugin clashes must not hide the list of plugins, and --strict must not say "skipped"."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from hapticdesk.plugin_loading import load_registry
from hapticdesk.registered import PluginError

from .test_runtime_registry import _env, plugin


def clashing_distribution(root: Path) -> None:
    """An installed distribution whose plugin registers an action called `log`, as a
    built-in does."""
    (root / "desk_clash.py").write_text(
        "from hapticdesk.hookspecs import hookimpl\n\n"
        "@hookimpl\n"
        "def register_actions(register):\n"
        "    register('log', lambda options, context: print, 'my log')\n"
        "    register('chime', lambda options, context: print, 'ring')\n"
    )
    info = root / "desk_clash-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: desk-clash\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text("[hapticdesk]\nclash = desk_clash\n")


def test_the_plugins_command_lists_a_name_clash_as_an_error_line(tmp_path):
    clashing_distribution(tmp_path)
    done = subprocess.run(
        [sys.executable, "-m", "hapticdesk", "plugins"],
        capture_output=True,
        text=True,
        env={**_env(), "PYTHONPATH": str(tmp_path)},
        timeout=60,
    )
    assert done.returncode == 1, done.stderr
    assert "Traceback" not in done.stderr
    assert "clash 1.0 (entry point of desk-clash)" in done.stdout  # the list is still shown
    assert "chime" in done.stdout  # and what the clashing plugin provides besides
    assert (
        "error: action `log` is registered by both plugin `hapticdesk.plugins.log` and plugin "
        "`clash`" in done.stdout
    )


def test_a_name_clash_still_stops_a_run():
    copycat = plugin(register_actions=lambda register: register("log", print, "mine"))
    with pytest.raises(PluginError, match="registered by both"):
        load_registry(entry_points=False, plugins=[("copycat", copycat)])
    listed = load_registry(
        entry_points=False, plugins=[("copycat", copycat)], conflicts_fatal=False
    )
    assert listed.actions["log"].plugin == "hapticdesk.plugins.log"  # the first one stays
    assert len(listed.errors) == 1


def test_strict_says_the_failure_is_fatal_not_that_something_is_skipped():
    def broken(register):
        raise RuntimeError("boom")

    with pytest.raises(PluginError) as err:
        load_registry(
            entry_points=False, strict=True, plugins=[("broken", plugin(register_actions=broken))]
        )
    assert "skipped" not in str(err.value)
    assert "fatal because of --strict" in str(err.value)
