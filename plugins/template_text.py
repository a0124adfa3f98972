"""What a template's text says before anything runs: its costs, its comparisons, its slips.

Read from the parsed template (Jinja2's node tree) when a layout is loaded:

- :func:`static_problems`: what it asks for beyond the limits in its text alone, whichever
  branch it stands in (literal arithmetic making a huge number, a literal format's widths, a
  literal repetition, a ``range`` or a filter's size);
- :func:`compared_constants`: the constants it compares a variable with (``region == 'b5'``),
  so ``check`` renders the branch they guard too;
- :func:`filters_on_a_number`: ``value * 254 | round``, a filter on a lone number where the
  result of the arithmetic was meant.

Imported when a layout has a template (it imports jinja2).
"""

from __future__ import annotations

import math
from collections.abc import Collection
from typing import Any

from jinja2 import nodes

from hapticdesk.plugins.template_limits import (
    MAX_EXPONENT,
    MAX_NUMBER_BITS,
    MAX_PIECE_CHARS,
    MAX_RANGE,
    format_string_widths,
    int_bits,
    percent_widths,
    wide_field,
)

#: the variables that always hold text (a repetition of one of them is a repetition of text)
TEXT_VARIABLES = frozenset(
    {"gesture", "region", "shape", "direction", "level", "phase", "action", "desk"}
)
#: filters whose numeric argument (after the value) is a size or a count of parts
_SIZE_ARGUMENT_FILTERS = frozenset({"center", "indent", "truncate", "wordwrap", "batch", "slice"})


def static_problems(tree: nodes.Template) -> list[str]:
    """What a parsed template asks for beyond the limits in its text alone, whatever event
    it is rendered for: literal arithmetic making a huge number (``9**999``, powers of
    powers), a literal format's widths (``'%999999999d'``, ``'{:>999999999}'``), a literal
    repetition (``'x' * 60000``), a ``range`` or a filter's size over the limits. Each a
    sentence; empty when none. (What depends on the event is bounded while rendering.)"""
    problems: list[str] = []
    for node in tree.find_all((nodes.Pow, nodes.Mul)):
        problems += _arithmetic_problems(node)
    for node in tree.find_all((nodes.Mod, nodes.Call, nodes.Filter)):
        problems += _size_problems(node)
        problem = wide_field(_widths_asked(node), "a format")
        if problem is not None:
            problems.append(problem)
    return problems


def _number(node: nodes.Node) -> float | None:
    """The value of a literal number (negated or not), else None."""
    if isinstance(node, nodes.Const) and isinstance(node.value, int | float):
        return None if isinstance(node.value, bool) else float(node.value)
    if isinstance(node, nodes.Neg):
        inner = _number(node.node)
        return None if inner is None else -inner
    return None


def _bits(node: nodes.Node) -> float | None:
    """The size of a constant arithmetic expression's result in bits (None: unknown)."""
    value = _number(node)
    if value is not None:
        return int_bits(value)
    if isinstance(node, nodes.Neg | nodes.Pos):
        return _bits(node.node)
    if isinstance(node, nodes.Pow):
        base, exponent = _bits(node.left), _number(node.right)
        if exponent is None:
            exponent_bits = _bits(node.right)  # a power of a power: 9 ** (9 ** 9)
            if base is None or exponent_bits is None:
                return None
            return math.inf if exponent_bits > 64 else base * 2.0**exponent_bits
        return None if base is None else base * max(exponent, 0.0)
    if isinstance(node, nodes.Mul):
        left, right = _bits(node.left), _bits(node.right)
        return None if left is None or right is None else left + right
    if isinstance(node, nodes.Add | nodes.Sub):
        left, right = _bits(node.left), _bits(node.right)
        return None if left is None or right is None else max(left, right) + 1
    if isinstance(node, nodes.Div | nodes.FloorDiv | nodes.Mod):
        return _bits(node.left)
    return None


def _length(node: nodes.Node) -> int | None:
    """The least length of what ``node`` makes when it is text or a list."""
    if isinstance(node, nodes.Const) and isinstance(node.value, str | list | tuple):
        return len(node.value)
    if isinstance(node, nodes.List | nodes.Tuple):
        return len(node.items)
    if isinstance(node, nodes.Name) and node.name in TEXT_VARIABLES:
        return 1  # (an empty region name is not possible, a gesture's never empty)
    if isinstance(node, nodes.Mul):
        for seq, count in ((node.left, node.right), (node.right, node.left)):
            inner, n = _length(seq), _number(count)
            if inner is not None and n is not None:
                return int(inner * max(n, 0))
    return None


