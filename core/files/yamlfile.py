"""YAML loading that remembers where every key and value stood, for errors users can act on.

Profiles, layouts and scenes are written by hand. When one is wrong the user must be told the
file, line and column and what was expected (STYLE.md 9), never shown a traceback. This module
loads YAML into ordinary dicts and lists that also carry the position of each key and item.
"""

from __future__ import annotations

import contextlib
import os
import re
import stat
import warnings
from collections.abc import Callable, Iterator
from contextvars import ContextVar
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml
from yaml.composer import Composer
from yaml.constructor import SafeConstructor
from yaml.parser import Parser
from yaml.reader import Reader
from yaml.resolver import Resolver
from yaml.scanner import Scanner

# YAML 1.1 reads these bare words as booleans; as keys they are almost always a mistake.
_YAML11_BOOL_WORDS = {"on", "off", "yes", "no", "y", "n", "true", "false"}


@dataclass(frozen=True)
class Position:
    """A place in a file: 1-based line and column."""

    file: str
    line: int
    column: int

    def __str__(self) -> str:
        return f"{self.file}:{self.line}:{self.column}"


class ConfigError(ValueError):
    """A user-written file is wrong. ``str(err)`` is ``file:line:column: what was expected``."""

    def __init__(self, where: Position | str | None, message: str) -> None:
        self.where = where
        self.message = message
        super().__init__(f"{where}: {message}" if where is not None else message)


class LayoutWarning(UserWarning):
    """A layout that works, but likely not as its author meant. A plugin's check of its
    options says it with ``warnings.warn(LayoutWarning(...))``; the layout reader collects it
    into :attr:`Layout.warnings` (``check`` shows them, ``run`` logs them). Anywhere else,
    e.g. when a run builds the actions again, it is not shown a second time."""


warnings.filterwarnings("ignore", category=LayoutWarning)


class MarkedDict(dict[str, Any]):
    """A mapping from YAML that knows the position of itself, each key and each value."""

    position: Position
    key_positions: dict[str, Position]
    value_positions: dict[str, Position]

    def where(self, key: str | None = None, *, of_key: bool = False) -> Position:
        """Position of ``key``'s value (or of the key itself), or of the mapping."""
        if key is None:
            return self.position
        table = self.key_positions if of_key else self.value_positions
        return table.get(key, self.position)


class MarkedList(list[Any]):
    """A sequence from YAML that knows the position of itself and of each item."""

    position: Position
    item_positions: list[Position]

    def where(self, index: int | None = None) -> Position:
        """Position of item ``index``, or of the sequence."""
        if index is None or index >= len(self.item_positions):
            return self.position
        return self.item_positions[index]


#: the largest file read; hand-written profiles, layouts and scenes are a few kilobytes
MAX_BYTES = 1_000_000
#: the most values (scalars, lists, mappings) a document may hold, an alias counted each time
#: it is used: a few aliases can otherwise stand for billions of values ("billion laughs")
MAX_VALUES = 50_000
#: the deepest nesting of lists and mappings (the loaders recurse once per level)
MAX_DEPTH = 64
_TOO_DEEP = f"lists and mappings nest more than {MAX_DEPTH} deep here; is a bracket left open?"
#: the longest number, in characters: a longer one is a mistake, and a huge one is slow to read
MAX_NUMBER_CHARS = 32
# tags PyYAML would build into objects the validators do not expect (bytes, sets, pairs)
_UNSUPPORTED_TAGS = {
    f"tag:yaml.org,2002:{name}": name for name in ("binary", "set", "omap", "pairs")
}
_NUMBER_TAGS = {"tag:yaml.org,2002:int", "tag:yaml.org,2002:float"}
_TIMESTAMP_TAG = "tag:yaml.org,2002:timestamp"


def _pos(file: str, node: yaml.Node | yaml.Event) -> Position:
    mark = node.start_mark
    return Position(file, mark.line + 1, mark.column + 1) if mark else Position(file, 1, 1)


