"""The sandbox a template renders in: Jinja2's immutable sandbox with every cost bounded.

This is the part of :mod:`hapticdesk.plugins.templating` that runs inside the template
worker (:mod:`hapticdesk.plugins.template_worker`), so it imports nothing of hapticdesk: the
worker starts fast and holds nothing but Jinja2.

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
import math
import re
import time
from collections.abc import Callable, Iterable, Iterator, Mapping
from contextvars import ContextVar
from string import Formatter
from typing import Any

#: the longest text a template may render in all (a payload is a few hundred characters)
MAX_RENDERED_CHARS = 65_536
#: the longest text or list one operation may make: a repetition (``'x' * n``), a join, a
#: padded field (``'%999d'``, ``'{:>999}'``), a filter's result
MAX_PIECE_CHARS = 16_384
#: the widest field a format may ask for (width or precision): a payload's numbers need a few
MAX_FORMAT_WIDTH = 1_024
#: the largest exponent of ``**``
MAX_EXPONENT = 1000
#: the largest integer an operation may make, in bits: 2**1100 is beyond any float already,
#: and no payload needs a number larger than a double
MAX_NUMBER_BITS = 1_100
#: the most items ``range`` may give (Jinja's own sandbox allows 100,000)
MAX_RANGE = 10_000
#: the most loop turns and calls one rendering may take (text or lists made on the way count
#: a step per kB): a payload loops over a few dozen items
MAX_STEPS = 100_000
#: how long one rendering may take, seconds (the worker's own check, at every loop turn and
#: call; the process that asked kills the worker a little later if a single C call holds on)
MAX_RENDER_S = 1.0


class TemplateLimitError(ValueError):
    """A template would render (or build on its way) more than the limits allow."""


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


def _limit(size: int, what: str, limit: int = MAX_PIECE_CHARS) -> None:
    if size > limit:
        raise TemplateLimitError(f"{what} would make {size} characters; the limit is {limit}")


def int_bits(value: Any) -> float:
    """About how many bits a number's integer part takes (0 for what is not a number)."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return 0.0
    if isinstance(value, int):
        return float(abs(value).bit_length())
    return math.log2(abs(value) + 1.0) if math.isfinite(value) else 0.0


def check_power(base: Any, exponent: Any) -> None:
    """Refuse ``base ** exponent`` when it would be a huge integer (before it is computed)."""
    if isinstance(exponent, bool) or not isinstance(exponent, int | float):
        return
    if abs(exponent) > MAX_EXPONENT:
        raise TemplateLimitError(f"an exponent over {MAX_EXPONENT} ({exponent})")
    if isinstance(base, int) and isinstance(exponent, int) and exponent > 0:
        bits = int_bits(base) * exponent
        if bits > MAX_NUMBER_BITS:
            raise TemplateLimitError(
                f"a power of about {bits * math.log10(2):.0f} digits; numbers are limited to "
                f"{MAX_NUMBER_BITS} bits (about {MAX_NUMBER_BITS * math.log10(2):.0f} digits)"
            )


def check_product(left: Any, right: Any) -> None:
    """Refuse ``left * right`` when it would be a long text or list, or a huge integer."""
    for seq, n in ((left, right), (right, left)):
        if isinstance(seq, str | list | tuple) and isinstance(n, int):
            _limit(len(seq) * n, "repeating")
    if isinstance(left, int) and isinstance(right, int):
        bits = int_bits(left) + int_bits(right)
        if bits > MAX_NUMBER_BITS:
            raise TemplateLimitError(
                f"a product of about {bits * math.log10(2):.0f} digits; numbers are limited "
                f"to {MAX_NUMBER_BITS} bits"
            )


def _digits(part: str) -> int:
    """A width or precision written in a format (digits; a thousand of them is not turned
    into an int: Python refuses that itself)."""
    return int(part) if len(part) <= 18 else 10**18


