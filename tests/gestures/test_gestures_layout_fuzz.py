"""Fuzzing the layout loader (issue 11, item 21): whatever bytes a layout file holds, loading
it ends in a layout or a ConfigError that names the file and a place in it — never another
exception, never a traceback, in bounded time.

Three generators: raw bytes (encodings, control characters, binary), YAML-ish text built from
the tokens that break parsers (brackets, anchors, aliases, tags, huge numbers), and
mutations of a valid layout (so the validator, not only the parser, is reached)."""

from __future__ import annotations

import re
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hapticdesk.errors import ConfigError
from hapticdesk.gestures.layout_reader import load_layout
from hapticdesk.plugin_loading import load_registry

VALID = """\
desk: kitamura2017
units: cm
regions:
  lamp: {rect: [-20, -10, -5, 5]}
  dimmer: {rect: [5, -10, 25, 5], axis: x}
  pad: {polygon: [[-10, 10], [10, 10], [0, 25]]}
settings:
  tap: {max_duration_s: 0.3}
bindings:
  - {gesture: tap, region: lamp, do: {log: {message: "tap {region}"}}}
  - {gesture: slide, region: dimmer, do: log}
  - gesture: stroke
    region: pad
    do: [log, {log: {message: "{shape}"}}]
"""

TOKENS = [
    "desk:", " kitamura2017", "\n", "  ", "- ", "[", "]", "{", "}", ",", ":", "&a ", "*a",
    "!!set ", "!!binary ", "!!python/object ", "<<: ", "? ", "9" * 40, "1e999", "-.inf",
    ".nan", "'", '"', "\\x00", "\t", "#", "regions:", "bindings:", "gesture: tap",
    "region: ", "do: log", "rect: [0, 0, 1, 1]", "polygon: ", "circle: ", "units: mm", "é",
    "\u2028", "\x07", "---", "...", "%YAML 1.1",
]  # fmt: skip

REGISTRY = load_registry(entry_points=False)
PLACE = re.compile(r"layout\.yaml(:\d+:\d+)?: ")


def _load(tmp_path: Path, content: bytes) -> None:
    path = tmp_path / "layout.yaml"
    path.write_bytes(content)
    try:
        load_layout(
            path,
            action_names=REGISTRY.action_names,
            validate_action=REGISTRY.validate_action,
            recognizer_types=REGISTRY.recognizer_types(),
            validate_section=REGISTRY.validate_section,
            section_names=REGISTRY.layout_sections,
        )
    except ConfigError as err:
        message = str(err)
        assert PLACE.search(message), message  # where
        assert len(message) < 2000  # what, said briefly (not a dump of the input)


FUZZ = settings(
    max_examples=150, deadline=2000, suppress_health_check=[HealthCheck.function_scoped_fixture]
)


@FUZZ
@given(st.binary(max_size=400))
def test_any_bytes_end_in_a_layout_or_a_placed_error(tmp_path, content):
    _load(tmp_path, content)


@FUZZ
@given(st.lists(st.sampled_from(TOKENS), max_size=60))
def test_yaml_like_text_ends_in_a_layout_or_a_placed_error(tmp_path, tokens):
    _load(tmp_path, "".join(tokens).encode("utf-8", "surrogatepass"))


@FUZZ
@given(
    st.integers(0, len(VALID) - 1),
    st.integers(0, 12),
    st.sampled_from(TOKENS + ["", "x", "0", "-1", "1e308", "null", "[]", "{}"]),
)
def test_a_mutated_valid_layout_ends_in_a_layout_or_a_placed_error(tmp_path, at, cut, insert):
    content = VALID[:at] + insert + VALID[at + cut :]
    _load(tmp_path, content.encode())


def test_the_valid_layout_loads(tmp_path):
    """The mutations start from a layout that loads (so they test the validator too)."""
    path = tmp_path / "layout.yaml"
    path.write_text(VALID)
    layout = load_layout(
        path, action_names=REGISTRY.action_names, validate_action=REGISTRY.validate_action
    )
    assert set(layout.regions) == {"lamp", "dimmer", "pad"}
    assert layout.gestures == ["tap", "slide", "stroke"]
