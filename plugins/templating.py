"""Templates in action options: Jinja2's sandbox with the gesture event's fields as variables.

``"{{ (value * 254) | round | int }}"`` is what Home Assistant users already write. The
environment is Jinja2's ``ImmutableSandboxedEnvironment`` (no attribute tricks, no mutation,
no eval), with ``StrictUndefined`` so a misspelt name fails loudly. Templates are compiled
when the layout is validated, so a syntax error or an unknown variable is reported with the
layout's ``file:line:column`` before anything runs.

Costs are bounded three times over, in ``check`` and ``run`` alike:

1. the text itself (:func:`~.template_sandbox.static_problems`): literal arithmetic making a
   huge number, a literal format's widths, a literal repetition, a ``range`` over the limits
   are refused at compile time, whichever branch they stand in;
2. while rendering (:mod:`.template_sandbox`): every operation that makes something large
   checks its size before, loop turns and calls spend a budget;
3. every rendering runs in a worker process (:mod:`.template_worker`) killed at
   :data:`MAX_RENDER_S`, with its memory limited: a single C call nobody foresaw cannot hold
   the desk.

``check`` renders each template for sample events, for the constants the template compares
variables with (``{% if region == 'b5' %}``), and (:func:`check_for_events`) for every event
its binding's gesture can make, so what passes ``check`` cannot blow up at run time.

A structured value (a payload mapping) is rendered leaf by leaf; a leaf that is a template
and renders to a number becomes a JSON number (``"{{ value * 100 }}"`` -> ``37.5``). Plain
strings are kept as written. jinja2 is imported only when a layout has a template.
"""

from __future__ import annotations

import logging
import math
import re
import time
import warnings
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Any

from hapticdesk.errors import ConfigError, LayoutWarning, Position
from hapticdesk.files.marked_values import MarkedDict, MarkedList
from hapticdesk.gestures.event import GestureEvent
from hapticdesk.plugins import template_sandbox, template_worker
from hapticdesk.plugins.template_sandbox import (
    MAX_EXPONENT,
    MAX_FORMAT_WIDTH,
    MAX_NUMBER_BITS,
    MAX_PIECE_CHARS,
    MAX_RANGE,
    MAX_RENDERED_CHARS,
    static_problems,
)

__all__ = [
    "CHECK_EVENTS",
    "MAX_EXPONENT",
    "MAX_FORMAT_WIDTH",
    "MAX_NUMBER_BITS",
    "MAX_PIECE_CHARS",
    "MAX_RANGE",
    "MAX_RENDERED_CHARS",
    "Template",
    "TemplateError",
    "TemplateLimitError",
    "TemplatedValue",
    "check_for_events",
    "compile_template",
    "compile_value",
    "event_variables",
]

log = logging.getLogger(__name__)

#: what the built-in actions register as their ``check_events`` (see :func:`check_for_events`)
CHECK_EVENTS = "hapticdesk.plugins.templating:check_for_events"

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

#: the most loop turns and calls one rendering may take (see :mod:`.template_sandbox`)
MAX_STEPS = template_sandbox.MAX_STEPS
#: the longest one rendering may take, seconds: the worker rendering it is killed then
MAX_RENDER_S = template_sandbox.MAX_RENDER_S
#: the longest `check` spends rendering one template for every event its gesture can make
MAX_CHECK_S = 3.0
#: the variables of the sample event a template is rendered with once when it is checked
SAMPLE_VARIABLES: dict[str, Any] = {
    "t": 0.0,
    "gesture": "tap",
    "region": "region",
    "x": 0.0,
    "y": 0.0,
    "shape": "circle",
    "score": 1.0,
    "direction": "up",
    "value": 0.5,
    "level": "light",
    "phase": "begin",
    "hold_s": 1.0,
    "force_n": 5.0,
    "action": "tap",
    "desk": "desk",
}
SAMPLE_VARIABLES["event"] = dict(SAMPLE_VARIABLES)
#: what a tap carries: the optional fields a gesture may leave out, left out
_OPTIONAL_FIELDS = ("shape", "score", "direction", "value", "level", "phase", "hold_s")

_INT = re.compile(r"[+-]?\d+")
_FLOAT = re.compile(r"[+-]?(\d+\.\d*|\.\d+|\d+)([eE][+-]?\d+)?|[+-]?(nan|inf|infinity)", re.I)


class TemplateError(ValueError):
    """A template failed while rendering for one event (reported by the dispatcher)."""


class TemplateLimitError(TemplateError):
    """A template would render (or build on its way) more than the limits allow."""


def is_template(text: str) -> bool:
    return "{{" in text or "{%" in text


def _environment() -> Any:
    return template_sandbox.environment()


