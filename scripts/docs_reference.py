"""The documentation's reference, generated from the code's own definitions.

The reference pages (docs/reference/*.md) are prose with markers, ``<!-- generated: NAME -->``;
when the site is built (``mkdocs build --strict``: this file is the site's hook, mkdocs.yml
``hooks:``) each marker is replaced by the table NAME, made here from the code: the layout
reader's keys, the gesture options and their defaults (core/gestures/options.py), the
registered actions' option tables, the command line (argparse), the desk profile's keys and
estimation settings, the browser UI's routes, the MQTT plugin's section, the plugin hooks.
Where the code has a key but no words for it (a layout key, a profile key, a route), the words
are in a table here; a key without them is listed in :attr:`Generated.undescribed`, which the
build reports as a warning (so ``--strict`` fails) and tests/docs/test_docs_reference.py as a
failure, beside its own check that every key the code accepts appears.

    python scripts/docs_reference.py OUT_DIR    # the reference pages with their tables
"""

from __future__ import annotations

import argparse
import ast
import contextlib
import dataclasses
import inspect
import logging
import os
import re
import sys
import textwrap
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

log = logging.getLogger("mkdocs.hooks.reference")

MARKER = re.compile(r"<!--\s*generated:\s*([a-z0-9-]+)\s*-->")


@dataclass
class Generated:
    """One generated table: its Markdown, the code's keys it covers, and the keys the code has
    but no description here."""

    markdown: str
    keys: list[str] = field(default_factory=list)
    undescribed: list[str] = field(default_factory=list)


# --- small helpers --------------------------------------------------------------------------