class _BoundedComposer(Composer):
    """PyYAML's composer, refusing documents too deep or too large once aliases expand.

    The node graph PyYAML composes shares an anchored node among its aliases; the marked
    values built from it (and every validator after) do not, so the expanded size is what
    counts. It is tallied as the nodes are composed: a node adds one, an alias adds the
    expanded size of its anchor. An alias inside its own anchor would expand forever.
    """

    peek_event: Callable[[], yaml.Event]  # from the parser it is mixed with

    def __init__(self, file: str) -> None:
        super().__init__()
        self.file = file
        self.expanded = 0
        self.depth = 0
        self.anchor_sizes: dict[str, int] = {}
        self.open_anchors: set[str] = set()

    def compose_node(self, parent: yaml.Node | None, index: Any) -> yaml.Node | None:
        event = self.peek_event()
        if isinstance(event, yaml.AliasEvent):
            if event.anchor in self.open_anchors:
                raise ConfigError(
                    _pos(self.file, event),
                    f"alias *{event.anchor} refers to the value that holds it, which would "
                    "never end; an alias may only repeat a value defined before it",
                )
            self._count(self.anchor_sizes.get(event.anchor or "", 1), event)
            return super().compose_node(parent, index)
        self.depth += 1
        if self.depth > MAX_DEPTH:
            raise ConfigError(_pos(self.file, event), _TOO_DEEP)
        before = self.expanded
        self._count(1, event)
        anchor = getattr(event, "anchor", None)
        if anchor is not None:
            self.open_anchors.add(anchor)
        node = super().compose_node(parent, index)
        if anchor is not None:
            self.open_anchors.discard(anchor)
            self.anchor_sizes[anchor] = self.expanded - before
        self.depth -= 1
        return node

    def _count(self, values: int, event: yaml.Event) -> None:
        self.expanded += values
        if self.expanded > MAX_VALUES:
            what = "with its aliases expanded " if isinstance(event, yaml.AliasEvent) else ""
            raise ConfigError(
                _pos(self.file, event),
                f"the file holds more than {MAX_VALUES} values {what}by here; "
                "a profile, layout or scene needs far fewer",
            )


if yaml.__with_libyaml__:  # libyaml's parser, PyYAML's (bounded) composer: 3x faster
    from yaml._yaml import CParser

    class _Loader(_BoundedComposer, CParser, SafeConstructor, Resolver):
        def __init__(self, text: str, file: str) -> None:
            CParser.__init__(self, text)
            _BoundedComposer.__init__(self, file)
            SafeConstructor.__init__(self)
            Resolver.__init__(self)

else:  # pragma: no cover - PyYAML built without libyaml

    class _Loader(Reader, Scanner, Parser, _BoundedComposer, SafeConstructor, Resolver):  # type: ignore[no-redef]
        def __init__(self, text: str, file: str) -> None:
            Reader.__init__(self, text)
            Scanner.__init__(self)
            Parser.__init__(self)
            _BoundedComposer.__init__(self, file)
            SafeConstructor.__init__(self)
            Resolver.__init__(self)


# YAML 1.1 (PyYAML) reads a float only with a dot and a signed exponent: `5e-2`, `1e6` and
# `2.5e3` are text, and a profile's `1e6` an error that looks absurd (YAML 1.2, and ruamel
# which the browser UI edits with, read them as numbers). Such a plain (unquoted) scalar is
# kept as the text written, marked: :func:`number` and :func:`vector` read it as the number
# it is, while a payload or an argv that means text keeps `1e3` as written (a resolver for
# the whole file turned an exec's `1e3` argument into "1000.0").
_EXPONENT_FLOAT = re.compile(r"[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+")


class NumberText(str):
    """A plain YAML scalar that YAML 1.2 reads as a float and YAML 1.1 as text (``1e6``)."""


class FlagText(str):
    """A plain YAML scalar that YAML 1.1 (PyYAML) reads as a boolean and YAML 1.2 (and ruamel,
    which the browser UI edits with) as text: ``on``, ``off``, ``yes``, ``no`` in any case.
    Kept as the text written, so that a Zigbee2MQTT payload's ``state: ON`` is sent as "ON"
    (it went out as ``true``); a setting that is true or false reads it through
    :func:`as_flag`, as before."""


