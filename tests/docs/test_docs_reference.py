"""The documentation's reference against the code: every key the code takes must be in it.

The reference tables are made from the code when the site is built (scripts/docs_reference.py,
the site's hook). These tests find the keys a second way, from what the code does (a
validator's own list of allowed keys, argparse's actions, the hookspecs, the routes), and
fail when one is missing from the pages as built, when the code has a key the generator has no
words for, when a page names a table that does not exist, or when a layout in the docs does
not check cleanly.
"""

from __future__ import annotations

import dataclasses
import importlib.util
import re
import sys
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"


def _load(name: str) -> Any:
    spec = importlib.util.spec_from_file_location(name, ROOT / "scripts" / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # (dataclasses look their module up while they are made)
    spec.loader.exec_module(module)
    return module


reference = _load("docs_reference")


@pytest.fixture(scope="module")
def pages() -> dict[str, str]:
    """Every reference page as the site shows it: its markers replaced by their tables."""
    made: dict[str, Any] = {}
    return {
        p.name: reference.expand(p.read_text("utf-8"), str(p), made)
        for p in sorted((DOCS / "reference").glob("*.md"))
    }


@pytest.fixture(scope="module")
def registry() -> Any:
    from hapticdesk.plugin_loading import load_registry

    return load_registry(entry_points=False)


def missing(keys: Any, text: str) -> list[str]:
    """The keys not written in ``text`` as code (`key`)."""
    return sorted(k for k in keys if f"`{k}`" not in text)


def test_every_layout_key_region_key_binding_key_and_unit(pages: dict[str, str], registry: Any):
    from hapticdesk.gestures.layout import UNITS
    from hapticdesk.gestures.layout_bindings import BINDING_KEYS
    from hapticdesk.gestures.layout_reader import allowed_top_keys
    from hapticdesk.gestures.layout_regions import REGION_KEYS

    layout = pages["layout.md"]
    assert missing(allowed_top_keys(registry.layout_sections), layout) == []
    assert missing(REGION_KEYS, layout) == []
    assert missing(BINDING_KEYS, layout) == []
    assert missing(UNITS, layout) == []
    # the region shapes as a person writes them
    for form in ("[x0, y0, x1, y1]", "{center: [x, y], radius: r}", "[[x0, y0], [x1, y1]]"):
        assert form in layout, form


def test_every_gesture_and_every_option_with_its_default(pages: dict[str, str], registry: Any):
    from hapticdesk.gestures.options import GESTURE_OPTIONS, PHASES

    text = pages["gestures.md"]
    assert set(registry.recognizers) <= set(GESTURE_OPTIONS)  # built-ins: all described here
    for gesture, specs in GESTURE_OPTIONS.items():
        assert f"### `{gesture}`" in text, gesture
        section = text.split(f"### `{gesture}`", 1)[1].split("\n### ", 1)[0]
        for name, spec in specs.items():
            row = next((r for r in section.splitlines() if r.startswith(f"| `{name}` |")), None)
            assert row is not None, f"{gesture}.{name}"
            assert reference.show_value(spec, spec.default) in row, row
    assert missing(PHASES, text) == []


def test_every_action_with_every_option_its_validator_takes(pages: dict[str, str], registry):
    text = pages["actions.md"]
    for name, action in registry.actions.items():
        assert f"### `{name}`" in text, name
        section = text.split(f"### `{name}`", 1)[1].split("\n### ", 1)[0]
        # the keys the validator itself accepts, from its refusal of an unknown one
        taken = reference.allowed_keys(lambda v, a=action: a.check(v, "probe"))
        assert missing(taken, section) == [], name


def test_every_key_of_the_mqtt_section_and_every_control_command(pages, registry):
    from hapticdesk.runtime.control import COMMANDS

    section = registry.layout_sections["mqtt"]
    taken = reference.allowed_keys(lambda v: section.check(v, "mqtt", Path("layout.yaml")))
    assert "broker" in taken
    assert missing(taken, pages["layout.md"]) == []
    assert missing(COMMANDS, pages["mqtt.md"]) == []


def _arguments(parser: Any, prefix: str) -> list[tuple[str, str]]:
    """(command, argument) for every argument of ``parser`` and its sub-commands."""
    import argparse

    out = []
    for action in parser._actions:
        if isinstance(action, argparse._HelpAction):
            continue
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                out.append((prefix, f"hapticdesk {prefix} {name}".replace("  ", " ")))
                out += _arguments(sub, f"{prefix} {name}".strip())
            continue
        out += [(prefix, s) for s in action.option_strings] or [
            (prefix, action.metavar or action.dest)
        ]
    return out


def test_every_command_and_argument(pages: dict[str, str]) -> None:
    from hapticdesk import cli

    text = pages["cli.md"]
    with reference._only_hapticdesk_plugins():
        names = list(cli._available())
        assert "init" in names
        for name in names:
            assert f"`hapticdesk {name}`" in text, name
            sub = reference._subparsers(cli.build_parser(only=name))[name]
            section = text.split(f"`hapticdesk {name}`", 1)[1]
            for command, argument in _arguments(sub, name):
                assert argument in section, f"{command}: {argument}"


def test_every_profile_key_sensor_kind_and_estimation_setting(pages: dict[str, str]) -> None:
    from hapticdesk.files import profile_reader, profile_sensors, profile_surfaces
    from hapticdesk.files.profile import EstimationSettings

    text = pages["profile.md"]
    for keys in (
        profile_reader.PROFILE_KEYS,
        profile_sensors.SENSOR_KEYS,
        profile_surfaces.SURFACE_KEYS,
        profile_reader.DESK_KEYS,
        profile_sensors.ACCELEROMETER_KEYS,
        profile_sensors.SENSOR_KINDS,
    ):
        assert missing(keys, text) == []
    assert missing([f.name for f in dataclasses.fields(EstimationSettings)], text) == []


def test_every_file_column_event_key_route_and_hook(pages: dict[str, str]) -> None:
    from starlette.routing import Route

    from hapticdesk.commands.contacts import HEADER
    from hapticdesk.gestures.event import GestureEvent
    from hapticdesk.hookspecs import hookspec_names
    from hapticdesk.plugins.ui.server import UiServer

    files = pages["files.md"]
    assert missing(HEADER, files) == []
    assert missing([f.name for f in dataclasses.fields(GestureEvent)], files) == []
    assert "`t,fl_fx,fl_fy,fl_fz,fl_mx,fl_my" in files  # a recording's header, from a profile
    routes = UiServer(Path("layout.yaml"), None).app().routes
    http = pages["http.md"]
    for route in routes:
        methods = sorted((getattr(route, "methods", None) or {"GET"}) - {"HEAD"})
        path = route.path
        for method in methods if isinstance(route, Route) else ["WS" if path == "/ws" else "GET"]:
            assert f"`{method} {path}`" in http, (method, path)
    for kind in ("desk", "contact", "gesture", "notice", "action"):
        assert f"| `{kind}` |" in http, kind
    for hook in hookspec_names():
        assert f"### `{hook}(" in pages["hooks.md"], hook


def test_the_code_has_no_key_the_reference_has_no_words_for() -> None:
    undescribed = {
        name: made.undescribed
        for name, generate in reference.SECTIONS.items()
        if (made := generate()).undescribed
    }
    assert undescribed == {}


def test_every_marker_names_a_table_and_every_table_is_shown() -> None:
    used = set()
    for page in DOCS.rglob("*.md"):
        for name in reference.MARKER.findall(page.read_text("utf-8")):
            assert name in reference.SECTIONS, f"{page}: {name}"
            used.add(name)
    assert set(reference.SECTIONS) - used == set()


def test_an_unknown_marker_is_an_error_naming_its_page() -> None:
    with pytest.raises(ValueError, match="page.md: unknown reference marker 'layuot-keys'"):
        reference.expand("<!-- generated: layuot-keys -->", "page.md")


def _doc_layouts() -> list[tuple[str, int, str]]:
    """Every whole layout in the docs (a YAML block with `desk:` and `bindings:`)."""
    found = []
    for page in sorted(DOCS.rglob("*.md")):
        text = page.read_text("utf-8")
        for m in re.finditer(r"```yaml\n(.*?)```", text, re.S):
            block = m.group(1)
            if re.search(r"^desk:", block, re.M) and re.search(r"^bindings:", block, re.M):
                line = text[: m.start()].count("\n") + 2
                found.append((str(page.relative_to(ROOT)), line, block))
    return found


@pytest.mark.parametrize(("page", "line", "text"), _doc_layouts(), ids=lambda v: str(v)[:40])
def test_each_layout_in_the_docs_checks_without_a_warning(
    page: str, line: int, text: str, tmp_path: Path, registry: Any
) -> None:
    from hapticdesk.runtime.assembly import load_scene_layout

    path = tmp_path / "layout.yaml"
    path.write_text(text, encoding="utf-8")
    layout, _ = load_scene_layout(path, registry, None)  # a ConfigError fails the test
    assert layout.warnings == [], f"{page}:{line}: {layout.warnings}"


def test_the_docs_found_whole_layouts_to_check() -> None:
    pages = {page for page, _, _ in _doc_layouts()}
    assert {"docs/guides/buttons.md", "docs/guides/lights.md", "docs/reference/layout.md"} <= pages


def test_users_are_not_sent_where_they_cannot_go() -> None:
    """The team's DESIGN.md and ../shared/ are not in the project: no page may send a user
    there (their contracts are stated in the docs' reference)."""
    pages = [ROOT / "README.md", *DOCS.rglob("*.md"), *(ROOT / "examples").rglob("*.md")]
    # the package's own docstrings too: `help()` and an editor show them to a plugin's author
    pages += [*(ROOT / "core").rglob("*.py"), *(ROOT / "plugins").rglob("*.py")]
    for page in pages:
        text = page.read_text("utf-8")
        assert "DESIGN.md" not in text, page
        assert "../shared" not in text, page


def test_the_plugin_example_names_every_hook_and_where_they_are() -> None:
    from hapticdesk.hookspecs import hookspec_names

    text = (ROOT / "examples" / "plugin-example" / "README.md").read_text("utf-8")
    assert missing(hookspec_names(), text) == []
    assert "hapticdesk/hookspecs.py" not in text  # not a path a user has
    assert "`hapticdesk.hookspecs`" in text and "`core/hookspecs.py`" in text
