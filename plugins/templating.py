"""Templates in action options: Jinja2's sandbox with the gesture event's fields as variables.

``"{{ (value * 254) | round | int }}"`` is what Home Assistant users already write. The
environment is Jinja2's ``ImmutableSandboxedEnvironment`` (no attribute tricks, no mutation,
no eval), with ``StrictUndefined`` so a misspelt name fails loudly. Templates are compiled
when the layout is validated, so a syntax error or an unknown variable is reported with the
layout's ``file:line:column`` before anything runs.

A structured value (a payload mapping) is rendered leaf by leaf; a leaf that is a template
and renders to a number becomes a JSON number (``"{{ value * 100 }}"`` -> ``37.5``). Plain
strings are kept as written. jinja2 is imported only when a layout has a template.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cache
from typing import Any

from hapticdesk.files.yamlfile import ConfigError, MarkedDict, MarkedList, Position
from hapticdesk.gestures.event import GestureEvent

#: the GestureEvent fields a template sees under their own names
EVENT_FIELDS = (
    "t",
    "gesture",
    "region",
    "x",
    "y",
    "shape",
    "score",
    "direction",
    "value",
    "level",
    "phase",
    "hold_s",
    "force_n",
)
#: every name a template can use; ``event`` is the whole event as a mapping (with plugin
#: extras), ``action`` its Zigbee2MQTT-style action string, ``desk`` the desk's name
VARIABLES = (*EVENT_FIELDS, "action", "desk", "event")

_INT = re.compile(r"[+-]?\d+")
_FLOAT = re.compile(r"[+-]?(\d+\.\d*|\.\d+|\d+)([eE][+-]?\d+)?|[+-]?(nan|inf|infinity)", re.I)


class TemplateError(ValueError):
    """A template failed while rendering for one event (reported by the dispatcher)."""


def is_template(text: str) -> bool:
    return "{{" in text or "{%" in text


@cache
def _environment() -> Any:
    from jinja2 import StrictUndefined
    from jinja2.sandbox import ImmutableSandboxedEnvironment

    return ImmutableSandboxedEnvironment(undefined=StrictUndefined, autoescape=False)


def event_variables(event: GestureEvent, desk: str) -> dict[str, Any]:
    """The variables a template sees for ``event``."""
    variables: dict[str, Any] = {name: getattr(event, name) for name in EVENT_FIELDS}
    variables["action"] = event.action_name
    variables["desk"] = desk
    variables["event"] = event.to_dict()
    return variables


@dataclass(frozen=True)
class Template:
    """One string, compiled when it holds ``{{ }}`` or ``{% %}``."""

    text: str
    compiled: Any  # jinja2.Template or None for plain text
    where: str

    def render(self, variables: Mapping[str, Any]) -> str:
        if self.compiled is None:
            return self.text
        try:
            return str(self.compiled.render(variables))
        except Exception as err:  # any template runtime error: name the template
            raise TemplateError(f"template {self.text!r} ({self.where}) failed: {err}") from err

    def render_value(self, variables: Mapping[str, Any]) -> Any:
        """Rendered text, as a number when the template rendered one."""
        text = self.render(variables)
        if self.compiled is None:
            return text
        stripped = text.strip()
        if _INT.fullmatch(stripped):
            return int(stripped)
        if _FLOAT.fullmatch(stripped):
            number = float(stripped)
            if not math.isfinite(number):
                raise TemplateError(
                    f"template {self.text!r} ({self.where}) rendered {stripped!r}; "
                    "a payload must not hold NaN or infinity"
                )
            return number
        return text


def compile_template(text: str, where: Position | str, what: str = "template") -> Template:
    """Compile ``text``; a syntax error or unknown variable is a ConfigError at ``where``."""
    if not is_template(text):
        return Template(text, None, str(where))
    env = _environment()
    from jinja2 import TemplateSyntaxError, meta

    try:
        unknown = sorted(meta.find_undeclared_variables(env.parse(text)) - set(VARIABLES))
        compiled = env.from_string(text)
    except TemplateSyntaxError as err:
        raise ConfigError(where, f"{what} is not a valid template: {err.message}") from None
    if unknown:
        raise ConfigError(
            where,
            f"{what} uses unknown variable(s) {', '.join(unknown)}; available: "
            f"{', '.join(VARIABLES)} (plugin fields as event.<name>)",
        )
    return Template(text, compiled, str(where))


@dataclass(frozen=True)
class TemplatedValue:
    """A YAML value (mapping, list, string, number) with every string leaf compiled."""

    value: Any

    def render(self, variables: Mapping[str, Any]) -> Any:
        return _render(self.value, variables)


def compile_value(value: Any, where: Position | str, what: str) -> TemplatedValue:
    """Compile every string leaf of ``value`` (positions taken from the YAML where known)."""
    return TemplatedValue(_compile(value, where, what))


def _compile(value: Any, where: Position | str, what: str) -> Any:
    if isinstance(value, str):
        return compile_template(value, where, what)
    if isinstance(value, Mapping):
        out = {}
        for key, item in value.items():
            pos = value.where(key) if isinstance(value, MarkedDict) else where
            out[str(key)] = _compile(item, pos, f"`{key}` of {what}")
        return out
    if isinstance(value, list):
        return [
            _compile(item, value.where(i) if isinstance(value, MarkedList) else where, what)
            for i, item in enumerate(value)
        ]
    if value is None or isinstance(value, bool | int | float):
        if isinstance(value, float) and not math.isfinite(value):
            raise ConfigError(where, f"{what} must not hold NaN or infinity")
        return value
    raise ConfigError(where, f"{what} holds a value of type {type(value).__name__}")


def _render(value: Any, variables: Mapping[str, Any]) -> Any:
    if isinstance(value, Template):
        return value.render_value(variables)
    if isinstance(value, dict):
        return {key: _render(item, variables) for key, item in value.items()}
    if isinstance(value, list):
        return [_render(item, variables) for item in value]
    return value
