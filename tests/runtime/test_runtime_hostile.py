"""Hostile input to a run: a source that fails part way ends the run as a normal end would
(nothing already sensed is lost, the summary says sensing failed), and a payload template
that would loop for hours is refused when the layout is checked."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import pytest

from hapticdesk.errors import ConfigError
from hapticdesk.files.recording_io import write_recording
from hapticdesk.plugin_loading import load_registry
from hapticdesk.plugins import templating
from hapticdesk.plugins.templating import SAMPLE_VARIABLES, TemplateError, compile_template
from hapticdesk.runtime.assembly import build_scene
from hapticdesk.runtime.run_report import report_json
from hapticdesk.runtime.service import Runtime

from .taps import Tap, tap_recording

LAYOUT = {
    "desk": "kitamura2017",
    "units": "cm",
    "regions": {"lamp": {"rect": [-5, -5, 5, 5]}},
    "bindings": [
        {"gesture": "tap", "region": "lamp", "do": {"log": {}}},
        {"gesture": "long_press", "region": "lamp", "hold_s": 0.5, "do": {"log": {}}},
    ],
}


def _run(tmp_path: Path, paper_desk, fail_at_end: bool):
    layout = tmp_path / "layout.yaml"
    layout.write_text(json.dumps(LAYOUT))
    recording = tmp_path / "taps.npz"
    # the last press is still held when the samples end: flushing ends the long press
    taps = [Tap(1.5, 0.0, 0.0), Tap(2.5, 0.0, 0.0, duration_s=2.0)]
    write_recording(recording, tap_recording(paper_desk, taps, 3.6))
    scene = build_scene(layout, f"replay:{recording}", load_registry(entry_points=False), speed=0)
    events_path = tmp_path / f"events-{fail_at_end}.jsonl"
    runtime = Runtime(scene, events_path=events_path)
    flushed: list[float] = []
    engine_flush = scene.engine.flush

    def flush(t: float):
        flushed.append(t)
        return engine_flush(t)

    scene.engine.flush = flush  # type: ignore[method-assign]
    if fail_at_end:
        blocks = scene.source.blocks

        def failing() -> Iterator:
            yield from blocks()
            raise ConfigError("taps.csv:9999:3", "column `fl_fz`: 'abc' is not a number")

        scene.source.blocks = failing  # type: ignore[method-assign]
    report = runtime.run(handle_signals=False)
    events = [json.loads(line) for line in events_path.read_text().splitlines()]
    return events, report, flushed


def test_a_source_that_fails_ends_the_run_as_a_normal_end(tmp_path, paper_desk):
    normal, normal_report, normal_flushed = _run(tmp_path, paper_desk, fail_at_end=False)
    failed, report, flushed = _run(tmp_path, paper_desk, fail_at_end=True)
    assert normal_report.error is None and normal_flushed
    # the same gestures (the held press's end comes from the flush), the same sensor time
    assert [e["gesture"] for e in normal].count("long_press") >= 2
    assert failed == normal
    assert flushed == normal_flushed
    assert report.samples == normal_report.samples
    assert report.sample_time_s == pytest.approx(normal_report.sample_time_s)
    assert report.sample_time_s > 3.5
    assert report.error == "taps.csv:9999:3: column `fl_fz`: 'abc' is not a number"
    lines = report.summary()
    assert lines[0].startswith(f"sensing failed: {report.samples} samples (3.60 s")
    assert lines[-1] == f"error: {report.error}"
    assert normal_report.summary()[0].startswith("the source ended:")
    info = json.loads(report_json(report))
    assert info["error"] == report.error and info["sample_time_s"] > 3.5


NESTED = "{%- for i in range(9999) -%}{%- for j in range(9999) -%}{%- endfor -%}{%- endfor -%}"
DOUBLING = (
    "{% macro f(n) %}{% if n %}{{ f(n - 1) }}{{ f(n - 1) }}{% endif %}{% endmacro %}{{ f(40) }}"
)


# each step small, but 16 kB made and kept at every one: 160 MB by the end (with the ranges
# and repetitions of an earlier version, 100,000 × 60 kB: 6 GB)
MAPPED = "{{ range(9999) | map('center', 16000) | list | length }}"
GROWING = (
    "{% set ns = namespace(x='') %}{% for i in range(9999) %}"
    "{% set ns.x = ns.x + 'a' * 16000 %}{% endfor %}{{ ns.x | length }}"
)


@pytest.mark.parametrize(
    "text",
    [NESTED, DOUBLING, MAPPED, GROWING],
    ids=["nested-loops", "doubling-macro", "mapped-text", "growing-text"],
)
def test_a_template_that_would_run_for_hours_is_too_costly(text, monkeypatch):
    monkeypatch.setattr(templating, "MAX_STEPS", 2_000)
    with pytest.raises(ConfigError) as info:
        compile_template(text, "layout.yaml:4:62", "`payload` of `mqtt`")
    said = str(info.value)
    assert said.startswith(
        "layout.yaml:4:62: `payload` of `mqtt` is too costly to render for an event: "
    )
    if text == GROWING:  # the text grows past what one rendering may make first
        assert said.endswith("joining with `+` would make 80000 characters; the limit is 65536")
    else:
        assert said.endswith("it takes more than 2000 loop turns and calls")


def test_a_template_too_slow_at_run_time_fails_for_that_event(monkeypatch):
    template = compile_template(
        "{% for i in range(3) %}{{ i }}{% endfor %}", "layout.yaml:1:1", "`payload`"
    )
    assert template.render_value(SAMPLE_VARIABLES) == 12  # "012" reads as a number
    monkeypatch.setattr(templating, "MAX_RENDER_S", -1.0)  # every step is past the deadline
    with pytest.raises(TemplateError, match="takes longer than -1 s"):
        template.render(SAMPLE_VARIABLES)


def test_each_rendering_has_a_budget_of_its_own(monkeypatch):
    monkeypatch.setattr(templating, "MAX_STEPS", 50)
    text = "{% for k in event %}{{ loop.index }}{% if loop.last %}/{{ loop.length }}{% endif %}"
    text += "{% else %}none{% endfor %}"
    template = compile_template(text, "layout.yaml:1:1", "`payload`")
    once = template.render(SAMPLE_VARIABLES)
    assert once.endswith(f"/{len(SAMPLE_VARIABLES['event'])}")
    for _ in range(
        5
    ):  # 15 turns each: a budget shared by the renderings would run out in the fourth
        assert template.render(SAMPLE_VARIABLES) == once


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        ("{{ event | tojson(indent=4 * 10**8) }}", "a `tojson` indent over 16"),
        ('{{ "%.999999999f" | format(1.5) }}', "a format asks for a field 999999999 "),
        ('{{ "%*d" | format(300000000, 1) }}', "the `format` filter asks for a field 3000"),
        ('{{ "%(a)900000000s" | format(a=1) }}', "a format asks for a field 900000000 "),
        ('{{ "%' + "9" * 5000 + 's" | format(1) }}', "a field more than 10**18 characters"),
    ],
    ids=["tojson-indent", "precision", "star-width", "keyed-width", "5000-digit-width"],
)
def test_a_filter_asked_for_gigabytes_is_refused_before_it_makes_them(text, needle):
    """The fuzzing pass: `hapticdesk check` on a 250-byte layout took 11.9 GB and 52 s
    (tojson's indent), 3.9 GB (a precision), about 1 GB (a `*` width, a keyed width): the
    filters' cost check saw plain widths only."""
    with pytest.raises(ConfigError, match="too costly to render") as info:
        compile_template(text, "layout.yaml:4:62", "`payload` of `mqtt`")
    assert needle in str(info.value)
    ordinary = compile_template('{{ event | tojson(indent=2) }}{{ "%5.2f" | format(x) }}',
                                "layout.yaml:1:1", "`payload`")  # fmt: skip
    assert ordinary.render(SAMPLE_VARIABLES)


@pytest.mark.parametrize("target", ["recording", "layout"])
def test_events_are_never_written_over_a_file_the_run_reads(tmp_path, paper_desk, capsys, target):
    """`run --source replay:rec.csv --events rec.csv` wrote the events over the recording as it
    was replayed (the run then failed at a line it had cut); `--events layout.yaml` replaced
    the layout. Both are refused before anything is read, and the files are as they were."""
    from hapticdesk.cli import main

    layout = tmp_path / "layout.yaml"
    layout.write_text(json.dumps(LAYOUT))
    recording = tmp_path / "taps.csv"
    write_recording(recording, tap_recording(paper_desk, [Tap(1.5, 0.0, 0.0)], 2.5))
    before = {p: p.read_bytes() for p in (layout, recording)}
    events = recording if target == "recording" else layout
    argv = ["run", "--layout", str(layout), "--source", f"replay:{recording}", "--speed", "0"]
    assert main([*argv, "--events", str(events)]) == 2
    what = "the file --source reads" if target == "recording" else "the layout"
    assert capsys.readouterr().err == (
        f"hapticdesk run: error: --events: cannot write {events}: it is {what}, which this "
        "command reads; give another file name\n"
    )
    assert {p: p.read_bytes() for p in before} == before


def test_contacts_are_never_written_over_their_recording(tmp_path, paper_desk, capsys):
    from hapticdesk.cli import main

    recording = tmp_path / "taps.csv"
    write_recording(recording, tap_recording(paper_desk, [Tap(1.5, 0.0, 0.0)], 2.5))
    before = recording.read_bytes()
    argv = ["contacts", str(recording), "--desk", "kitamura2017"]
    assert main([*argv, "-o", str(tmp_path / "." / "taps.csv")]) == 2
    assert "it is the recording, which this command reads" in capsys.readouterr().err
    assert recording.read_bytes() == before
