"""Meta-test: every hookspec is documented, and every one is exercised by a real run."""

from __future__ import annotations

import inspect
from types import ModuleType, SimpleNamespace

import pytest

from hapticdesk import hookspecs
from hapticdesk.estimator.contacts import ContactEvent
from hapticdesk.gestures.event import GestureEvent
from hapticdesk.gestures.recognizer import Recognizer
from hapticdesk.gestures.touch import Touch
from hapticdesk.hookspecs import hookimpl, hookspec_names
from hapticdesk.plugin_loading import load_registry
from hapticdesk.plugins.replay import RecordingSource
from hapticdesk.runtime.assembly import build_scene
from hapticdesk.runtime.run_report import RunReport
from hapticdesk.runtime.service import Runtime

from .taps import Tap, tap_recording

LAYOUT = """\
desk: kitamura2017
spy_section: {loud: true}
bindings:
  - gesture: knock
    do: {spy: {}}
"""


@pytest.mark.parametrize("name", hookspec_names())
def test_every_hookspec_is_documented(name):
    spec = getattr(hookspecs, name)
    doc = inspect.getdoc(spec) or ""
    assert "Called" in doc, f"{name}: say when it is called"
    for argument in inspect.signature(spec).parameters:
        assert f"``{argument}``" in doc, f"{name}: document the argument `{argument}`"


@pytest.mark.parametrize("name", hookspec_names())
def test_every_hookspec_argument_is_typed(name):
    """The hooks' types are the plugin contract: none is left `Any`."""
    spec = getattr(hookspecs, name)
    for argument, parameter in inspect.signature(spec).parameters.items():
        assert parameter.annotation not in (inspect.Parameter.empty, "Any"), (name, argument)


class Knock(Recognizer):
    """A plugin gesture: every touch is a knock, placed where it was released."""

    gestures = ("knock",)

    def on_contact(self, event: ContactEvent, touch: Touch) -> list[GestureEvent]:
        if event.kind == "up":
            return [GestureEvent(event.t, "knock", None, event.x, event.y)]
        return []


def test_every_hookspec_is_exercised_by_a_run(tmp_path, paper_desk):
    called: dict[str, dict] = {}
    knocks: list[GestureEvent] = []
    everything: list[GestureEvent] = []
    summaries: list = []
    sections: list = []
    recording = tap_recording(paper_desk, [Tap(1.5, 0.1, 0.0), Tap(2.5, -0.1, 0.05)], 3.2)

    def register_sources(register):
        called["register_sources"] = {}
        register("spy", lambda argument, profile, **o: RecordingSource(recording, 1200.0))

    def register_actions(register):
        called["register_actions"] = {}
        register("spy", lambda options, context: knocks.append, "collect events")

    def register_recognizers(register):
        called["register_recognizers"] = {}
        register("knock", Knock, "a touch-down")

    def register_layout_sections(register):
        called["register_layout_sections"] = {}
        register("spy_section", lambda value, position, path: sections.append((value, path)))

    def register_commands(register):
        called["register_commands"] = {}
        command = ModuleType("spy_command")  # a module with configure(parser) and run(args)
        command.configure, command.run = print, lambda args: 0  # type: ignore[attr-defined]
        register("spy", command, "a command")

    def event_sink(desk, layout, context):
        called["event_sink"] = {"desk_name": context.desk_name}
        return everything.append

    def control_channel(control):  # fewer arguments than the spec: allowed
        called["control_channel"] = {"control": control}

    def contact_sink(desk, layout, context):
        called["contact_sink"] = {"desk": desk}
        return summaries.append

    def startup(desk, layout):
        called["startup"] = {"desk": desk, "layout": layout}

    def shutdown(report):  # fewer arguments than the spec: allowed
        called["shutdown"] = {"report": report}

    spy = SimpleNamespace(
        **{
            fn.__name__: hookimpl(fn)
            for fn in (
                register_sources,
                register_actions,
                register_recognizers,
                register_layout_sections,
                register_commands,
                event_sink,
                control_channel,
                contact_sink,
                startup,
                shutdown,
            )
        }
    )
    registry = load_registry(entry_points=False, plugins=[("spy", spy)])
    layout_path = tmp_path / "knock.yaml"
    layout_path.write_text(LAYOUT)
    scene = build_scene(layout_path, "spy:", registry, speed=0)
    report = Runtime(scene).run(handle_signals=False)

    assert sorted(called) == hookspec_names()
    assert called["control_channel"]["control"] is scene.control
    assert called["startup"]["desk"].name == paper_desk.name
    assert called["startup"]["layout"].path == layout_path
    assert isinstance(called["shutdown"]["report"], RunReport)
    assert [round(e.x, 2) for e in knocks] == [0.1, -0.1]
    assert report.gestures == {"knock": 2}
    assert everything == knocks  # the event sink saw every event
    assert called["event_sink"]["desk_name"] == paper_desk.name
    # the contact sink saw every block: times rising, forces finite, the knocks' force
    times = [s.t for s in summaries]
    assert len(times) > 10 and times == sorted(times)
    assert max(s.force_n for s in summaries) > 1.0
    assert sections == [({"loud": True}, layout_path)]
    assert registry.commands["spy"].load().run(None) == 0
