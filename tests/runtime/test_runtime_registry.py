"""The plugin registry: built-ins through the public API, entry points loaded one by one,
duplicates rejected naming both plugins, and failures isolated (or fatal under --strict)."""

from __future__ import annotations

import importlib
import json
import logging
import os
import subprocess
import sys
import textwrap
from pathlib import Path
from types import SimpleNamespace

import pytest

from hapticdesk.errors import ConfigError
from hapticdesk.hookspecs import hookimpl
from hapticdesk.plugin_loading import load_registry
from hapticdesk.registered import PluginError
from hapticdesk.registry import DEFAULT_PLUGINS, DISABLE_AUTOLOAD_ENV


def plugin(**hooks):
    """A plugin object with the given hookimpls."""
    return SimpleNamespace(**{name: hookimpl(fn) for name, fn in hooks.items()})


def test_builtins_are_registered_through_the_same_hooks():
    registry = load_registry(entry_points=False)
    assert list(registry.plugins) == list(DEFAULT_PLUGINS)
    assert set(registry.sources) == {"sim", "replay", "can", "serial"}
    assert set(registry.actions) >= {"mqtt", "exec", "http", "log"}
    assert registry.actions["mqtt"].plugin == "hapticdesk.plugins.mqtt"
    assert registry.sources["can"].plugin == "hapticdesk.plugins.can"
    assert registry.plugins["hapticdesk.plugins.mqtt"].provides["actions"] == ["mqtt"]
    assert registry.warnings == []


def test_a_duplicate_name_is_rejected_naming_both_plugins():
    copycat = plugin(register_actions=lambda register: register("log", print, "mine"))
    with pytest.raises(PluginError) as err:
        load_registry(entry_points=False, plugins=[("copycat", copycat)])
    message = str(err.value)
    assert "`log`" in message
    assert "hapticdesk.plugins.log" in message and "copycat" in message


def test_a_plugin_whose_hook_raises_is_skipped_with_a_warning(caplog):
    def broken(register):
        register("half", print)
        raise RuntimeError("database not found")

    with caplog.at_level(logging.WARNING):
        registry = load_registry(
            entry_points=False, plugins=[("broken", plugin(register_actions=broken))]
        )
    assert "half" not in registry.actions  # nothing of a failed registration is kept
    assert "log" in registry.actions  # the others are untouched
    assert any("broken" in w and "database not found" in w for w in registry.warnings)
    assert "broken" in caplog.text


def test_strict_makes_a_failing_plugin_fatal():
    def broken(register):
        raise RuntimeError("boom")

    with pytest.raises(PluginError, match="broken.*boom"):
        load_registry(
            entry_points=False, strict=True, plugins=[("broken", plugin(register_actions=broken))]
        )


def test_a_hookimpl_may_take_fewer_arguments_than_the_spec():
    calls = []
    registry = load_registry(
        entry_points=False, plugins=[("quiet", plugin(startup=lambda: calls.append("up")))]
    )
    registry.notify("startup", desk=None, layout=None)
    assert calls == ["up"]


def test_an_unknown_hook_name_is_not_a_valid_plugin():
    typo = plugin(register_action=lambda register: None)  # missing "s"
    registry = load_registry(entry_points=False, plugins=[("typo", typo)])
    assert "typo" not in registry.plugins
    assert any("typo" in w and "not a valid hapticdesk plugin" in w for w in registry.warnings)


def test_bad_registrations_are_reported_as_the_plugins_fault():
    bad_name = plugin(register_actions=lambda register: register("has space", print))
    with pytest.raises(PluginError, match="bad.*identifiers"):
        load_registry(entry_points=False, plugins=[("bad", bad_name)])
    no_factory = plugin(register_sources=lambda register: register("x", 42))
    with pytest.raises(PluginError, match="expected a callable"):
        load_registry(entry_points=False, plugins=[("nofactory", no_factory)])


def test_unknown_action_and_source_list_what_is_installed():
    registry = load_registry(entry_points=False)
    with pytest.raises(
        ConfigError, match="unknown action `lamp`; installed actions: exec, http, log, mqtt"
    ):
        registry.validate_action("lamp", {}, "layout.yaml:3:5")
    with pytest.raises(
        ConfigError, match="unknown source kind `usb`; installed: can, replay, serial, sim"
    ):
        registry.source("usb")


