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

import functools
import json
import math
import re
import time
import warnings
from collections.abc import Callable, Iterable, Iterator, Mapping
from contextvars import ContextVar
from dataclasses import dataclass
from functools import cache
from typing import Any

from hapticdesk.files.yamlfile import ConfigError, LayoutWarning, MarkedDict, MarkedList, Position
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

#: the longest text a template may render, or build on its way (a payload is a few hundred)
MAX_RENDERED_CHARS = 65_536
#: the largest exponent of ``**`` (10 ** 1000 is already far beyond any payload)
MAX_EXPONENT = 1000
#: the most loop turns and calls one rendering may take (text or lists made on the way count
#: a step per kB): a payload loops over a few dozen items, and loops nested in loops would
#: otherwise run for hours with nothing to show
MAX_STEPS = 100_000
#: the longest one rendering may take (checked at every loop turn and call), seconds
MAX_RENDER_S = 1.0
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

_INT = re.compile(r"[+-]?\d+")
_FLOAT = re.compile(r"[+-]?(\d+\.\d*|\.\d+|\d+)([eE][+-]?\d+)?|[+-]?(nan|inf|infinity)", re.I)


class TemplateError(ValueError):
    """A template failed while rendering for one event (reported by the dispatcher)."""


class TemplateLimitError(TemplateError):
    """A template would render (or build on its way) more than the limits allow."""


class _Budget:
    """What is left of one rendering's :data:`MAX_STEPS` and :data:`MAX_RENDER_S`."""

    __slots__ = ("deadline", "steps")

    def __init__(self) -> None:
        self.steps = MAX_STEPS
        self.deadline = time.monotonic() + MAX_RENDER_S

    def spend(self, steps: int) -> None:
        self.steps -= steps
        if self.steps < 0:
            raise TemplateLimitError(f"it takes more than {MAX_STEPS} loop turns and calls")
        if time.monotonic() > self.deadline:
            raise TemplateLimitError(f"it takes longer than {MAX_RENDER_S:g} s")


#: the budget of the rendering under way in this thread (dispatcher lanes render in parallel)
_BUDGET: ContextVar[_Budget | None] = ContextVar("hapticdesk_template_budget", default=None)


def _spend(steps: int = 1) -> None:
    budget = _BUDGET.get()
    if budget is not None:
        budget.spend(steps)


