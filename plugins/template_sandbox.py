"""The sandbox a template renders in: Jinja2's immutable sandbox with every cost bounded.

This is the part of :mod:`hapticdesk.plugins.templating` that runs inside the template
worker (:mod:`hapticdesk.plugins.template_worker`), so it imports nothing of hapticdesk but
the limits (:mod:`.template_limits`): the worker starts fast and holds nothing but Jinja2.

Every operation that can make something large checks the size *before* making it: ``*``
(a repeated text or list, a product of integers), ``**`` (an integer power), ``%`` (a
%-format's widths), ``+`` and ``~`` (joined text), ``str.format`` (each field's width),
``range`` and the filters that take a width or a count. Loop turns and calls spend a budget
(:data:`MAX_STEPS`) with a deadline. Nothing is folded into constants while compiling (the
optimizer is off, every binary operator is intercepted and every filter takes the context),
so compiling a template costs only its length, whatever it asks for.

These bounds are the first line; the worker's deadline and memory limit are the second, for
a cost no check here foresaw (one C call that runs for minutes cannot be stopped from Python).
"""

from __future__ import annotations

import functools
import json
import time
from collections.abc import Callable, Iterable, Iterator, Mapping
from contextvars import ContextVar
from typing import Any

from hapticdesk.plugins.template_limits import (
    MAX_PIECE_CHARS,
    MAX_RANGE,
    MAX_RENDER_S,
    MAX_RENDERED_CHARS,
    MAX_STEPS,
    TemplateLimitError,
    check_power,
    check_product,
    check_size,
    check_widths,
    percent_widths,
    spec_widths,
)


class _Budget:
    """What is left of one rendering's steps and time."""

    __slots__ = ("deadline", "limit_s", "max_steps", "steps")

    def __init__(self, max_steps: int, limit_s: float, shown_s: float) -> None:
        self.steps = self.max_steps = max_steps
        self.limit_s = shown_s
        self.deadline = time.monotonic() + limit_s

    def spend(self, steps: int) -> None:
        self.steps -= steps
        if self.steps < 0:
            raise TemplateLimitError(f"it takes more than {self.max_steps} loop turns and calls")
        if time.monotonic() > self.deadline:
            raise TemplateLimitError(f"it takes longer than {self.limit_s:g} s")


#: the budget of the rendering under way in this thread
_BUDGET: ContextVar[_Budget | None] = ContextVar("hapticdesk_template_budget", default=None)


def _spend(steps: int = 1) -> None:
    budget = _BUDGET.get()
    if budget is not None:
        budget.spend(steps)