def test_a_lazy_factory_that_cannot_be_imported_names_its_plugin():
    lazy = plugin(register_sources=lambda register: register("ghost", "no_such_module_xyz:open"))
    registry = load_registry(entry_points=False, plugins=[("ghosts", lazy)])
    with pytest.raises(PluginError, match="`ghost` from plugin `ghosts` cannot be loaded"):
        registry.sources["ghost"].load()


def test_a_crashing_validator_is_the_plugins_fault_not_the_layouts():
    def validate(options, position):
        raise KeyError("oops")

    crashing = plugin(register_actions=lambda register: register("beep", print, validate=validate))
    registry = load_registry(entry_points=False, plugins=[("beeper", crashing)])
    with pytest.raises(PluginError, match="layout.yaml:4:9: plugin `beeper` crashed validating"):
        registry.validate_action("beep", {}, "layout.yaml:4:9")


# --- entry points: the only tests that load installed plugins ----------------------------------


def make_distribution(root: Path) -> None:
    """A fake installed distribution with two entry points: one good, one that cannot import."""
    (root / "desk_beeper.py").write_text(
        textwrap.dedent(
            """
            from hapticdesk.hookspecs import hookimpl

            @hookimpl
            def register_actions(register):
                register("beep", lambda options, context: print, "ring a bell")
            """
        )
    )
    (root / "desk_broken.py").write_text("import a_module_that_is_not_installed\n")
    info = root / "desk_plugins-2.5.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: desk-plugins\nVersion: 2.5.1\n")
    (info / "entry_points.txt").write_text(
        "[hapticdesk]\nbeeper = desk_beeper\nbroken = desk_broken\n"
    )


def test_entry_points_are_loaded_each_on_its_own(tmp_path, monkeypatch):
    make_distribution(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))
    importlib.invalidate_caches()
    registry = load_registry(entry_points=True)  # the only test that loads entry points
    assert registry.actions["beep"].plugin == "beeper"
    assert registry.plugins["beeper"].version == "2.5.1"
    assert registry.plugins["beeper"].origin == "entry point of desk-plugins"
    assert "broken" not in registry.plugins
    [warning] = [w for w in registry.warnings if "broken" in w]
    assert "a_module_that_is_not_installed" in warning and "skipped" in warning
    with pytest.raises(PluginError, match="broken"):
        load_registry(entry_points=True, strict=True)
    assert "beeper" not in load_registry().plugins  # not when autoloading is disabled


def test_plugins_command_lists_versions_and_what_each_provides(tmp_path):
    make_distribution(tmp_path)
    env_path = f"{tmp_path}"
    done = subprocess.run(
        [sys.executable, "-m", "hapticdesk", "plugins", "--json"],
        capture_output=True,
        text=True,
        env={**_env(), "PYTHONPATH": env_path},
        check=True,
    )
    rows = [json.loads(line) for line in done.stdout.splitlines()]
    by_name = {row.get("name"): row for row in rows}
    assert by_name["beeper"]["version"] == "2.5.1"
    assert by_name["beeper"]["actions"] == ["beep"]
    assert by_name["hapticdesk.plugins.replay"]["sources"] == ["replay"]
    assert any("broken" in row.get("warning", "") for row in rows)
    text = subprocess.run(
        [sys.executable, "-m", "hapticdesk", "plugins"],
        capture_output=True,
        text=True,
        env={**_env(), "PYTHONPATH": env_path},
        check=True,
    ).stdout
    assert "beeper 2.5.1 (entry point of desk-plugins)" in text
    assert "warning: plugin `broken`" in text
    strict = subprocess.run(
        [sys.executable, "-m", "hapticdesk", "plugins", "--strict"],
        capture_output=True,
        text=True,
        env={**_env(), "PYTHONPATH": env_path},
    )
    assert strict.returncode == 2
    assert "Traceback" not in strict.stderr and "broken" in strict.stderr


def _env() -> dict[str, str]:
    """This environment without PYTHONPATH, and with entry-point autoloading on."""
    skip = ("PYTHONPATH", DISABLE_AUTOLOAD_ENV)
    return {k: v for k, v in os.environ.items() if k not in skip}