def _made(value: Any) -> Any:
    """``value``, spending a step per kB (or 1,000 items) it holds: text or lists built in a
    loop (``map`` over a long list, a namespace growing by ``+``) then cost what they take
    in memory, not one step each."""
    if isinstance(value, str | list | tuple | dict):
        _spend(len(value) // 1024)
    return value


def _counted(iterable: Iterable[Any]) -> Iterator[Any]:
    """``iterable``, spending one step of the rendering's budget per item."""
    for item in iterable:
        _spend()
        yield item


def is_template(text: str) -> bool:
    return "{{" in text or "{%" in text


@cache
def _environment() -> Any:
    from jinja2 import StrictUndefined, nodes
    from jinja2.sandbox import ImmutableSandboxedEnvironment

    def limit(size: int, what: str) -> None:
        if size > MAX_RENDERED_CHARS:
            raise TemplateLimitError(
                f"{what} would make {size} characters; the limit is {MAX_RENDERED_CHARS}"
            )

    class BoundedEnvironment(ImmutableSandboxedEnvironment):
        # intercepted operators are also never folded into constants when compiling, so
        # `{{ "a" * 10**10 }}` cannot allocate at compile time either
        intercepted_binops = frozenset({"*", "**", "+"})

        def call_binop(self, context: Any, operator: str, left: Any, right: Any) -> Any:
            if operator == "*":
                for seq, n in ((left, right), (right, left)):
                    if isinstance(seq, str | list | tuple) and isinstance(n, int):
                        limit(len(seq) * n, "repeating")
            if operator == "**" and isinstance(right, int | float) and abs(right) > MAX_EXPONENT:
                raise TemplateLimitError(f"an exponent over {MAX_EXPONENT} ({right})")
            _spend()
            return _made(super().call_binop(context, operator, left, right))

        def call(__self, __context: Any, __obj: Any, *args: Any, **kwargs: Any) -> Any:  # noqa: N805
            # every call of a sandboxed template comes here: a macro calling itself twice
            # is as costly as nested loops
            _spend()
            return _made(super().call(__context, __obj, *args, **kwargs))

        def call_filter(self, *args: Any, **kwargs: Any) -> Any:
            # the filters `map`, `select` … apply to each item of a list
            _spend()
            return _made(super().call_filter(*args, **kwargs))

        def _parse(self, source: str, name: str | None, filename: str | None) -> Any:
            # every `for` loop iterates through _counted: an empty loop body has no call
            # and no output to count otherwise
            tree = super()._parse(source, name, filename)
            for loop in tree.find_all(nodes.For):
                counter = nodes.EnvironmentAttribute("count_steps", lineno=loop.lineno)
                loop.iter = nodes.Call(counter, [loop.iter], [], None, None, lineno=loop.lineno)
            return tree

    env = BoundedEnvironment(undefined=StrictUndefined, autoescape=False)
    env.count_steps = _counted  # type: ignore[attr-defined]
    del env.globals["lipsum"]  # random text of any length: no use in a payload
    for name, size in _FILTER_SIZES.items():
        env.filters[name] = _bounded_filter(name, env.filters[name], size, limit)
    return env


def _width(value: Any) -> int:
    return len(value) if isinstance(value, str) else int(value)


#: a %-conversion: an optional (key), flags, a width and a precision, each digits or `*`
_CONVERSION = re.compile(r"%(?:\([^)]*\))?[-+ #0]*(\d+|\*)?(?:\.(\d+|\*))?")
#: a width or precision of more digits than this is counted as this many characters (and
#: refused): int() of thousands of digits is itself refused by Python
_MAX_DIGITS = 9


def _format_widths(text: Any, args: tuple[Any, ...]) -> int:
    """An upper bound of the padding a %-format string adds: its field widths and
    precisions (``%99999s`` pads to 99999, ``%.99999f`` prints 99999 decimals, ``%(a)9s``
    too), and for a ``*`` (the width taken from the arguments) every integer argument."""
    total, star = 0, False
    for width, precision in _CONVERSION.findall(str(text)):
        for part in (width, precision):
            if part == "*":
                star = True
            elif part:
                total += 10**_MAX_DIGITS if len(part) > _MAX_DIGITS else int(part)
    if star:
        total += sum(abs(a) for a in args if isinstance(a, int) and not isinstance(a, bool))
    return total


#: `tojson`'s indent at most this (a payload's JSON needs no more)
MAX_JSON_INDENT = 16


def _json_size(value: Any, indent: Any = None) -> int:
    """An upper bound of ``tojson``'s result: refused past MAX_JSON_INDENT (an indent of
    4·10⁸ spaces made gigabytes before the length was checked)."""
    if indent is None:
        spaces = 0
    elif isinstance(indent, int) and not isinstance(indent, bool) and indent >= 0:
        spaces = indent
    elif isinstance(indent, str):
        spaces = len(indent)
    else:
        spaces = MAX_JSON_INDENT + 1
    if spaces > MAX_JSON_INDENT:
        raise TemplateLimitError(f"a `tojson` indent over {MAX_JSON_INDENT} ({indent!r})")
    text = json.dumps(value, default=str, separators=(",", ":"))
    # each value on its own line, indented at most its depth (a payload's: a few) times
    return len(text) * (2 + spaces * 8)


# filter -> an upper bound of its result's length from its arguments, computed before any
# text is made (the arguments are those Jinja passes: an environment or eval context first
# for `wordwrap` and `replace`)
_FILTER_SIZES: dict[str, Callable[..., int]] = {
    "center": lambda s, width=80: len(str(s)) + _width(width),
    "indent": lambda s, width=4, *_: len(str(s)) * (1 + _width(width)),
    "wordwrap": lambda _env, s, width=79, *_, **__: 2 * len(str(s)) + _width(width),
    "format": lambda s, *args, **kw: (
        len(str(s)) + len(str(args)) + len(str(kw)) + _format_widths(s, args)
    ),
    "tojson": lambda _ctx, value, indent=None: _json_size(value, indent),
    "replace": lambda _ctx, s, old, new, *_: len(str(s)) * max(1, len(str(new))) + len(str(new)),
}


def _bounded_filter(name: str, original: Any, size: Callable[..., int], limit: Any) -> Any:
    """``original``, refusing arguments whose result could exceed the limit."""

    @functools.wraps(original)  # keeps Jinja's marker of what to pass first
    def bounded(*args: Any, **kwargs: Any) -> Any:
        limit(size(*args, **kwargs), f"the `{name}` filter")
        return original(*args, **kwargs)

    return bounded


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
            text = _render_bounded(self.compiled, variables)
        except Exception as err:  # any template runtime error: name the template
            raise TemplateError(f"template {self.text!r} ({self.where}) failed: {err}") from err
        return text

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


def _render_bounded(compiled: Any, variables: Mapping[str, Any]) -> str:
    """The rendered text, stopped as soon as it grows past :data:`MAX_RENDERED_CHARS` or
    spends more than its budget of loop turns, calls and time."""
    parts: list[str] = []
    size = 0
    token = _BUDGET.set(_Budget())
    try:
        for part in compiled.generate(variables):
            size += len(part)
            if size > MAX_RENDERED_CHARS:
                raise TemplateLimitError(
                    f"the text rendered exceeds {MAX_RENDERED_CHARS} characters"
                )
            parts.append(part)
    finally:
        _BUDGET.reset(token)
    return "".join(parts)


def compile_template(text: str, where: Position | str, what: str = "template") -> Template:
    """Compile ``text``; a syntax error or unknown variable is a ConfigError at ``where``."""
    if not is_template(text):
        return Template(text, None, str(where))
    env = _environment()
    from jinja2 import TemplateSyntaxError, meta

    try:
        tree = env.parse(text)
        misread = _filters_on_a_number(tree)  # (first: the analysis below folds constants)
        unknown = sorted(meta.find_undeclared_variables(tree) - set(VARIABLES))
        compiled = env.from_string(text)
    except TemplateSyntaxError as err:
        raise ConfigError(where, f"{what} is not a valid template: {err.message}") from None
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
    _check_limits(compiled, where, what)
    return Template(text, compiled, str(where))


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


def _check_limits(compiled: Any, where: Position | str, what: str) -> None:
    """Render once with a sample event: breaking a limit then is an error in the layout.

    Other failures are not reported here: they may depend on the event (``value`` is None
    for a tap), and the dispatcher reports them when they happen.
    """
    try:
        _render_bounded(compiled, SAMPLE_VARIABLES)
    except (TemplateLimitError, MemoryError) as err:
        raise ConfigError(where, f"{what} is too costly to render for an event: {err}") from None
    except Exception:
        return  # may depend on the event: the dispatcher reports it when it happens


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