_FLAG_TRUE = {"on", "yes"}
# YAML 1.1's octal ints (`010` is 8); YAML 1.2 writes octal `0o10` and reads `010` as 10
_YAML11_OCTAL = re.compile(r"[-+]?0[0-7_]+")


def as_flag(value: Any) -> Any:
    """``value``, or the boolean a :class:`FlagText` says."""
    return value.lower() in _FLAG_TRUE if isinstance(value, FlagText) else value


def _yaml12_scalar(node: yaml.ScalarNode) -> Any:
    """Where YAML 1.1 and 1.2 read a plain scalar differently, 1.2's reading (the UI's
    ruamel and every other current YAML reader agree with it); else None. A sexagesimal
    `1:30` is text in 1.2 (PyYAML: 90), `010` is 10 (PyYAML: 8), `on` text (PyYAML: true)."""
    value = node.value
    if node.tag == "tag:yaml.org,2002:bool" and value.lower() not in ("true", "false"):
        return FlagText(value)
    if node.tag in _NUMBER_TAGS and ":" in value:
        return value
    if node.tag == "tag:yaml.org,2002:int" and _YAML11_OCTAL.fullmatch(value):
        return int(value.replace("_", ""), 10)
    return None


def as_number(value: Any) -> Any:
    """``value``, or the float a :class:`NumberText` writes."""
    return float(value.replace("_", "")) if isinstance(value, NumberText) else value


def _construct(node: yaml.Node, file: str, loader: _Loader) -> Any:
    if isinstance(node, yaml.MappingNode):
        if node.tag in _UNSUPPORTED_TAGS:
            raise _unsupported(node, file)
        loader.flatten_mapping(node)
        out = MarkedDict()
        out.position = _pos(file, node)
        out.key_positions = {}
        out.value_positions = {}
        for key_node, value_node in node.value:
            key = _construct(key_node, file, loader)
            if not isinstance(key, str):
                raw = key_node.value if isinstance(key_node, yaml.ScalarNode) else key
                hint = ""
                if isinstance(raw, str) and raw.lower() in _YAML11_BOOL_WORDS:
                    hint = f"; YAML reads a bare `{raw}` as a boolean, write it in quotes"
                raise ConfigError(_pos(file, key_node), f"keys must be text, found {raw!r}{hint}")
            if key in out:
                raise ConfigError(_pos(file, key_node), f"key `{key}` appears twice")
            out[key] = _construct(value_node, file, loader)
            out.key_positions[key] = _pos(file, key_node)
            out.value_positions[key] = _pos(file, value_node)
        return out
    if isinstance(node, yaml.SequenceNode):
        if node.tag in _UNSUPPORTED_TAGS:
            raise _unsupported(node, file)
        seq = MarkedList(_construct(item, file, loader) for item in node.value)
        seq.position = _pos(file, node)
        seq.item_positions = [_pos(file, item) for item in node.value]
        return seq
    if node.tag in _UNSUPPORTED_TAGS:
        raise _unsupported(node, file)
    if node.tag == _TIMESTAMP_TAG:
        return str(node.value)  # a date as written: nothing here reads dates
    if (
        isinstance(node, yaml.ScalarNode)
        and node.tag == "tag:yaml.org,2002:str"
        and not node.style  # plain: None from PyYAML's parser, "" from libyaml's
        and len(node.value) <= MAX_NUMBER_CHARS
        and _EXPONENT_FLOAT.fullmatch(node.value)
    ):
        return NumberText(node.value)
    if isinstance(node, yaml.ScalarNode) and not node.style and len(node.value) <= MAX_NUMBER_CHARS:
        read = _yaml12_scalar(node)
        if read is not None:
            return read
    if node.tag in _NUMBER_TAGS and len(node.value) > MAX_NUMBER_CHARS:
        raise ConfigError(
            _pos(file, node),
            f"a number of {len(node.value)} characters; numbers here have at most "
            f"{MAX_NUMBER_CHARS}",
        )
    return loader.construct_object(node, deep=True)


def _unsupported(node: yaml.Node, file: str) -> ConfigError:
    name = _UNSUPPORTED_TAGS[node.tag]
    return ConfigError(
        _pos(file, node),
        f"a YAML !!{name} is not read here; write text, numbers, lists and mappings",
    )