def _arithmetic_problems(node: nodes.Pow | nodes.Mul) -> list[str]:
    """A power's exponent, a huge number, a long repetition, in literal arithmetic."""
    problems: list[str] = []
    if isinstance(node, nodes.Pow):
        exponent = _number(node.right)
        if exponent is not None and abs(exponent) > MAX_EXPONENT:
            problems.append(f"an exponent over {MAX_EXPONENT} ({exponent:g})")
    size = _bits(node)
    if size is not None and size > MAX_NUMBER_BITS:
        digits = "more than a billion" if size > 3e9 else f"about {size * math.log10(2):.0f}"
        problems.append(
            f"literal arithmetic making a number of {digits} digits; numbers are limited "
            f"to {MAX_NUMBER_BITS} bits (about {MAX_NUMBER_BITS * math.log10(2):.0f} digits)"
        )
    made = _length(node) if isinstance(node, nodes.Mul) else None
    if made is not None and made > MAX_PIECE_CHARS:
        problems.append(
            f"a repetition making {made} characters or items; the limit is {MAX_PIECE_CHARS}"
        )
    return problems


def _size_problems(node: nodes.Node) -> list[str]:
    """A literal ``range`` over MAX_RANGE items, a filter asked for a size over the limit."""
    if isinstance(node, nodes.Call):
        callee = node.node
        if not (isinstance(callee, nodes.Name) and callee.name == "range"):
            return []
        counts = [_number(a) for a in node.args]
        if not counts or not all(c is not None and c == int(c) for c in counts):
            return []
        try:
            items = len(range(*(int(c) for c in counts if c is not None)))
        except (ValueError, OverflowError):
            items = 0
        return [f"a range of {items} items; the limit is {MAX_RANGE}"] if items > MAX_RANGE else []
    if isinstance(node, nodes.Filter) and node.name in _SIZE_ARGUMENT_FILTERS:
        return [
            f"the `{node.name}` filter asked for {n:g} (characters or parts); "
            f"the limit is {MAX_PIECE_CHARS}"
            for n in (_number(arg) for arg in node.args)
            if n is not None and n > MAX_PIECE_CHARS
        ]
    return []


def _widths_asked(node: nodes.Node) -> list[int]:
    """The widths a literal format asks for: ``'…' % x``, ``'…'.format(…)``, ``|format``."""
    if isinstance(node, nodes.Mod) and isinstance(node.left, nodes.Const):
        if isinstance(node.left.value, str):
            return percent_widths(node.left.value)
    elif isinstance(node, nodes.Call):
        callee = node.node
        if (
            isinstance(callee, nodes.Getattr)
            and callee.attr in ("format", "format_map")
            and isinstance(callee.node, nodes.Const)
            and isinstance(callee.node.value, str)
        ):
            return format_string_widths(callee.node.value)
    elif isinstance(node, nodes.Filter) and node.name == "format":
        if isinstance(node.node, nodes.Const) and isinstance(node.node.value, str):
            return percent_widths(node.node.value)
    return []


def filters_on_a_number(tree: nodes.Template) -> list[tuple[str, Any, str]]:
    """(filters, number, operator) of each ``value * 254 | round``: a filter binds tighter
    than arithmetic, so this rounds 254 and sends the product unrounded (a brightness of
    24.93). A filter on a lone number is never meant: the template's compiler says so as a
    layout warning."""
    found = []
    for op in tree.find_all(nodes.BinExpr):
        names, inner = [], op.right
        while isinstance(inner, nodes.Filter):
            names.append(inner.name)
            inner = inner.node
        if names and isinstance(inner, nodes.Const) and not isinstance(op.left, nodes.Const):
            found.append((" | ".join(reversed(names)), inner.value, op.operator))
    return found


def compared_constants(
    tree: nodes.Template, variables: Collection[str], event_fields: Collection[str]
) -> dict[str, set[Any]]:
    """Variable -> the constants the template compares it with (``region == 'b5'``,
    ``direction in ['up', 'down']``, ``event.level == 'hard'``): the values a check renders
    it with besides the sample's, so the branch they guard is rendered too. ``variables``:
    the names a template can use; ``event_fields``: those also under ``event.``."""
    found: dict[str, set[Any]] = {}
    for compare in tree.find_all(nodes.Compare):
        operands = [compare.expr, *(op.expr for op in compare.ops)]
        for a, b in zip(operands, operands[1:], strict=False):
            for name_node, value_node in ((a, b), (b, a)):
                name = _variable(name_node, variables, event_fields)
                if name is not None:
                    found.setdefault(name, set()).update(_constants(value_node))
    return found


def _variable(
    node: nodes.Node, variables: Collection[str], event_fields: Collection[str]
) -> str | None:
    """The variable ``node`` reads (``region``, ``event.region``, ``event['region']``)."""
    if isinstance(node, nodes.Name) and node.name in variables:
        return str(node.name)
    if isinstance(node, nodes.Getattr | nodes.Getitem) and isinstance(node.node, nodes.Name):
        if node.node.name == "event":
            key = node.attr if isinstance(node, nodes.Getattr) else None
            if isinstance(node, nodes.Getitem) and isinstance(node.arg, nodes.Const):
                key = node.arg.value
            return key if key in event_fields else None
    return None


def _constants(node: nodes.Node) -> list[Any]:
    """The literal texts and numbers of ``node`` (a constant, or a list or tuple of them)."""
    if isinstance(node, nodes.Const) and isinstance(node.value, str | int | float):
        return [node.value]
    if isinstance(node, nodes.List | nodes.Tuple):
        return [c for item in node.items for c in _constants(item)]
    return []