def _made(value: Any) -> Any:
    """``value``, spending a step per kB (or 1,000 items) it holds: text or lists built in a
    loop then cost what they take in memory, not one step each."""
    if isinstance(value, str | list | tuple | dict):
        _spend(len(value) // 1024)
    return value


def _counted(iterable: Iterable[Any]) -> Iterator[Any]:
    """``iterable``, spending one step of the rendering's budget per item."""
    for item in iterable:
        _spend()
        yield item


def _width(value: Any) -> int:
    return len(value) if isinstance(value, str) else int(value)


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


def _format_filter_size(s: Any, *args: Any, **kw: Any) -> int:
    check_widths(percent_widths(str(s), args), "the `format` filter")
    return len(str(s)) + len(str(args)) + len(str(kw)) + sum(percent_widths(str(s), args))


# filter -> an upper bound of its result's length from its arguments, computed before any
# text is made (the arguments are those Jinja passes the original: an environment or eval
# context first for `wordwrap`, `replace`, `tojson`)
_FILTER_SIZES: dict[str, Callable[..., int]] = {
    "center": lambda s, width=80: len(str(s)) + _width(width),
    "indent": lambda s, width=4, *_: len(str(s)) * (1 + _width(width)),
    "wordwrap": lambda _env, s, width=79, *_, **__: 2 * len(str(s)) + _width(width),
    "format": _format_filter_size,
    "tojson": lambda _ctx, value, indent=None: _json_size(value, indent),
    "replace": lambda _ctx, s, old, new, *_: len(str(s)) * max(1, len(str(new))) + len(str(new)),
    "truncate": lambda _env, s, length=255, *_, **__: min(len(str(s)), _width(length)) + 16,
}
#: filters whose count argument makes that many lists or items
_COUNT_FILTERS = {"batch": 1, "slice": 1}


def _bounded_join(eval_ctx: Any, value: Any, d: str = "", attribute: Any = None) -> Any:
    """``join``, stopped before the joined text passes MAX_PIECE_CHARS (``range(100000) |
    join('x' * 60000)`` had made 6 GB)."""
    from jinja2.filters import do_join

    items: list[Any] = []
    size = 0
    for item in value:
        _spend()
        items.append(item)
        size += len(str(item)) + len(str(d))
        check_size(size, "the `join` filter")
    return do_join(eval_ctx, items, d, attribute)


def _both_sequences(left: Any, right: Any) -> bool:
    return (isinstance(left, str) and isinstance(right, str)) or (
        isinstance(left, list | tuple) and isinstance(right, list | tuple)
    )


def _bounded_concat(*parts: Any) -> str:
    """``a ~ b ~ …`` (text joined), refused before it passes MAX_RENDERED_CHARS."""
    texts = [str(p) for p in parts]
    check_size(sum(len(t) for t in texts), "joining text with `~`", MAX_RENDERED_CHARS)
    return _made("".join(texts))


def _bounded_range(*args: Any) -> range:
    """``range``, of at most MAX_RANGE items (Jinja's sandbox allows 100,000)."""
    made = range(*args)
    if len(made) > MAX_RANGE:
        raise TemplateLimitError(f"a range of {len(made)} items; the limit is {MAX_RANGE}")
    return made


def _context_filter(name: str, original: Any, size: Callable[..., int] | None) -> Any:
    """``original`` as a filter that takes the context: such a filter is never folded into a
    constant while compiling (Jinja calls the others on constant arguments right then, so
    ``'x' | center(999999999)`` had been made by ``check`` itself). ``size`` bounds its
    result from its arguments before it runs."""
    from jinja2.utils import _PassArg, pass_context

    passes = _PassArg.from_obj(original)
    count_at = _COUNT_FILTERS.get(name)

    @pass_context
    @functools.wraps(original)
    def bounded(context: Any, *args: Any, **kwargs: Any) -> Any:
        if passes is _PassArg.context:
            first: tuple[Any, ...] = (context,)
        elif passes is _PassArg.eval_context:
            first = (context.eval_ctx,)
        elif passes is _PassArg.environment:
            first = (context.environment,)
        else:
            first = ()
        if size is not None:
            check_size(size(*first, *args, **kwargs), f"the `{name}` filter")
        if count_at is not None and len(args) > count_at and isinstance(args[count_at], int):
            if args[count_at] > MAX_PIECE_CHARS:
                raise TemplateLimitError(
                    f"the `{name}` filter asked for {args[count_at]} parts; the limit is "
                    f"{MAX_PIECE_CHARS}"
                )
        return original(*first, *args, **kwargs)

    # (functools.wraps copied the original's own marker; the context one must win)
    bounded.jinja_pass_arg = _PassArg.context  # type: ignore[attr-defined]
    return bounded


class _BoundedFormatter:
    """``str.format`` in the sandbox, refusing a field wider than MAX_FORMAT_WIDTH (its
    width known only once nested fields are filled: ``'{0:{1}}'.format(1, 10**9)``)."""

    @staticmethod
    def make(env: Any) -> Any:
        from jinja2.sandbox import SandboxedFormatter

        class Bounded(SandboxedFormatter):
            def format_field(self, value: Any, format_spec: str) -> Any:
                check_widths(spec_widths(format_spec), "a `format` field")
                return super().format_field(value, format_spec)

        return Bounded(env)


def _check_binop(operator: str, left: Any, right: Any) -> None:
    """Refuse ``left <operator> right`` when it would make something over the limits."""
    if operator == "*":
        check_product(left, right)
    elif operator == "**":
        check_power(left, right)
    elif operator == "%" and isinstance(left, str):
        check_widths(percent_widths(left, right), "a `%` format")
        check_size(len(left) + sum(percent_widths(left, right)), "a `%` format")
    elif operator == "+" and _both_sequences(left, right):
        check_size(len(left) + len(right), "joining with `+`", MAX_RENDERED_CHARS)


def _bounded_str_format(env: Any, value: Any) -> Callable[..., str]:
    """``text.format`` / ``text.format_map`` (``value``, a bound method of a text), each
    field's width checked once filled in, the result's length too."""
    text = value.__self__
    is_map = value.__name__ == "format_map"
    formatter = _BoundedFormatter.make(env)

    def bounded(*args: Any, **kwargs: Any) -> str:
        if is_map:
            if kwargs or len(args) != 1:
                raise TypeError("format_map() takes exactly one mapping")
            args, kwargs = (), args[0]
        out = formatter.vformat(text, args, kwargs)
        check_size(len(out), "`format`", MAX_RENDERED_CHARS)
        return type(text)(out)

    return bounded


@functools.cache
def _environment_class() -> type:
    """Jinja2's immutable sandbox, every cost checked (jinja2 is imported here)."""
    from jinja2.sandbox import ImmutableSandboxedEnvironment

    class BoundedEnvironment(ImmutableSandboxedEnvironment):
        # an intercepted operator is also never folded into a constant when compiling
        intercepted_binops = frozenset({"*", "**", "+", "-", "/", "//", "%"})

        def call_binop(self, context: Any, operator: str, left: Any, right: Any) -> Any:
            _check_binop(operator, left, right)
            _spend()
            return _made(super().call_binop(context, operator, left, right))

        def call(__self, __context: Any, __obj: Any, *args: Any, **kwargs: Any) -> Any:  # noqa: N805
            # every call of a sandboxed template comes here: a macro calling itself twice
            # is as costly as nested loops
            _spend()
            return _made(super().call(__context, __obj, *args, **kwargs))

        def call_filter(self, *args: Any, **kwargs: Any) -> Any:
            _spend()
            return _made(super().call_filter(*args, **kwargs))

        def wrap_str_format(self, value: Any) -> Any:
            if super().wrap_str_format(value) is None:
                return None
            return _bounded_str_format(self, value)

        def _parse(self, source: str, name: str | None, filename: str | None) -> Any:
            return _costs_counted()().visit(super()._parse(source, name, filename))

    return BoundedEnvironment


@functools.cache
def _costs_counted() -> type:
    """The transformer every parsed template passes: each `for` loop iterates through
    _counted (an empty loop body has no call and no output to count otherwise), and `a ~ b`
    joins text through a bounded call (it has no operator hook: a namespace doubling itself
    with `~` in a loop had no bound but the memory)."""
    from jinja2 import nodes
    from jinja2.visitor import NodeTransformer

    class CostsCounted(NodeTransformer):
        def visit_For(self, node: Any) -> Any:
            node = self.generic_visit(node)
            counter = nodes.EnvironmentAttribute("count_steps", lineno=node.lineno)
            node.iter = nodes.Call(counter, [node.iter], [], None, None, lineno=node.lineno)
            return node

        def visit_Concat(self, node: Any) -> Any:
            node = self.generic_visit(node)
            joined = nodes.EnvironmentAttribute("bounded_concat", lineno=node.lineno)
            return nodes.Call(joined, list(node.nodes), [], None, None, lineno=node.lineno)

    return CostsCounted


def make_environment() -> Any:
    """The bounded sandbox (see the module docstring); jinja2 is imported here."""
    from jinja2 import StrictUndefined
    from jinja2.utils import pass_eval_context

    env = _environment_class()(undefined=StrictUndefined, autoescape=False, optimized=False)
    env.count_steps = _counted
    env.bounded_concat = _bounded_concat
    del env.globals["lipsum"]  # random text of any length: no use in a payload
    env.globals["range"] = _bounded_range
    env.filters["join"] = pass_eval_context(_bounded_join)
    for name in list(env.filters):
        env.filters[name] = _context_filter(name, env.filters[name], _FILTER_SIZES.get(name))
    return env


@functools.cache
def environment() -> Any:
    """The one bounded environment of this process."""
    return make_environment()


def render_bounded(
    compiled: Any,
    variables: Mapping[str, Any],
    *,
    max_steps: int = MAX_STEPS,
    limit_s: float = MAX_RENDER_S,
    limit_shown_s: float | None = None,
) -> str:
    """The rendered text, stopped as soon as it grows past :data:`MAX_RENDERED_CHARS` or
    spends more than its budget of loop turns, calls and time (``limit_s``; the limit it
    is stopped short of, as the error says it, ``limit_shown_s``)."""
    parts: list[str] = []
    size = 0
    shown = limit_s if limit_shown_s is None else limit_shown_s
    token = _BUDGET.set(_Budget(max_steps, limit_s, shown))
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
