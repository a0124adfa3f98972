"""Action templates: the event's fields as variables, numbers kept numbers, errors positioned."""

from __future__ import annotations

import pytest

from hapticdesk.errors import ConfigError
from hapticdesk.files.yamlfile import load_marked_yaml
from hapticdesk.gestures.event import GestureEvent
from hapticdesk.plugins.templating import (
    VARIABLES,
    TemplateError,
    compile_template,
    compile_value,
    event_variables,
)

SLIDE = GestureEvent(3.25, "slide", "dimmer", 0.1, -0.05, value=0.5, phase="update")


def render(value, event=SLIDE):
    return compile_value(value, "layout.yaml:1:1", "payload").render(
        event_variables(event, "study")
    )


def test_payload_leaves_that_render_numbers_become_numbers():
    payload = {
        "brightness": "{{ (value * 254) | round | int }}",
        "fraction": "{{ value }}",
        "state": "ON",
        "note": "{{ region }} {{ gesture }}",
        "steps": ["{{ value * 10 }}", 3, True, None],
    }
    assert render(payload) == {
        "brightness": 127,
        "fraction": 0.5,
        "state": "ON",
        "note": "dimmer slide",
        "steps": [5.0, 3, True, None],
    }


def test_a_literal_string_that_looks_like_a_number_stays_a_string():
    assert render({"code": "0042"}) == {"code": "0042"}


def test_every_event_field_and_the_extras_are_available():
    stroke = GestureEvent(
        1.0, "stroke", None, 0.0, 0.0, shape="circle", score=0.93, extra={"hand": "left"}
    )
    text = "{{ action }}|{{ desk }}|{{ shape }}|{{ score }}|{{ event.hand }}|{{ region }}"
    assert render(text, stroke) == "desk_stroke_circle|study|circle|0.93|left|None"
    assert set(event_variables(stroke, "d")) == set(VARIABLES)


def test_unknown_variables_and_syntax_errors_name_the_place():
    doc = load_marked_yaml("layout.yaml", 'payload:\n  level: "{{ valeu * 100 }}"\n')
    with pytest.raises(ConfigError) as err:
        compile_value(doc["payload"], doc.where("payload"), "`payload`")
    assert str(err.value).startswith("layout.yaml:2:10: ")
    assert "valeu" in str(err.value) and "value" in str(err.value)
    with pytest.raises(ConfigError, match="layout.yaml:9:3: .*not a valid template"):
        compile_template("{{ value ", "layout.yaml:9:3")


def test_the_sandbox_refuses_reaching_into_python():
    template = compile_template("{{ gesture.__class__.__mro__ }}", "x")
    with pytest.raises(TemplateError):
        template.render(event_variables(SLIDE, "d"))


def test_nan_and_infinity_never_reach_a_payload():
    template = compile_value({"v": "{{ value / 0.0 if false else 'nan' }}"}, "x", "payload")
    with pytest.raises(TemplateError, match="NaN"):
        template.render(event_variables(SLIDE, "d"))
    with pytest.raises(ConfigError, match="NaN"):
        compile_value({"v": float("inf")}, "x", "payload")


def test_a_template_failing_on_an_event_says_which_template():
    template = compile_template("{{ value * 2 }}", "layout.yaml:5:7")
    tap = GestureEvent(1.0, "tap", "lamp", 0.0, 0.0)  # a tap has no value
    with pytest.raises(TemplateError, match="layout.yaml:5:7"):
        template.render(event_variables(tap, "d"))


@pytest.mark.parametrize(
    ("template", "said"),
    [
        # DESIGN.md's example: rounds 254 and sends 24.93 for a slide at 0.098
        ("{{ value * 254 | round }}", "applies `round` to the number 254 alone"),
        ("{{ value * 100 | round | int }}", "applies `round | int` to the number 100 alone"),
        ("{{ (value * 254) | round | int }}", None),
        ("{{ value | round(2) * 100 }}", None),
        ("{{ 2 * 3 | int }}", None),  # numbers alone: nothing was meant otherwise
    ],
)
def test_a_filter_on_a_lone_number_after_arithmetic_is_a_layout_warning(
    tmp_path, capsys, template, said
):
    from hapticdesk.cli import main

    layout = tmp_path / "l.yaml"
    layout.write_text(
        "desk: kitamura2017\nregions: {d: {rect: [-0.3, 0.1, 0.3, 0.2], axis: x}}\nbindings:\n"
        "  - {gesture: slide, region: d, do: {log: {message: '" + template + "'}}}\n"
    )
    assert main(["check", str(layout)]) == 0
    warned = [line for line in capsys.readouterr().out.splitlines() if "warning" in line]
    if said is None:
        assert warned == []
    else:
        assert len(warned) == 1 and warned[0].startswith(f"warning: {layout}:4:")
        assert said in warned[0] and "write `(… " in warned[0]