#: a %-conversion: an optional (key), flags, a width and a precision, each digits or `*`
_CONVERSION = re.compile(r"%(?:\([^)]*\))?[-+ #0]*(\d+|\*)?(?:\.(\d+|\*))?")


def percent_widths(text: str, args: Any = ()) -> list[int]:
    """The widths and precisions a %-format string asks for (``*`` takes the integers of
    ``args``), in order."""
    out: list[int] = []
    star = False
    for width, precision in _CONVERSION.findall(text):
        for part in (width, precision):
            if part == "*":
                star = True
            elif part:
                out.append(_digits(part))
    if star:
        items = args if isinstance(args, tuple | list) else (args,)
        out += [abs(a) for a in items if isinstance(a, int) and not isinstance(a, bool)]
    return out


_FORMAT_SPEC = re.compile(r"^(?:.?[<>=^])?[-+ ]?[z]?#?0?(\d*)[,_]?(?:\.(\d+))?")


def spec_widths(spec: str) -> list[int]:
    """The width and precision of one ``str.format`` field's spec (``>999``, ``.5f``)."""
    m = _FORMAT_SPEC.match(spec)
    if m is None:
        return []
    return [_digits(part) for part in m.groups() if part]


def format_string_widths(text: str) -> list[int]:
    """Every literal width and precision in a ``str.format`` string (nested fields too)."""
    out: list[int] = []
    try:
        parsed = list(Formatter().parse(text))
    except ValueError:  # not a valid format string: it fails when called, making nothing
        return out
    for _, _, spec, _ in parsed:
        if spec:
            out += spec_widths(spec)
            if "{" in spec:
                out += format_string_widths(spec)
    return out


def wide_field(widths: list[int], what: str) -> str | None:
    """What is wrong with the widest of ``widths``, if it is over MAX_FORMAT_WIDTH."""
    too_wide = [w for w in widths if w > MAX_FORMAT_WIDTH]
    if not too_wide:
        return None
    shown = f"{too_wide[0]}" if too_wide[0] < 10**18 else "more than 10**18"
    return (
        f"{what} asks for a field {shown} characters wide (or with that many decimals); "
        f"the limit is {MAX_FORMAT_WIDTH}"
    )


def check_widths(widths: list[int], what: str) -> None:
    problem = wide_field(widths, what)
    if problem is not None:
        raise TemplateLimitError(problem)


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
        _limit(size, "the `join` filter")
    return do_join(eval_ctx, items, d, attribute)


def _both_sequences(left: Any, right: Any) -> bool:
    return (isinstance(left, str) and isinstance(right, str)) or (
        isinstance(left, list | tuple) and isinstance(right, list | tuple)
    )


def _bounded_concat(*parts: Any) -> str:
    """``a ~ b ~ …`` (text joined), refused before it passes MAX_RENDERED_CHARS."""
    texts = [str(p) for p in parts]
    _limit(sum(len(t) for t in texts), "joining text with `~`", MAX_RENDERED_CHARS)
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
            _limit(size(*first, *args, **kwargs), f"the `{name}` filter")
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


