"""The limits a template renders within: their values, the errors that say one is passed,
how what a template asks for is measured (a number's bits, a format's widths) and the checks
that refuse it before it is made.

Shared by the two places that hold a template to the limits: the sandbox while it renders
(:mod:`.template_sandbox`, inside the template worker) and the reading of the text before
anything runs (:mod:`.template_text`). Imports nothing of hapticdesk: the worker starts fast.
"""

from __future__ import annotations

import math
import re
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


class TemplateError(ValueError):
    """A template failed while rendering for one event (reported by the dispatcher)."""


class TemplateLimitError(TemplateError):
    """A template would render (or build on its way) more than the limits allow."""


def int_bits(value: Any) -> float:
    """About how many bits a number's integer part takes (0 for what is not a number)."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return 0.0
    if isinstance(value, int):
        return float(abs(value).bit_length())
    return math.log2(abs(value) + 1.0) if math.isfinite(value) else 0.0


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


def check_size(size: int, what: str, limit: int = MAX_PIECE_CHARS) -> None:
    """Refuse making ``size`` characters (or items) for ``what`` past ``limit``."""
    if size > limit:
        raise TemplateLimitError(f"{what} would make {size} characters; the limit is {limit}")


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
            check_size(len(seq) * n, "repeating")
    if isinstance(left, int) and isinstance(right, int):
        bits = int_bits(left) + int_bits(right)
        if bits > MAX_NUMBER_BITS:
            raise TemplateLimitError(
                f"a product of about {bits * math.log10(2):.0f} digits; numbers are limited "
                f"to {MAX_NUMBER_BITS} bits"
            )


def check_widths(widths: list[int], what: str) -> None:
    """Refuse a format asking for a field wider than MAX_FORMAT_WIDTH."""
    problem = wide_field(widths, what)
    if problem is not None:
        raise TemplateLimitError(problem)