def load_marked_yaml(path: str | Path, text: str | None = None, max_bytes: int = MAX_BYTES) -> Any:
    """Load one YAML document from ``path`` (or from ``text``, naming it ``path``).

    Raises :class:`ConfigError` with the position for every problem: a file over
    ``max_bytes``, text that is not UTF-8, invalid YAML, nesting deeper than
    :data:`MAX_DEPTH`, more than :data:`MAX_VALUES` values once aliases are expanded.
    """
    file = str(path)
    data = _read_bytes(Path(path), max_bytes) if text is None else _encode(text, file)
    if len(data) > max_bytes:
        raise ConfigError(
            Position(file, 1, 1),
            f"the file is larger than {max_bytes / 1e6:g} MB, the limit for a profile, layout "
            "or scene (they are a few kB)",
        )
    text = _decode(data, file)
    loader = _Loader(text, file)
    try:
        node = loader.get_single_node()
        if node is None:
            raise ConfigError(Position(file, 1, 1), "the file is empty, expected a mapping")
        return _construct(node, file, loader)
    except yaml.MarkedYAMLError as err:
        mark = err.problem_mark or err.context_mark
        where = Position(file, mark.line + 1, mark.column + 1) if mark else file
        if "nesting depth" in str(err.problem):
            # libyaml from PyYAML 6.0.4 on stops at 1000 levels while it scans ahead on one
            # line, before the composer has seen the 65th: the same mistake, the same words
            raise ConfigError(where, _TOO_DEEP) from None
        raise ConfigError(where, f"not valid YAML: {err.problem or err}") from None
    except yaml.reader.ReaderError as err:
        # libyaml counts the offset in bytes of the UTF-8 text, PyYAML's reader in characters
        offset = err.position if yaml.__with_libyaml__ else len(text[: err.position].encode())
        raise ConfigError(
            _byte_position(data, offset, file),
            f"not valid YAML: character {err.character!r} is not allowed ({err.reason})",
        ) from None
    except yaml.YAMLError as err:  # no position known
        raise ConfigError(Position(file, 1, 1), f"not valid YAML: {err}") from None
    finally:
        loader.dispose()


def _read_bytes(path: Path, max_bytes: int) -> bytes:
    """At most ``max_bytes + 1`` bytes: enough to tell that a file is too large."""
    regular_file_size(path, "the file")
    try:
        with path.open("rb") as f:
            return f.read(max_bytes + 1)
    except OSError as err:
        raise ConfigError(str(path), f"cannot read the file: {err.strerror or err}") from None