_said_in_process = False


def render_text(text: str, variables: Mapping[str, Any]) -> str:
    """``text`` (a template) rendered with ``variables`` in a template worker, within
    :data:`MAX_RENDER_S` and the worker's memory bound; TemplateLimitError past them,
    TemplateError when the template fails for these variables."""
    global _said_in_process
    workers = template_worker.pool()
    if workers.unavailable is None:
        try:
            return workers.render(text, variables, max_steps=MAX_STEPS, limit_s=MAX_RENDER_S)
        except template_worker.WorkerLimit as err:
            raise TemplateLimitError(str(err)) from None
        except template_worker.WorkerFailed as err:
            raise TemplateError(str(err)) from None
        except OSError:
            pass  # no worker could start: said below, rendered here
    if not _said_in_process:
        _said_in_process = True
        log.warning(
            "templates render in this process (%s): their time and memory are bounded by the "
            "sandbox's checks only",
            workers.unavailable or "no template worker",
        )
    try:
        compiled = _environment().from_string(text)
        return template_sandbox.render_bounded(
            compiled, variables, max_steps=MAX_STEPS, limit_s=MAX_RENDER_S
        )
    except template_sandbox.TemplateLimitError as err:
        raise TemplateLimitError(str(err)) from None
    except MemoryError:
        raise TemplateLimitError("it needs more memory than there is") from None
    except Exception as err:
        raise TemplateError(f"{type(err).__name__}: {err}") from None


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
            return render_text(self.text, variables)
        except TemplateLimitError as err:
            raise TemplateLimitError(
                f"template {self.text!r} ({self.where}) failed: {err}"
            ) from None
        except TemplateError as err:  # any template runtime error: name the template
            raise TemplateError(f"template {self.text!r} ({self.where}) failed: {err}") from None

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
    """Compile ``text``; a syntax error, an unknown variable, or a cost over the limits (in
    the text itself, or when rendered for sample events) is a ConfigError at ``where``."""
    if not is_template(text):
        return Template(text, None, str(where))
    env = _environment()
    template_worker.pool().warm()  # (the first rendering then finds a worker started)
    from jinja2 import TemplateSyntaxError, meta

    try:
        tree = env.parse(text)
        too_costly = static_problems(tree)
        misread = _filters_on_a_number(tree)
        unknown = sorted(meta.find_undeclared_variables(tree) - set(VARIABLES))
        compared = _compared_constants(tree)
        compiled = env.from_string(text)
    except TemplateSyntaxError as err:
        raise ConfigError(where, f"{what} is not a valid template: {err.message}") from None
    except RecursionError:
        raise ConfigError(where, f"{what} nests too deep to be read as a template") from None
    if too_costly:
        raise ConfigError(where, f"{what} is too costly to render: {too_costly[0]}")
    if unknown:
        raise ConfigError(
            where,
            f"{what} uses unknown variable(s) {', '.join(unknown)}; available: "
            f"{', '.join(VARIABLES)} (plugin fields as event.<name>)",
        )
    for chain, number, operator in misread:
        warnings.warn(
            LayoutWarning(
                f"{where}: {what} applies `{chain}` to the number {number} alone, not to the "
                f"result of `{operator}` (a filter binds tighter): write `(… {operator} "
                f"{number}) | {chain}`"
            ),
            stacklevel=2,
        )
    template = Template(text, compiled, str(where))
    samples = [(v, "an event") for v in _sample_variables(compared)]
    _check_renders(template, samples, where, what)
    return template


def _filters_on_a_number(tree: Any) -> list[tuple[str, Any, str]]:
    """(filters, number, operator) of each ``value * 254 | round``: a filter binds tighter
    than arithmetic, so this rounds 254 and sends the product unrounded (a brightness of
    24.93). A filter on a lone number is never meant: :func:`compile_template` says so as a
    layout warning (the layout reader collects ``warnings.warn``)."""
    from jinja2 import nodes

    found = []
    for op in tree.find_all(nodes.BinExpr):
        names, inner = [], op.right
        while isinstance(inner, nodes.Filter):
            names.append(inner.name)
            inner = inner.node
        if names and isinstance(inner, nodes.Const) and not isinstance(op.left, nodes.Const):
            found.append((" | ".join(reversed(names)), inner.value, op.operator))
    return found