def make_environment() -> Any:
    """The bounded sandbox (see the module docstring); jinja2 is imported here."""
    from jinja2 import StrictUndefined, nodes
    from jinja2.sandbox import ImmutableSandboxedEnvironment
    from jinja2.visitor import NodeTransformer

    class BoundedEnvironment(ImmutableSandboxedEnvironment):
        # an intercepted operator is also never folded into a constant when compiling
        intercepted_binops = frozenset({"*", "**", "+", "-", "/", "//", "%"})

        def call_binop(self, context: Any, operator: str, left: Any, right: Any) -> Any:
            if operator == "*":
                check_product(left, right)
            elif operator == "**":
                check_power(left, right)
            elif operator == "%" and isinstance(left, str):
                check_widths(percent_widths(left, right), "a `%` format")
                _limit(len(left) + sum(percent_widths(left, right)), "a `%` format")
            elif operator == "+" and _both_sequences(left, right):
                _limit(len(left) + len(right), "joining with `+`", MAX_RENDERED_CHARS)
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
            wrapped = super().wrap_str_format(value)
            if wrapped is None:
                return None
            text = value.__self__
            is_map = value.__name__ == "format_map"
            formatter = _BoundedFormatter.make(self)

            def bounded(*args: Any, **kwargs: Any) -> str:
                if is_map:
                    if kwargs or len(args) != 1:
                        raise TypeError("format_map() takes exactly one mapping")
                    args, kwargs = (), args[0]
                out = formatter.vformat(text, args, kwargs)
                _limit(len(out), "`format`", MAX_RENDERED_CHARS)
                return type(text)(out)

            return bounded

        def _parse(self, source: str, name: str | None, filename: str | None) -> Any:
            return _CostsCounted().visit(super()._parse(source, name, filename))

    class _CostsCounted(NodeTransformer):
        """Every `for` loop iterates through _counted (an empty loop body has no call and
        no output to count otherwise), and `a ~ b` joins text through a bounded call (it has
        no operator hook: a namespace doubling itself with `~` in a loop had no bound but
        the memory)."""

        def visit_For(self, node: Any) -> Any:
            node = self.generic_visit(node)
            counter = nodes.EnvironmentAttribute("count_steps", lineno=node.lineno)
            node.iter = nodes.Call(counter, [node.iter], [], None, None, lineno=node.lineno)
            return node

        def visit_Concat(self, node: Any) -> Any:
            node = self.generic_visit(node)
            joined = nodes.EnvironmentAttribute("bounded_concat", lineno=node.lineno)
            return nodes.Call(joined, list(node.nodes), [], None, None, lineno=node.lineno)

    env = BoundedEnvironment(undefined=StrictUndefined, autoescape=False, optimized=False)
    env.count_steps = _counted  # type: ignore[attr-defined]
    env.bounded_concat = _bounded_concat  # type: ignore[attr-defined]
    del env.globals["lipsum"]  # random text of any length: no use in a payload
    env.globals["range"] = _bounded_range
    from jinja2.utils import pass_eval_context

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


# --- before anything runs: what the text itself asks for -------------------------------------

#: the variables that always hold text (a repetition of one of them is a repetition of text)
TEXT_VARIABLES = frozenset(
    {"gesture", "region", "shape", "direction", "level", "phase", "action", "desk"}
)
#: filters whose numeric argument (after the value) is a size or a count of parts
_SIZE_ARGUMENT_FILTERS = frozenset({"center", "indent", "truncate", "wordwrap", "batch", "slice"})


