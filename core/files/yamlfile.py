"""YAML loading that remembers where every key and value stood, for errors users can act on.

Profiles, layouts and scenes are written by hand. When one is wrong the user must be told the
file, line and column and what was expected (STYLE.md 9), never shown a traceback. This module
loads YAML, bounded in size, depth and expanded aliases, into the marked dicts and lists of
:mod:`.marked_values`, which carry the position of each key and item; the checks of what they
hold are :mod:`.validators`, the errors :mod:`hapticdesk.errors`.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import yaml
from yaml.composer import Composer
from yaml.constructor import SafeConstructor
from yaml.parser import Parser
from yaml.reader import Reader
from yaml.resolver import Resolver
from yaml.scanner import Scanner

from hapticdesk.errors import ConfigError, Position
from hapticdesk.files.file_safety import byte_position, decode_utf8, regular_file_size
from hapticdesk.files.marked_values import FlagText, MarkedDict, MarkedList, NumberText

# YAML 1.1 reads these bare words as booleans; as keys they are almost always a mistake.
_YAML11_BOOL_WORDS = {"on", "off", "yes", "no", "y", "n", "true", "false"}


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
_MERGE_TAG = "tag:yaml.org,2002:merge"


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
# kept as the text written, marked (NumberText): the validators' `number` and `vector` read
# it as the number it is, while a payload or an argv that means text keeps `1e3` as written
# (a resolver for the whole file turned an exec's `1e3` argument into "1000.0").
_EXPONENT_FLOAT = re.compile(r"[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+")
# YAML 1.1's octal ints (`010` is 8); YAML 1.2 writes octal `0o10` and reads `010` as 10
_YAML11_OCTAL = re.compile(r"[-+]?0[0-7_]+")


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


def _construct_mapping(node: yaml.MappingNode, file: str, loader: _Loader) -> MarkedDict:
    """A mapping, its keys text, none written twice in it. A merge (``<<: *base``, or a
    list of them) gives the keys the mapping does not write itself, as YAML's merge key
    says: a key written overrides a merged one (``{<<: *base, rect: …}`` was refused, "key
    `rect` appears twice"), and of a list of merged mappings the earlier wins."""
    out = _merged(node, file, loader)  # (first: merged keys keep their place, as before)
    own: set[str] = set()  # the keys written in this mapping itself
    for key_node, value_node in node.value:
        if key_node.tag == _MERGE_TAG:
            continue
        if key_node.tag == "tag:yaml.org,2002:value":  # (`=` as a key: text, as PyYAML has it)
            key_node.tag = "tag:yaml.org,2002:str"
        key = _construct(key_node, file, loader)
        if not isinstance(key, str):
            raw = key_node.value if isinstance(key_node, yaml.ScalarNode) else key
            hint = ""
            if isinstance(raw, str) and raw.lower() in _YAML11_BOOL_WORDS:
                hint = f"; YAML reads a bare `{raw}` as a boolean, write it in quotes"
            raise ConfigError(_pos(file, key_node), f"keys must be text, found {raw!r}{hint}")
        if key in own:
            raise ConfigError(_pos(file, key_node), f"key `{key}` appears twice")
        own.add(key)
        out[key] = _construct(value_node, file, loader)
        out.key_positions[key] = _pos(file, key_node)
        out.value_positions[key] = _pos(file, value_node)
    return out


def _merged(node: yaml.MappingNode, file: str, loader: _Loader) -> MarkedDict:
    """The keys ``node``'s merges (``<<``) give it, each merged mapping read as a mapping of
    its own (its own merges resolved), the earlier of a list winning; empty without one."""
    out = MarkedDict()
    out.position = _pos(file, node)
    out.key_positions = {}
    out.value_positions = {}
    for key_node, value_node in node.value:
        if key_node.tag != _MERGE_TAG:
            continue
        many = isinstance(value_node, yaml.SequenceNode)
        for source in value_node.value if many else [value_node]:
            if not isinstance(source, yaml.MappingNode):
                raise ConfigError(
                    _pos(file, source),
                    "not valid YAML: a merge (`<<`) takes a mapping or a list of mappings",
                )
            merged = _construct(source, file, loader)
            for key, value in merged.items():
                if key not in out:
                    out[key] = value
                    out.key_positions[key] = merged.key_positions[key]
                    out.value_positions[key] = merged.value_positions[key]
    return out


def _construct(node: yaml.Node, file: str, loader: _Loader) -> Any:
    if isinstance(node, yaml.MappingNode):
        if node.tag in _UNSUPPORTED_TAGS:
            raise _unsupported(node, file)
        return _construct_mapping(node, file, loader)
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
            byte_position(data, offset, file),
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


def _encode(text: str, file: str) -> bytes:
    try:
        return text.encode("utf-8")
    except UnicodeEncodeError as err:
        raise ConfigError(
            byte_position(text[: err.start].encode("utf-8", "replace"), None, file),
            "the text holds a lone surrogate character, which UTF-8 cannot hold",
        ) from None


def _decode(data: bytes, file: str) -> str:
    return decode_utf8(data, file, "YAML")