def table(header: list[str], rows: list[list[str]]) -> str:
    """A Markdown table; a ``|`` inside a cell is escaped."""

    def cell(text: str) -> str:
        return str(text).replace("|", "\\|").replace("\n", " ")

    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(cell(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def code(text: Any) -> str:
    return f"`{text}`"


_ROLE = re.compile(r":(?:class|func|meth|data|attr|mod):`(~?)([\w.]+)`")


def plain_docstring(text: str | None) -> str:
    """A docstring as Markdown: Sphinx roles as code, ``double`` backticks as single."""
    text = inspect.cleandoc(text or "")
    text = _ROLE.sub(
        lambda m: code(m.group(2).rsplit(".", 1)[-1] if m.group(1) else m.group(2)), text
    )
    return text.replace("``", "`")


def _described(keys: list[str], words: dict[str, str], out: Generated) -> list[tuple[str, str]]:
    """(key, words) for every key; a key without words is noted in ``out.undescribed``."""
    rows = []
    for key in keys:
        out.keys.append(key)
        if key not in words:
            out.undescribed.append(key)
        rows.append((key, words.get(key, "**not described yet**")))
    return rows


def key_table(
    keys: Any, words: dict[str, str], header: tuple[str, str] = ("key", "what"), note: str = ""
) -> Generated:
    """A table of ``keys`` (from the code) with their ``words`` (from here), and ``note``."""
    out = Generated("")
    rows = [[code(k), w] for k, w in _described(list(keys), words, out)]
    out.markdown = table(list(header), rows) + note
    return out


@contextlib.contextmanager
def _only_hapticdesk_plugins() -> Iterator[None]:
    """The built-in plugins alone: the reference is of hapticdesk, not of what else happens
    to be installed (the example plugin, say)."""
    from hapticdesk import cli
    from hapticdesk.registry import DISABLE_AUTOLOAD_ENV

    saved = os.environ.get(DISABLE_AUTOLOAD_ENV)
    os.environ[DISABLE_AUTOLOAD_ENV] = "1"
    cli._plugin_commands.cache_clear()
    try:
        yield
    finally:
        if saved is None:
            os.environ.pop(DISABLE_AUTOLOAD_ENV, None)
        else:
            os.environ[DISABLE_AUTOLOAD_ENV] = saved
        cli._plugin_commands.cache_clear()


def registry() -> Any:
    from hapticdesk.plugin_loading import load_registry

    return load_registry(entry_points=False)


# --- the layout -----------------------------------------------------------------------------

LAYOUT_KEY_WORDS = {
    "desk": "the desk profile: a name from the shipped profiles (`kitamura2017`) or a path, "
    "relative to the layout; `--desk` overrides it",
    "desk_name": "the desk's name in what it sends (MQTT topics, `{{ desk }}` in templates); "
    "letters, digits, `_` and `-`; default: the profile's name",
    "units": "the unit of every length below: `m` (default), `cm` or `mm`",
    "regions": "named areas of the desk: `{name: {rect | circle | polygon, axis?, surface?}}`",
    "bindings": "a list of bindings, each a gesture (in a region, or anywhere) and what it does; "
    "may be empty (`[]`) while a layout is being made: `check` then warns that nothing will "
    "happen",
    "settings": "layout-wide gesture settings: `{gesture: {option: value}}` (the recognizer's "
    "options; see Gestures)",
    "templates": "your own stroke shapes: `{shape: [files, folders or inline [x, y] points]}`, or "
    "one folder holding a sub-folder per shape",
    "builtin_templates": "`false` matches strokes against your `templates:` only (default `true`)",
    "description": "free text, for people",
    "layouts": "other layout files a running desk can switch to: `{name: file.yaml}` (the MQTT "
    '`set` command `{"layout": name}`); each is checked, by `check` and as `run` starts, as '
    "the switch loads it: valid, for the same desk and `desk_name`",
}

REGION_KEY_WORDS = {
    "rect": "`[x0, y0, x1, y1]`: the lower-left then the upper-right corner, x0 < x1, y0 < y1",
    "circle": "`{center: [x, y], radius: r}`",
    "polygon": "`[[x, y], [x, y], [x, y], ...]`: 3 to 500 points in order around the outline "
    "(it must not cross itself)",
    "axis": "makes the region a slider: `x`, `y`, or two points `[[x0, y0], [x1, y1]]` (value 0 "
    "at the first, 1 at the second)",
    "surface": "which of the desk's surfaces the region is on (default: the first, `top` on the "
    "shipped desks)",
    "description": "free text, for people",
}

BINDING_KEY_WORDS = {
    "gesture": "the gesture's name (see Gestures)",
    "region": "the region's name; `stroke` and `swipe` may leave it out (anywhere on the desk)",
    "do": "one action `{name: {options}}`, or a list of them; each runs on its own thread",
    "description": "free text, for people",
}


def layout_keys() -> Generated:
    from hapticdesk.gestures.layout_reader import LAYOUT_KEYS

    out = Generated("")
    reg = registry()
    rows = [[code(k), words] for k, words in _described(sorted(LAYOUT_KEYS), LAYOUT_KEY_WORDS, out)]
    for name, section in sorted(reg.layout_sections.items()):
        out.keys.append(name)
        rows.append(
            [code(name), f"{section.description} (claimed by the plugin `{section.plugin}`)"]
        )
    out.markdown = table(["key", "what"], rows)
    return out


def region_keys() -> Generated:
    from hapticdesk.gestures.layout_regions import REGION_KEYS, REGION_RULE

    order = ["rect", "circle", "polygon", "axis", "surface", "description"]
    keys = [k for k in order if k in REGION_KEYS] + sorted(set(REGION_KEYS) - set(order))
    note = f"\n\nA region's name {REGION_RULE}. Give exactly one of `rect`, `circle`, `polygon`."
    return key_table(keys, REGION_KEY_WORDS, note=note)


def binding_keys() -> Generated:
    from hapticdesk.gestures.layout_bindings import BINDING_KEYS

    keys = [k for k in ("gesture", "region", "do", "description") if k in BINDING_KEYS]
    keys += sorted(set(BINDING_KEYS) - set(keys))
    note = "\n\nAny other key of a binding is one of its gesture's options (see Gestures)."
    return key_table(keys, BINDING_KEY_WORDS, note=note)


def units() -> Generated:
    from hapticdesk.gestures.layout import UNITS

    out = Generated("", keys=list(UNITS))
    rows = [[code(u), f"{m:g} m"] for u, m in UNITS.items()]
    out.markdown = table(["`units:`", "one unit is"], rows)
    return out


# --- gestures -------------------------------------------------------------------------------

#: what each built-in gesture's event carries besides t, gesture, region, x, y
GESTURE_CARRIES = {
    "tap": "`force_n` (its peak)",
    "double_tap": "`force_n`",
    "two_finger_tap": "`x2`, `y2`: where the second finger landed, once placed",
    "long_press": "`hold_s` (the tier reached); `phase`: none at the tier, `repeat`, `end` "
    "(the release after a tier), `cancel`",
    "press": "`level`, `force_n`",
    "force": "`value` 0..1 between `min_n` and `max_n`, `force_n`; `phase` begin, update, end, "
    "cancel",
    "swipe": "`direction`",
    "slide": "`value` 0..1 along the region's axis; `phase` begin, update, end, cancel",
    "stroke": "`shape` (null when nothing matched well enough) and `score` 0..1",
}

#: an example event per gesture, to show its action string as the code makes it
_EXAMPLES: dict[str, list[dict[str, Any]]] = {
    "tap": [{"region": "lamp"}],
    "double_tap": [{"region": "lamp"}],
    "two_finger_tap": [{"region": "pad"}],
    "long_press": [
        {"region": "lamp", "hold_s": 0.8},
        {"region": "lamp", "hold_s": 0.8, "phase": "repeat"},
        {"region": "lamp", "hold_s": 0.8, "phase": "end"},
    ],
    "press": [{"region": "pad", "level": "firm"}],
    "force": [{"region": "pad", "phase": "begin"}, {"region": "pad", "phase": "update"}],
    "swipe": [{"region": None, "direction": "left"}],
    "slide": [
        {"region": "dimmer", "phase": "begin"},
        {"region": "dimmer", "phase": "update"},
        {"region": "dimmer", "phase": "end"},
    ],
    "stroke": [{"region": None, "shape": "circle"}],
}

_KIND_WORDS = {
    "seconds": "seconds",
    "length": "length (the layout's units)",
    "newtons": "newtons",
    "fraction": "number 0..1",
    "degrees": "degrees",
    "choice": "one of",
    "bool": "true or false",
    "names": "a name or a list of names",
    "levels": "`{name: newtons}`",
}


def show_value(spec: Any, value: Any) -> str:
    """A default as a person writes it (lengths in mm)."""
    if value is None:
        return "any" if spec.kind == "names" else "—"
    if spec.kind == "length":
        return f"{value * 1000:g} mm"
    if spec.kind == "seconds":
        return f"{value:g} s"
    if spec.kind == "newtons":
        return f"{value:g} N"
    if spec.kind == "degrees":
        return f"{value:g}°"
    if spec.kind == "levels":
        return ", ".join(f"{k} {v:g} N" for k, v in value.items())
    if isinstance(value, bool):
        return str(value).lower()
    return f"{value:g}" if isinstance(value, float) else str(value)


def _bounds(spec: Any) -> str:
    parts = []
    if spec.choices:
        parts.append(", ".join(str(c) for c in spec.choices))
    lo, hi = spec.minimum, spec.maximum
    unit = {"seconds": " s", "newtons": " N", "degrees": "°", "length": " m"}.get(spec.kind, "")
    if lo is not None and hi is not None:
        parts.append(f"{lo:g}–{hi:g}{unit}")
    elif lo is not None and lo > 0:
        parts.append(f"≥ {lo:g}{unit}")
    return "; ".join(parts)


def gestures() -> Generated:
    from hapticdesk.gestures.event import GestureEvent
    from hapticdesk.gestures.options import ANYWHERE_GESTURES, GESTURE_OPTIONS

    out = Generated("")
    reg = registry()
    parts = []
    for gesture, specs in GESTURE_OPTIONS.items():
        out.keys.append(gesture)
        if gesture not in GESTURE_CARRIES:
            out.undescribed.append(f"{gesture} (what its event carries)")
        recognizer = reg.recognizers.get(gesture)
        what = recognizer.description if recognizer else ""
        where = "anywhere, or in a region" if gesture in ANYWHERE_GESTURES else "in a region"
        examples = ", ".join(
            code(GestureEvent(0.0, gesture, x=0.0, y=0.0, **e).action_name)
            for e in _EXAMPLES.get(gesture, [{"region": "r"}])
        )
        parts.append(f"### `{gesture}`\n\n{what[:1].upper() + what[1:]}; {where}.\n")
        parts.append(
            f"- its event carries: {GESTURE_CARRIES.get(gesture, '**not described yet**')}\n"
            f"- action strings: {examples}\n"
        )
        rows = []
        for name, spec in specs.items():
            out.keys.append(f"{gesture}.{name}")
            role = "binding" if spec.role == "match" else "recognizer"
            rows.append(
                [
                    code(name),
                    show_value(spec, spec.default),
                    _KIND_WORDS.get(spec.kind, spec.kind),
                    _bounds(spec),
                    role,
                    spec.help,
                ]
            )
        parts.append(table(["option", "default", "kind", "allowed", "set on", "what"], rows))
        parts.append("")
    out.markdown = "\n".join(parts)
    return out


def phases() -> Generated:
    from hapticdesk.gestures.options import PHASES

    words = {
        "begin": "the touch starts on the region",
        "update": "it moves or presses on (at most every `interval_s`, by at least `step`)",
        "end": "it is released",
        "cancel": "the touch broke off without a release being seen (a gap in the sensor "
        "stream, `run` stopped, a recording that ends mid-press), or it left its region with "
        "`leave: cancel`; nothing that fires on a release fires then",
    }
    return key_table(PHASES, words, ("phase", "when"))


def event_fields() -> Generated:
    from hapticdesk.gestures.event import GestureEvent

    words = {
        "t": "sample time of the event, seconds on the sensor clock",
        "gesture": "the gesture's name",
        "region": "the region's name, or null for anywhere",
        "x": "where, metres in the desk frame (x to your right)",
        "y": "where, metres in the desk frame (y away from you)",
        "shape": "stroke: the recognised shape, or null",
        "score": "stroke: the similarity 0..1",
        "direction": "swipe: right, up, left, down (and the diagonals with 8 directions)",
        "value": "slide, force: 0..1",
        "level": "press: the level's name",
        "phase": "begin, update, end, cancel (slide, force); repeat, end, cancel (long_press)",
        "hold_s": "long_press: the tier reached, seconds",
        "force_n": "the force, newtons, where the gesture has one",
        "extra": "not a key itself: what a recognizer adds (`x2`, `y2` of a two-finger tap) is "
        "merged into the event",
    }
    names = [f.name for f in dataclasses.fields(GestureEvent)]
    note = (
        "\n\nOptional keys are left out when the gesture has no such value. Lengths are "
        "metres whatever the layout's `units`."
    )
    return key_table(names, words, note=note)


# --- actions --------------------------------------------------------------------------------


def actions() -> Generated:
    out = Generated("")
    reg = registry()
    parts = []
    for name, action in sorted(reg.actions.items()):
        out.keys.append(name)
        parts.append(f"### `{name}`\n\n{action.description[:1].upper()}{action.description[1:]}.\n")
        options = action.options or {}
        if not options:
            out.undescribed.append(f"{name} (its options)")
            continue
        rows = []
        for key, spec in options.items():
            out.keys.append(f"{name}.{key}")
            kind = spec.get("kind", "")
            if spec.get("choices"):
                kind += ": " + ", ".join(
                    str(c).lower() if isinstance(c, bool) else str(c) for c in spec["choices"]
                )
            rows.append(
                [code(key), "yes" if spec.get("required") else "", kind, spec.get("help", "")]
            )
        parts.append(table(["option", "required", "kind", "what"], rows))
        parts.append("")
    out.markdown = "\n".join(parts)
    return out


def template_variables() -> Generated:
    from hapticdesk.plugins.templating import EVENT_FIELDS, VARIABLES

    words = {
        "action": "the action string (`lamp_tap`)",
        "desk": "the desk's name (`desk_name:`)",
        "event": "the whole event as a mapping, with what a plugin recognizer adds",
    }
    out = Generated("")
    rows = []
    for name in VARIABLES:
        out.keys.append(name)
        if name in EVENT_FIELDS:
            rows.append([code(name), "the event's field (see Gesture events); none when absent"])
        else:
            if name not in words:
                out.undescribed.append(name)
            rows.append([code(name), words.get(name, "**not described yet**")])
    out.markdown = table(["variable", "what"], rows)
    return out


def sources() -> Generated:
    out = Generated("")
    reg = registry()
    rows = []
    for name, source in sorted(reg.sources.items()):
        out.keys.append(name)
        rows.append([code(f"{name}:…"), source.description])
    out.markdown = table(["`--source`", "what"], rows)
    return out


MQTT_KEY_WORDS = {
    "broker": "`mqtt://host[:port]` or `mqtts://host[:port]` (TLS); default "
    "`mqtt://localhost:1883`; `--mqtt URL` overrides it",
    "username": "the login's user name",
    "password_env": "the environment variable holding the password (never in the layout)",
    "password_file": "a file holding the password, relative to the layout",
    "tls": "`{ca: FILE, cert: FILE, key: FILE}` for `mqtts://`",
    "client_id": "the MQTT client id; default: the desk's prefix with `-` for `/`",
    "keepalive": "seconds between keep-alive pings (default 60)",
    "qos": "0, 1 or 2 (default 2: a TOGGLE arrives exactly once)",
    "retain": "whether action messages are retained (default false)",
    "discovery": "announce the desk to Home Assistant (default false)",
    "discovery_prefix": "Home Assistant's discovery prefix (default `homeassistant`)",
    "base_topic": "topics under `<base_topic>/<desk>` (default `hapticdesk`)",
    "prefix": "the desk's whole topic prefix, e.g. `hapticdesk/site1/floor2/study` (not with "
    "`base_topic`)",
    "queue_size": "commands kept while the broker is away (default 1000; the oldest go first)",
    "protocol": '`auto` (MQTT 5 where the broker speaks it, else 3.1.1), `5` or `"3.1.1"`',
    "expiry_s": "MQTT 5: a command undelivered this long is dropped (default 60; 0 never)",
    "action_style": "`hapticdesk` (`lamp_tap`) or `zigbee2mqtt` (`lamp_single`, "
    "`brightness_move_up`, … as Zigbee2MQTT's remotes send)",
    "zigbee2mqtt_slide": "with `action_style: zigbee2mqtt`: `step` (the Hue dimmer's "
    "`brightness_step_*`, default) or `move` (IKEA's `brightness_move_*`/`brightness_stop`)",
}


def allowed_keys(validate: Callable[[Any], Any]) -> list[str]:
    """The keys a validator accepts, read from its own refusal of a key nobody would use
    (check_keys says ``unknown key `…` in …; allowed: a, b, c``): the code's behaviour, not a
    copy of its table."""
    from hapticdesk.errors import ConfigError
    from hapticdesk.files.yamlfile import load_marked_yaml

    probe = load_marked_yaml(Path("probe.yaml"), "__no_such_key__: 1\n")  # as a layout gives it
    try:
        validate(probe)
    except ConfigError as err:
        found = re.search(r"allowed: (.+)$", str(err))
        if found:
            return [k.strip() for k in found.group(1).split(",")]
        raise
    raise AssertionError("the validator took a key nobody would use")


def mqtt_section() -> Generated:
    from pathlib import Path as _Path

    reg = registry()
    section = reg.layout_sections["mqtt"]
    keys = allowed_keys(lambda v: section.check(v, "mqtt", _Path("layout.yaml")))
    return key_table(keys, MQTT_KEY_WORDS)


def control_commands() -> Generated:
    from hapticdesk.runtime.control import COMMANDS

    words = {
        "tare": "take the zero again over the next still `tare_s`",
        "pause": "recognise gestures but send nothing; sensing and the zero go on",
        "resume": "send again after `pause` (no new tare needed)",
        "reload": "read the layout file again; the estimator and its zero are kept",
        "layout": "switch to one of the layout's `layouts:` (`default`: the one the run "
        'started with): `{"layout": "evening"}`',
    }
    return key_table(COMMANDS, words, ("command", "what"))


def desk_state() -> Generated:
    from hapticdesk.plugins.mqtt.sensors import DeskState

    words = {
        "force_n": "the force on the desk now, newtons",
        "x": "where the finger is, metres (null while not located)",
        "y": "where the finger is, metres (null while not located)",
        "resting_load_n": "what came to rest on the desk since the tare (a cup, a book), newtons",
        "occupancy": "true while the desk is in use (touched within the last 30 s)",
        "paused": "true while a `pause` command holds the desk's gestures back (at most 1 h)",
        "layout": "the running layout's name (the Home Assistant select of layouts reads it)",
    }
    return key_table(DeskState().snapshot(), words)


def zigbee2mqtt_actions() -> Generated:
    from hapticdesk.plugins.mqtt.z2m import BUTTON_ACTIONS

    out = Generated("")
    rows = []
    for (gesture, phase), action in BUTTON_ACTIONS.items():
        out.keys.append(f"{gesture} {phase}")
        rows.append([code(gesture) + (f" ({phase})" if phase else ""), code(f"<region>_{action}")])
    rows.append(["`slide`, `zigbee2mqtt_slide: step`", "`<region>_brightness_step_up` / `_down`"])
    rows.append(
        [
            "`slide`, `zigbee2mqtt_slide: move`",
            "`<region>_brightness_move_up` / `_down`, then `<region>_brightness_stop`",
        ]
    )
    rows.append(["anything else", "the desk's own action string"])
    out.markdown = table(["gesture", "action"], rows)
    return out


# --- the command line -----------------------------------------------------------------------


def _argument_rows(parser: argparse.ArgumentParser, out: Generated, prefix: str) -> list[list[str]]:
    formatter = parser._get_formatter()
    rows = []
    for action in parser._actions:
        if isinstance(action, argparse._HelpAction | argparse._SubParsersAction):
            continue
        if action.option_strings:
            names = ", ".join(action.option_strings)
            metavar = ""
            if action.nargs != 0:
                metavar = " " + formatter._format_args(action, action.dest.upper())
            shown = names + metavar
            out.keys += [f"{prefix} {s}" for s in action.option_strings]
        else:
            shown = formatter._format_args(action, action.dest)
            out.keys.append(f"{prefix} {action.dest}")
        help_text = formatter._expand_help(action) if action.help else ""
        default = action.default
        if default in (None, False, argparse.SUPPRESS) or action.nargs == 0:
            default_text = ""
        else:
            default_text = code(default)
        if action.choices and not isinstance(action.choices, dict) and "{" not in shown:
            help_text += " (" + ", ".join(str(c) for c in action.choices) + ")"
        rows.append([code(shown), help_text, default_text])
    return rows


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def _command_section(
    name: str, parser: argparse.ArgumentParser, out: Generated, level: int
) -> list[str]:
    heading = "#" * level
    parts = [f"{heading} `hapticdesk {name}`", ""]
    if parser.description:
        parts += [parser.description[:1].upper() + parser.description[1:] + ".", ""]
    usage = " ".join(parser.format_usage().split())  # (argparse pads for its own width)
    parts += ["```", textwrap.fill(usage, 92, subsequent_indent="    "), "```", ""]
    rows = _argument_rows(parser, out, name)
    if rows:
        parts += [table(["argument", "what", "default"], rows), ""]
    for sub_name, sub in _subparsers(parser).items():
        out.keys.append(f"{name} {sub_name}")
        parts += _command_section(f"{name} {sub_name}", sub, out, level + 1)
    return parts


def command_line() -> Generated:
    from hapticdesk import cli

    out = Generated("")
    with _only_hapticdesk_plugins():
        top = cli.build_parser()
        names = list(_subparsers(top))
        parts = ["### `hapticdesk`", "", "Options before any command:", ""]
        parts += [table(["argument", "what", "default"], _argument_rows(top, out, "")), ""]
        for name in names:
            out.keys.append(name)
            sub = _subparsers(cli.build_parser(only=name))[name]
            sub.prog = f"hapticdesk {name}"
            parts += _command_section(name, sub, out, 3)
    out.markdown = "\n".join(parts)
    return out


# --- the desk profile ------------------------------------------------------------------------

PROFILE_WORDS = {
    "top": {
        "name": "the desk's name",
        "sample_rate_hz": "samples per second of every sensor (10 Hz to 100 kHz)",
        "sensors": "the sensors: 3 or more for a desk, 1 for a sensor on the bench",
        "surfaces": "the planes a finger can touch, each with an outline",
        "estimation": "how contacts are estimated (below); defaults are the paper's",
        "can": "how the sensors' CAN frames are decoded (see Sensors over CAN)",
        "serial": "a board on a serial line: its channels' timing and scales "
        "(see Boards on a serial line)",
        "desk": "the desk itself: `{mass_kg, natural_frequency_hz, center_of_mass_m, "
        "inertia_kg_m2, note}`",
        "accelerometer": "one accelerometer on the desk top (its inertial force is taken out)",
        "accelerometers": "several, each as `accelerometer`; three not on one line measure the "
        "desk's rotation too",
    },
    "sensor": {
        "name": "letters, digits and `_`: the recording's columns are `<name>_<channel>`",
        "position": "`[x, y, z]` metres in the desk frame",
        "rotation_rpy_deg": "`[roll, pitch, yaw]`: the sensor frame in the desk frame, "
        "R = Rz(yaw)·Ry(pitch)·Rx(roll) (default `[0, 0, 0]`)",
        "reports": "`reaction` (default: pressing down reads +Fz) or `load` (the opposite sign)",
        "range": "saturation: `{force_n: [x, y, z], moment_nm: [x, y, z]}`, or `{channels: "
        "[...]}` for a calibrated sensor",
        "kind": "`six_axis` (default), `load_cell` (fz only) or `three_axis` (fx, fy, fz)",
        "axes": "any subset of fx, fy, fz, mx, my, mz the sensor delivers",
        "channels": "names of raw channels (a force plate's amplifier), with `calibration`",
        "calibration": "the (6, n) matrix from the raw `channels` to the sensor's wrench "
        "Fx Fy Fz Mx My Mz",
    },
    "surface": {
        "name": "the surface's name (regions name it with `surface:`)",
        "origin": "a point of the plane, metres",
        "normal": "the plane's normal, towards where touches come from",
        "polygon": "the outline: desk (x, y) for a horizontal plane, else (u, v) along `u_axis`",
        "u_axis": "for a plane that is not horizontal: the direction of its first coordinate",
    },
    "desk": {
        "mass_kg": "the desk's mass (the simulator; vibration compensation)",
        "natural_frequency_hz": "the lowest sway mode; sets the low-pass cut-off (0.81 × it) and "
        "the legs' sway compensation",
        "center_of_mass_m": "`[x, y, z]`; default above the legs' centre at 85 % of the top's "
        "height",
        "inertia_kg_m2": "`[Ixx, Iyy, Izz]` about the centre of mass; default a solid box",
        "note": "free text",
    },
    "accelerometer": {
        "position": "`[x, y, z]` metres",
        "rotation_rpy_deg": "as for a sensor",
        "axes": "which of x, y, z it measures (default all three)",
        "noise_m_s2": "its noise σ, m/s²",
        "range_m_s2": "its range, m/s² (beyond it a reading is not used)",
    },
}


def _estimation_comments() -> dict[str, str]:
    """Each EstimationSettings field's comment in the source (on its line, or the lines of
    comment just above it): the code's own words."""
    from hapticdesk.files.profile import EstimationSettings

    source = inspect.getsource(EstimationSettings)
    lines = source.splitlines()
    words: dict[str, str] = {}
    for node in ast.parse(textwrap.dedent(source)).body[0].body:  # type: ignore[attr-defined]
        if not isinstance(node, ast.AnnAssign) or not isinstance(node.target, ast.Name):
            continue
        row = node.lineno - 1
        said = []
        k = row - 1
        while k >= 0 and lines[k].strip().startswith("#"):
            said.insert(0, lines[k].strip()[1:].strip())
            k -= 1
        _, hash_, tail = lines[row].partition("  # ")
        if hash_:
            said.append(tail.strip())
        words[node.target.id] = " ".join(said)
    return words


def profile_keys() -> Generated:
    from hapticdesk.files.profile_reader import DESK_KEYS, PROFILE_KEYS
    from hapticdesk.files.profile_sensors import ACCELEROMETER_KEYS, SENSOR_KEYS, SENSOR_KINDS
    from hapticdesk.files.profile_surfaces import SURFACE_KEYS

    out = Generated("")
    parts = []
    for title, keys, words in (
        ("The profile", PROFILE_KEYS, PROFILE_WORDS["top"]),
        ("A sensor (`sensors:`)", SENSOR_KEYS, PROFILE_WORDS["sensor"]),
        ("A surface (`surfaces:`)", SURFACE_KEYS, PROFILE_WORDS["surface"]),
        ("The desk (`desk:`)", DESK_KEYS, PROFILE_WORDS["desk"]),
        ("An accelerometer", ACCELEROMETER_KEYS, PROFILE_WORDS["accelerometer"]),
    ):
        ordered = [k for k in words if k in keys] + sorted(set(keys) - set(words))
        rows = [[code(k), w] for k, w in _described(ordered, words, out)]
        parts += [f"#### {title}", "", table(["key", "what"], rows), ""]
    kinds = [[code(k), ", ".join(v)] for k, v in SENSOR_KINDS.items()]
    out.keys += list(SENSOR_KINDS)
    parts += ["#### Sensor kinds (`kind:`)", "", table(["kind", "channels"], kinds), ""]
    out.markdown = "\n".join(parts)
    return out


#: words for the estimation settings whose line in the code has no comment
ESTIMATION_WORDS = {
    "method": "`force`, `diff`, `switched` (the paper's Fig. 3) or `fused` (ours); see How a "
    "touch is found",
    "tare_s": "the zero is taken over this long of a quiet desk at the start (a window where "
    "someone leans is refused and retried)",
    "noise_moment_nm": "as `noise_force_n`, for the moment channels",
}


def estimation_settings() -> Generated:
    from hapticdesk.files.profile import EstimationSettings

    out = Generated("")
    comments = _estimation_comments()
    rows = []
    for f in dataclasses.fields(EstimationSettings):
        out.keys.append(f.name)
        said = comments.get(f.name, "") or ESTIMATION_WORDS.get(f.name, "")
        if not said:
            out.undescribed.append(f.name)
        default = f.default
        if default is None:
            shown = "auto"
        elif isinstance(default, bool):
            shown = str(default).lower()
        else:
            shown = f"{default:g}" if isinstance(default, float) else str(default)
        rows.append([code(f.name), code(shown), _estimation_allowed(f.name), said])
    out.markdown = table(["key", "default", "allowed", "what"], rows)
    return out


def _estimation_allowed(key: str) -> str:
    """What the profile reader accepts at ``estimation: key`` (its own tables)."""
    from hapticdesk.files import profile_estimation as pe
    from hapticdesk.files.profile import METHODS

    if key == "method":
        return ", ".join(METHODS)
    if key in pe.CUTOFF_KEYS:
        return "below half `sample_rate_hz`"
    largest = pe.MAX_WINDOW_S.get(key, pe.MAX_ESTIMATION.get(key))
    if largest is None:
        return "true, false or auto" if key == "sway_compensation" else "true or false"
    if key == "min_normal_cos":
        return "0 to below 1"
    low = "0" if key in pe.MAY_BE_ZERO else "above 0"
    return f"{low} to {largest:g}"


# --- files ----------------------------------------------------------------------------------


def recording_columns() -> Generated:
    from hapticdesk.files.profile_reader import load_profile

    out = Generated("")
    rows = []
    for name in ("kitamura2017",):
        desk = load_profile(name)
        columns = ["t", *desk.channel_names()]
        shown = ",".join(columns[:7]) + ",…," + columns[-1]
        rows.append([code(name), f"{len(columns)}", code(shown)])
    out.markdown = (
        "Header `t`, then `<sensor>_<channel>` for each channel of each sensor, in the "
        "profile's order: a six-axis sensor's channels are `fx, fy, fz, mx, my, mz`, a load "
        "cell's `fz`, a three-axis cell's `fx, fy, fz`, a calibrated sensor's its own "
        "`channels`.\n\n" + table(["desk", "columns", "header"], rows)
    )
    return out


def contacts_columns() -> Generated:
    from hapticdesk.commands.contacts import HEADER

    words = {
        "t": "sample time, seconds",
        "x": "metres, desk frame (empty while not located)",
        "y": "metres, desk frame (empty while not located)",
        "z": "metres, desk frame (empty while not located)",
        "surface": "the surface's name (empty while not located)",
        "force_n": "the force's magnitude, newtons",
        "source": "`force`, `diff` or `fused`: which candidate the point came from (empty while "
        "not located)",
        "phase": "`touch`, `hold` or `release`",
    }
    made = key_table(HEADER, words, ("column", "what"))
    made.markdown = f"Header `{','.join(HEADER)}`, one row per sample in contact.\n\n" + (
        made.markdown
    )
    return made


# --- the browser UI -------------------------------------------------------------------------

ROUTE_WORDS = {
    "GET /": "the page (shipped in the package; nothing fetched at run time)",
    "GET /api/layout": "the layout file's YAML text",
    "PUT /api/layout": "save YAML text (comments kept): `{ok, errors, reloaded}`; 422 with the "
    "errors when refused, 403 when no layout file was given",
    "POST /api/check": "YAML text → `{ok, errors: [{line, column, message}], regions}`",
    "POST /api/edit": "an edit the designer makes, applied to YAML text → `{ok, text}`",
    "GET /api/schema": "the forms: every gesture's options, every action's options",
    "POST /api/strokes": "`{points: [[x, y], ...]}` → the stroke's score against every shape",
    "POST /api/setup/start": "`{points: [[x, y], ...]}` metres: start a set-up check",
    "POST /api/setup/finish": "end it: what was found, each press's residual, a profile snippet",
    "GET /api/setup/weight/spots": "`?count=N` (3 to 5) → `{ok, spots_m}`: the spots to mark for "
    "the set-up with a known weight (a load-cell desk)",
    "POST /api/setup/weight/start": "`{mass_kg, count}`: start recording the weight put on each "
    "spot in turn → `{ok, mass_kg, spots_m}`",
    "POST /api/setup/weight/finish": "end it: each cell's `gain` and `position_m`, the `check` on "
    "the spot the fit did not use (`error_m`, and `check_before_m` with the profile as it "
    "was), `leave_one_out`, `passed`, `profile_path` (written beside the layout) or `note`",
    "WS /ws": "JSON messages, one per frame (below)",
    "GET /static/{path:path}": "the page's script and style (behind the token when one is set)",
}


def http_routes() -> Generated:
    from starlette.routing import Mount, Route, WebSocketRoute

    from hapticdesk.plugins.ui.server import UiServer

    app = UiServer(Path("layout.yaml"), None).app()
    keys = []
    for route in app.routes:
        if isinstance(route, Route):
            keys += [f"{m} {route.path}" for m in sorted(route.methods or ()) if m != "HEAD"]
        elif isinstance(route, WebSocketRoute):
            keys.append(f"WS {route.path}")
        elif isinstance(route, Mount):
            keys.append(f"GET {route.path}")
    return key_table(keys, ROUTE_WORDS, ("request", "what"))


# --- plugins --------------------------------------------------------------------------------


def hooks() -> Generated:
    from hapticdesk import hookspecs
    from hapticdesk.hookspecs import hookspec_names

    out = Generated("")
    parts = []
    for name in hookspec_names():
        out.keys.append(name)
        function = getattr(hookspecs, name)
        signature = str(inspect.signature(function)).replace("'", "")
        if not function.__doc__:
            out.undescribed.append(name)
        parts += [f"### `{name}{signature}`", "", plain_docstring(function.__doc__), ""]
    out.markdown = "\n".join(parts)
    return out


EXTRA_WORDS = {
    "plot": "drawings: `check --png`, `plot`, `bench --plot`",
    "demo": "`hapticdesk demo`'s own MQTT broker",
    "ui": "the browser page: `hapticdesk ui`, `run --ui`",
    "docs": "this site: `mkdocs serve`, `mkdocs build --strict`",
    "serial": "boards on a serial line: `run --source serial:PORT` (pyserial)",
    "c3d": "force plates from C3D files: `contacts`, `plot`, "
    "`run --source replay:FILE.c3d` (ezc3d)",
    "test": "the test suite and its linters (all of the above)",
}


def extras() -> Generated:
    import importlib.metadata

    out = Generated("")
    found: dict[str, list[str]] = {}
    for requirement in importlib.metadata.requires("hapticdesk") or []:
        name, _, marker = requirement.partition(";")
        m = re.search(r"extra\s*==\s*['\"]([\w.\-]+)['\"]", marker)
        if m:
            found.setdefault(m.group(1), []).append(name.strip())
    rows = []
    for extra, packages in found.items():
        out.keys.append(extra)
        if extra not in EXTRA_WORDS:
            out.undescribed.append(extra)
        shown = ", ".join(packages) if len(packages) <= 5 else ", ".join(packages[:5]) + ", …"
        rows.append([code(f"pip install 'hapticdesk[{extra}]'"), EXTRA_WORDS.get(extra, ""), shown])
    out.markdown = table(["install", "for", "brings"], rows)
    return out


SECTIONS: dict[str, Callable[[], Generated]] = {
    "extras": extras,
    "layout-keys": layout_keys,
    "region-keys": region_keys,
    "binding-keys": binding_keys,
    "units": units,
    "gestures": gestures,
    "phases": phases,
    "event-fields": event_fields,
    "actions": actions,
    "sources": sources,
    "template-variables": template_variables,
    "mqtt-section": mqtt_section,
    "control-commands": control_commands,
    "desk-state": desk_state,
    "zigbee2mqtt-actions": zigbee2mqtt_actions,
    "cli": command_line,
    "profile-keys": profile_keys,
    "estimation-settings": estimation_settings,
    "recording-columns": recording_columns,
    "contacts-columns": contacts_columns,
    "http-routes": http_routes,
    "hooks": hooks,
}


def expand(markdown: str, where: str, made: dict[str, Generated] | None = None) -> str:
    """``markdown`` with every marker replaced by its generated table; an unknown marker is a
    ValueError naming ``where``."""
    made = {} if made is None else made

    def one(m: re.Match[str]) -> str:
        name = m.group(1)
        if name not in SECTIONS:
            known = ", ".join(SECTIONS)
            raise ValueError(f"{where}: unknown reference marker {name!r}; known: {known}")
        if name not in made:
            made[name] = SECTIONS[name]()
        return made[name].markdown

    return MARKER.sub(one, markdown)


# --- the MkDocs hook --------------------------------------------------------------------------

_made: dict[str, Generated] = {}


def on_pre_build(config: Any) -> None:
    """Each build makes its tables afresh (``mkdocs serve`` rebuilds after an edit)."""
    _made.clear()


def on_page_markdown(markdown: str, page: Any, config: Any, files: Any) -> str:
    if "<!-- generated:" not in markdown:
        return markdown
    text = expand(markdown, page.file.src_uri, _made)
    for name in MARKER.findall(markdown):
        for key in _made[name].undescribed:
            log.warning("reference %s: `%s` is in the code but not described", name, key)
    return text


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("out", help="folder to write the reference pages into")
    args = parser.parse_args(argv)
    docs = Path(__file__).resolve().parents[1] / "docs" / "reference"
    target = Path(args.out)
    target.mkdir(parents=True, exist_ok=True)
    made: dict[str, Generated] = {}
    for page in sorted(docs.glob("*.md")):
        (target / page.name).write_text(expand(page.read_text("utf-8"), str(page), made), "utf-8")
    missing = [f"{n}: {k}" for n, g in made.items() for k in g.undescribed]
    for line in missing:
        print(f"not described: {line}", file=sys.stderr)
    return 1 if missing else 0


if __name__ == "__main__":
    sys.exit(main())