_FILE_KINDS = (
    (stat.S_ISREG, "a regular file"),
    (stat.S_ISDIR, "a directory"),
    (stat.S_ISFIFO, "a named pipe (FIFO)"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
)


def file_kind(mode: int) -> str:
    """What a file of ``os.stat`` mode ``mode`` is, for a message (``a directory`` …)."""
    return next((name for test, name in _FILE_KINDS if test(mode)), "not a regular file")


#: while set (:func:`reads_confined_to`), the only folders files are read from
_READ_ROOTS: ContextVar[tuple[Path, ...] | None] = ContextVar("read_roots", default=None)


@contextlib.contextmanager
def reads_confined_to(*roots: str | Path) -> Iterator[None]:
    """Within it, a file outside ``roots`` (after symlinks and ``..``) is not read: the
    browser UI checks a layout a page sent, and its `desk: /etc/passwd` had been read and
    quoted back in the error."""
    token = _READ_ROOTS.set(tuple(Path(r).resolve() for r in roots))
    try:
        yield
    finally:
        _READ_ROOTS.reset(token)


def check_confined(path: str | Path, what: str, where: Position | str | None = None) -> None:
    """ConfigError (at ``where``, else at the path) when reads are confined
    (:func:`reads_confined_to`) and ``path`` lies outside every root.

    Called *before* anything looks at the path (exists, is a file or a folder, its listing):
    the answer for a path outside is then the same whether it exists or not (``layouts: {x:
    /etc/shadow}`` had been accepted where a missing file was "no such file", and
    ``templates: /root`` had named a folder in it)."""
    roots = _READ_ROOTS.get()
    if roots is None:
        return
    real = Path(path).resolve()
    if not any(real.is_relative_to(root) for root in roots):
        raise ConfigError(
            str(path) if where is None else where,
            f"{what} lies outside the layout's folder: a layout edited in the browser reads "
            "files there only (and the shipped profiles and examples)",
        )


def regular_file_size(path: str | Path, what: str) -> int:
    """The size in bytes of ``path``, which must be a regular file (after symlinks).

    Checked before opening: opening a named pipe with no writer blocks forever, a device
    such as /dev/zero never ends, a directory cannot be read. ``what`` names the file in the
    message (``the file``, ``the stroke file`` …).
    """
    check_confined(path, what)
    try:
        info = os.stat(path)
    except OSError as err:
        raise ConfigError(str(path), f"cannot read {what}: {err.strerror or err}") from None
    if not stat.S_ISREG(info.st_mode):
        raise ConfigError(
            str(path), f"cannot read {what}: it is {file_kind(info.st_mode)}, not a regular file"
        )
    return info.st_size


def _encode(text: str, file: str) -> bytes:
    try:
        return text.encode("utf-8")
    except UnicodeEncodeError as err:
        raise ConfigError(
            _byte_position(text[: err.start].encode("utf-8", "replace"), None, file),
            "the text holds a lone surrogate character, which UTF-8 cannot hold",
        ) from None


def _decode(data: bytes, file: str) -> str:
    return decode_utf8(data, file, "YAML")


def decode_utf8(data: bytes, file: str, kind: str) -> str:
    """Strict UTF-8 (a UTF-8 byte-order mark is allowed); otherwise say where and why.

    ``kind`` names what the text should be (``YAML``, ``a CSV stroke`` …) in the messages.
    """
    for bom, name in (
        (b"\xff\xfe", "UTF-16"),
        (b"\xfe\xff", "UTF-16"),
        (b"\x00\x00\xfe\xff", "UTF-32"),
    ):
        if data.startswith(bom):
            raise ConfigError(Position(file, 1, 1), f"the file is {name} text; save it as UTF-8")
    nul = data.find(b"\x00")
    if nul >= 0:
        raise ConfigError(
            _byte_position(data, nul, file),
            f"a NUL byte: this is a binary file (or UTF-16 text), not {kind} saved as UTF-8",
        )
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        raise ConfigError(
            _byte_position(data, err.start, file),
            f"not UTF-8 text: byte 0x{data[err.start]:02x} ({err.reason}); save the file as UTF-8",
        ) from None


def _byte_position(data: bytes, offset: int | None, file: str) -> Position:
    """Line and column (in characters) of byte ``offset`` of ``data`` (its end when None)."""
    offset = len(data) if offset is None else offset
    line_start = data.rfind(b"\n", 0, offset) + 1
    column = len(data[line_start:offset].decode("utf-8", "replace")) + 1
    return Position(file, data.count(b"\n", 0, offset) + 1, column)


# --- small validation helpers shared by profiles, layouts and scenes -------------------------


def require_mapping(value: Any, where: Position | str, what: str) -> MarkedDict:
    """``value`` must be a mapping; otherwise a ConfigError naming ``what``."""
    if not isinstance(value, MarkedDict):
        raise ConfigError(where, f"{what} must be a mapping, found {_describe(value)}")
    return value


def check_keys(
    mapping: MarkedDict,
    allowed: set[str] | frozenset[str],
    what: str,
    required: set[str] | frozenset[str] = frozenset(),
) -> None:
    """Reject unknown keys (naming the allowed ones) and missing required keys."""
    for key in mapping:
        if key not in allowed:
            raise ConfigError(
                mapping.where(key, of_key=True),
                f"unknown key `{key}` in {what}; allowed: {', '.join(sorted(allowed))}",
            )
    for key in sorted(required):
        if key not in mapping:
            raise ConfigError(mapping.where(), f"{what} is missing `{key}`")


def number(
    mapping: MarkedDict,
    key: str,
    what: str,
    *,
    default: float | None = None,
    minimum: float | None = None,
    maximum: float | None = None,
    exclusive_minimum: bool = False,
) -> float:
    """Read a finite number at ``key`` with optional bounds."""
    if key not in mapping:
        if default is None:
            raise ConfigError(mapping.where(), f"{what} is missing `{key}` (a number)")
        return default
    value = as_number(mapping[key])
    where = mapping.where(key)
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ConfigError(
            where,
            f"`{key}` in {what} must be a number, found {_describe(value)}{_number_hint(value)}",
        )
    value = float(value)
    if value != value or value in (float("inf"), float("-inf")):
        raise ConfigError(where, f"`{key}` in {what} must be finite, found {value}")
    if minimum is not None and (value < minimum or (exclusive_minimum and value == minimum)):
        op = ">" if exclusive_minimum else ">="
        raise ConfigError(where, f"`{key}` in {what} must be {op} {minimum:g}, found {value:g}")
    if maximum is not None and value > maximum:
        raise ConfigError(where, f"`{key}` in {what} must be <= {maximum:g}, found {value:g}")
    return value


def flag(mapping: MarkedDict, key: str, what: str, *, default: bool) -> bool:
    """Read ``true`` or ``false`` at ``key``."""
    if key not in mapping:
        return default
    value = as_flag(mapping[key])
    if not isinstance(value, bool):
        raise ConfigError(
            mapping.where(key), f"`{key}` in {what} must be true or false, found {_describe(value)}"
        )
    return value


def flag_or_auto(mapping: MarkedDict, key: str, what: str) -> bool | None:
    """Read ``true``, ``false`` or ``auto`` at ``key``; ``auto`` or no key is None (the
    program decides)."""
    if key not in mapping or mapping[key] == "auto":
        return None
    value = as_flag(mapping[key])
    if not isinstance(value, bool):
        raise ConfigError(
            mapping.where(key),
            f"`{key}` in {what} must be true, false or auto, found {_describe(value)}",
        )
    return value


def vector(value: Any, where: Position | str, what: str, length: int | None = None) -> list[float]:
    """A list of finite numbers (of ``length`` items when given)."""
    shape = f"{length} numbers" if length else "a list of numbers"
    if not isinstance(value, list):
        raise ConfigError(where, f"{what} must be {shape}, found {_describe(value)}")
    items = [as_number(v) for v in value]
    for i, v in enumerate(items):
        if isinstance(v, bool) or not isinstance(v, int | float):
            item_where = value.where(i) if isinstance(value, MarkedList) else where
            raise ConfigError(
                item_where,
                f"{what} must be {shape}; item {i + 1} is {_describe(v)}{_number_hint(v)}",
            )
    if length is not None and len(value) != length:
        raise ConfigError(where, f"{what} must have {length} numbers, found {len(value)}")
    out = [float(v) for v in items]
    if any(v != v or abs(v) == float("inf") for v in out):
        raise ConfigError(where, f"{what} must be finite numbers, found {value}")
    return out


def choice(
    mapping: MarkedDict, key: str, allowed: tuple[str, ...], what: str, default: str | None = None
) -> str:
    """A string from ``allowed``."""
    if key not in mapping:
        if default is None:
            raise ConfigError(
                mapping.where(), f"{what} is missing `{key}`; one of {', '.join(allowed)}"
            )
        return default
    value = mapping[key]
    if value not in allowed:
        raise ConfigError(
            mapping.where(key),
            f"`{key}` in {what} must be one of {', '.join(allowed)}, found {_describe(value)}",
        )
    return str(value)


def _number_hint(value: Any) -> str:
    """A hint when ``value`` is text that reads as a number (it was quoted)."""
    if not isinstance(value, str):
        return ""
    try:
        float(value.replace("_", ""))
    except ValueError:
        return ""
    return "; write the number without quotes"


def _describe(value: Any) -> str:
    if isinstance(value, dict):
        return "a mapping"
    if isinstance(value, list):
        return f"a list of {len(value)}"
    if value is None:
        return "nothing"
    return f"{type(value).__name__} {value!r}"