def static_problems(tree: Any) -> list[str]:
    """What a parsed template asks for beyond the limits in its text alone, whatever event
    it is rendered for: literal arithmetic making a huge number (``9**999``, powers of
    powers), a literal format's widths (``'%999999999d'``, ``'{:>999999999}'``), a literal
    repetition (``'x' * 60000``), a ``range`` or a filter's size over the limits. Each a
    sentence; empty when none. (What depends on the event is bounded while rendering.)"""
    from jinja2 import nodes

    problems: list[str] = []

    def number(node: Any) -> float | None:
        if isinstance(node, nodes.Const) and isinstance(node.value, int | float):
            return None if isinstance(node.value, bool) else float(node.value)
        if isinstance(node, nodes.Neg):
            inner = number(node.node)
            return None if inner is None else -inner
        return None

    def bits(node: Any) -> float | None:
        """The size of a constant arithmetic expression's result in bits (None: unknown)."""
        value = number(node)
        if value is not None:
            return int_bits(value)
        if isinstance(node, nodes.Neg | nodes.Pos):
            return bits(node.node)
        if isinstance(node, nodes.Pow):
            base, exponent = bits(node.left), number(node.right)
            if exponent is None:
                exponent_bits = bits(node.right)  # a power of a power: 9 ** (9 ** 9)
                if base is None or exponent_bits is None:
                    return None
                return math.inf if exponent_bits > 64 else base * 2.0**exponent_bits
            return None if base is None else base * max(exponent, 0.0)
        if isinstance(node, nodes.Mul):
            left, right = bits(node.left), bits(node.right)
            return None if left is None or right is None else left + right
        if isinstance(node, nodes.Add | nodes.Sub):
            left, right = bits(node.left), bits(node.right)
            return None if left is None or right is None else max(left, right) + 1
        if isinstance(node, nodes.Div | nodes.FloorDiv | nodes.Mod):
            return bits(node.left)
        return None

    def length(node: Any) -> int | None:
        """The least length of what ``node`` makes when it is text or a list."""
        if isinstance(node, nodes.Const) and isinstance(node.value, str | list | tuple):
            return len(node.value)
        if isinstance(node, nodes.List | nodes.Tuple):
            return len(node.items)
        if isinstance(node, nodes.Name) and node.name in TEXT_VARIABLES:
            return 1  # (an empty region name is not possible, a gesture's never empty)
        if isinstance(node, nodes.Mul):
            for seq, count in ((node.left, node.right), (node.right, node.left)):
                inner, n = length(seq), number(count)
                if inner is not None and n is not None:
                    return int(inner * max(n, 0))
        return None

    for node in tree.find_all((nodes.Pow, nodes.Mul)):
        if isinstance(node, nodes.Pow):
            exponent = number(node.right)
            if exponent is not None and abs(exponent) > MAX_EXPONENT:
                problems.append(f"an exponent over {MAX_EXPONENT} ({exponent:g})")
        size = bits(node)
        if size is not None and size > MAX_NUMBER_BITS:
            digits = "more than a billion" if size > 3e9 else f"about {size * math.log10(2):.0f}"
            problems.append(
                f"literal arithmetic making a number of {digits} digits; numbers are limited "
                f"to {MAX_NUMBER_BITS} bits (about {MAX_NUMBER_BITS * math.log10(2):.0f} digits)"
            )
        made = length(node) if isinstance(node, nodes.Mul) else None
        if made is not None and made > MAX_PIECE_CHARS:
            problems.append(
                f"a repetition making {made} characters or items; the limit is {MAX_PIECE_CHARS}"
            )
    for node in tree.find_all((nodes.Mod, nodes.Call, nodes.Filter)):
        widths: list[int] = []
        if isinstance(node, nodes.Mod) and isinstance(node.left, nodes.Const):
            if isinstance(node.left.value, str):
                widths = percent_widths(node.left.value)
        elif isinstance(node, nodes.Call):
            callee = node.node
            if isinstance(callee, nodes.Name) and callee.name == "range":
                counts = [number(a) for a in node.args]
                if counts and all(c is not None and c == int(c) for c in counts):
                    try:
                        items = len(range(*(int(c) for c in counts if c is not None)))
                    except (ValueError, OverflowError):
                        items = 0
                    if items > MAX_RANGE:
                        problems.append(f"a range of {items} items; the limit is {MAX_RANGE}")
            elif (
                isinstance(callee, nodes.Getattr)
                and callee.attr in ("format", "format_map")
                and isinstance(callee.node, nodes.Const)
                and isinstance(callee.node.value, str)
            ):
                widths = format_string_widths(callee.node.value)
        elif isinstance(node, nodes.Filter):
            if node.name == "format" and isinstance(node.node, nodes.Const):
                if isinstance(node.node.value, str):
                    widths = percent_widths(node.node.value)
            elif node.name in _SIZE_ARGUMENT_FILTERS:
                for arg in node.args:
                    n = number(arg)
                    if n is not None and n > MAX_PIECE_CHARS:
                        problems.append(
                            f"the `{node.name}` filter asked for {n:g} (characters or parts); "
                            f"the limit is {MAX_PIECE_CHARS}"
                        )
        problem = wide_field(widths, "a format")
        if problem is not None:
            problems.append(problem)
    return problems