def _compared_constants(tree: Any) -> dict[str, set[Any]]:
    """Variable -> the constants the template compares it with (``region == 'b5'``,
    ``direction in ['up', 'down']``, ``event.level == 'hard'``): the values a check renders
    it with besides the sample's, so the branch they guard is rendered too."""
    from jinja2 import nodes

    def variable(node: Any) -> str | None:
        if isinstance(node, nodes.Name) and node.name in VARIABLES:
            return str(node.name)
        if isinstance(node, nodes.Getattr | nodes.Getitem) and isinstance(node.node, nodes.Name):
            if node.node.name == "event":
                key = node.attr if isinstance(node, nodes.Getattr) else None
                if isinstance(node, nodes.Getitem) and isinstance(node.arg, nodes.Const):
                    key = node.arg.value
                return key if key in EVENT_FIELDS else None
        return None

    def constants(node: Any) -> list[Any]:
        if isinstance(node, nodes.Const) and isinstance(node.value, str | int | float):
            return [node.value]
        if isinstance(node, nodes.List | nodes.Tuple):
            return [c for item in node.items for c in constants(item)]
        return []

    found: dict[str, set[Any]] = {}
    for compare in tree.find_all(nodes.Compare):
        operands = [compare.expr, *(op.expr for op in compare.ops)]
        for a, b in zip(operands, operands[1:], strict=False):
            for name_node, value_node in ((a, b), (b, a)):
                name = variable(name_node)
                if name is not None:
                    found.setdefault(name, set()).update(constants(value_node))
    return found


def _sample_variables(compared: Mapping[str, set[Any]]) -> list[dict[str, Any]]:
    """The sample event, one like a tap's (its optional fields absent), and one for each
    constant the template compares a variable with (at most 64 in all)."""
    tap = {**SAMPLE_VARIABLES, **dict.fromkeys(_OPTIONAL_FIELDS)}
    tap["event"] = {k: v for k, v in tap.items() if k != "event" and v is not None}
    out = [dict(SAMPLE_VARIABLES), tap]
    for name, values in sorted(compared.items()):
        for value in sorted(values, key=repr):
            for base in (SAMPLE_VARIABLES, tap):
                variant = {**base, name: value}
                variant["event"] = {**base["event"], name: value}
                out.append(variant)
    return out[:64]


def _check_renders(
    template: Template,
    samples: list[tuple[dict[str, Any], str]],
    where: Position | str,
    what: str,
) -> None:
    """Render ``template`` with each of ``samples`` ((variables, the event they stand for)):
    breaking a limit with any is an error in the layout. Other failures are not reported
    here (``value`` is None for a tap; the dispatcher reports them when they happen)."""
    started = time.monotonic()
    for variables, label in samples:
        try:
            render_text(template.text, variables)
        except TemplateLimitError as err:
            raise ConfigError(where, f"{what} is too costly to render for {label}: {err}") from None
        except TemplateError:
            pass
        if time.monotonic() - started > MAX_CHECK_S:
            raise ConfigError(
                where,
                f"{what} is too costly to render for an event: rendering it for the events it "
                f"may see took longer than {MAX_CHECK_S:g} s",
            )


def check_for_events(
    options: Any, position: Position | str, events: list[GestureEvent], desk: str
) -> None:
    """Render every template in an action's ``options`` for each of ``events`` (the events
    its binding can make, from :func:`hapticdesk.runtime.binding_events.possible_events`):
    one that breaks a limit for any of them is a ConfigError at its place, so what passes
    `check` cannot blow up at run time. Registered by the actions as their
    ``check_events``."""
    samples: dict[str, tuple[dict[str, Any], str]] = {}
    for event in events:
        variables = event_variables(event, desk)
        samples.setdefault(repr(sorted(variables.items())), (variables, _describe(event)))
    for text, where, what in _templates_in(options, position, "the action's options"):
        _check_renders(Template(text, True, str(where)), list(samples.values()), where, what)


def _describe(event: GestureEvent) -> str:
    """``a press in b6 (level hard, force_n 5.0)``: which event broke a limit."""
    fields = ", ".join(
        f"{name} {getattr(event, name)}"
        for name in ("phase", "level", "shape", "direction", "value", "hold_s", "force_n")
        if getattr(event, name) is not None
    )
    where = f" in {event.region}" if event.region else " outside every region"
    return f"a {event.gesture}{where}" + (f" ({fields})" if fields else "")


def _templates_in(value: Any, where: Position | str, what: str) -> Iterator[tuple[str, Any, str]]:
    """(text, position, what) of every template among the leaves of ``value``."""
    if isinstance(value, str):
        if is_template(value):
            yield value, where, what
    elif isinstance(value, Mapping):
        for key, item in value.items():
            pos = value.where(key) if isinstance(value, MarkedDict) else where
            yield from _templates_in(item, pos, f"`{key}`")
    elif isinstance(value, list):
        for i, item in enumerate(value):
            pos = value.where(i) if isinstance(value, MarkedList) else where
            yield from _templates_in(item, pos, f"item {i + 1} of {what}")


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
