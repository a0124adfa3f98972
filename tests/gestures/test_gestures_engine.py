"""The engine: block-split invariance, building only what the layout binds, plugin recognizers."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import numpy as np
import pytest

from hapticdesk.gestures.engine import GestureEngine
from hapticdesk.gestures.event import GestureEvent
from hapticdesk.gestures.recognizer import Recognizer
from hapticdesk.gestures.strokes.shapes import hand_drawn
from hapticdesk.plugins.recognizers import RECOGNIZERS

EVERYTHING = """
units: cm
regions:
  lamp: {rect: [-30, -20, -20, -10]}
  fan: {rect: [20, -20, 30, -10]}
  knob: {circle: {center: [0, -15], radius: 4}}
  dimmer: {rect: [-30, 10, 30, 20], axis: x}
bindings:
  - {gesture: tap, region: lamp, do: log}
  - {gesture: double_tap, region: lamp, do: log}
  - {gesture: tap, region: fan, do: log}
  - {gesture: two_finger_tap, region: fan, do: log}
  - {gesture: long_press, region: fan, do: log}
  - {gesture: long_press, region: fan, hold_s: 1.5, do: log}
  - {gesture: press, region: knob, do: log}
  - {gesture: force, region: knob, do: log}
  - {gesture: slide, region: dimmer, do: log}
  - {gesture: swipe, do: log}
  - {gesture: stroke, shape: [circle, v], do: log}
"""


def busy_timeline(timeline):
    rng = np.random.default_rng(7)
    tl = timeline(20.0, seed=11)
    tl.touch(1.0, 0.1, (-0.25, -0.15)).touch(1.3, 0.1, (-0.25, -0.15))  # double on lamp
    tl.touch(2.0, 0.1, (-0.25, -0.15))  # single on lamp (waits)
    tl.touch(2.6, 0.1, (0.25, -0.15))  # tap on fan
    tl.touch(3.2, 2.0, (0.25, -0.15))  # long press on fan, two tiers
    tl.touch(6.0, 1.5, (0.0, -0.15), force_profile=lambda tau: 2 + 20 * np.sin(tau / 1.5 * np.pi))
    tl.touch(8.0, 1.5, np.array([[-0.2, 0.15], [0.2, 0.15]]))  # slide
    tl.touch(10.0, 0.3, np.array([[0.0, 0.0], [0.0, 0.12]]))  # swipe up
    tl.touch(11.0, 3.0, hand_drawn("circle", rng, 0.1, 0.01) + [0.1, 0.0])
    tl.touch(15.0, 3.0, hand_drawn("v", rng, 0.1, 0.01) + [-0.1, 0.0])
    tl.touch(19.9, 0.1, (-0.25, -0.15))  # a tap cut off by the end of the stream
    return tl


def test_every_gesture_kind_appears_in_the_busy_stream(make_layout, timeline):
    layout = make_layout(EVERYTHING)
    engine = GestureEngine(layout)
    block = busy_timeline(timeline).block()
    events = engine.feed(block) + engine.flush(float(block.t[-1]))
    kinds = {e.gesture for e in events}
    assert kinds == {
        "tap",
        "double_tap",
        "long_press",
        "press",
        "force",
        "slide",
        "swipe",
        "stroke",
    }
    # the swipe is also a straight stroke, but no binding wants a line and the swipe holds
    # the touch (one gesture per touch); the slide, which starts on the dimmer, is neither a
    # swipe nor a stroke; a finger that stays put is never a stroke, however long it stays
    strokes = [e.shape for e in events if e.gesture == "stroke"]
    assert strokes == ["circle", "v"]
    assert [e.direction for e in events if e.gesture == "swipe"] == ["up"]
    assert [e.t for e in events] == sorted(e.t for e in events)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_output_does_not_depend_on_how_the_stream_is_split(make_layout, timeline, seed):
    layout = make_layout(EVERYTHING)
    block = busy_timeline(timeline).block()
    whole = GestureEngine(layout)
    expected = whole.feed(block) + whole.flush(float(block.t[-1]))
    rng = np.random.default_rng(seed)
    cuts = np.sort(rng.choice(np.arange(1, len(block)), size=300, replace=False))
    if seed == 2:  # also single samples and empty blocks
        cuts = np.sort(np.concatenate([cuts, np.arange(1200, 1300), [5000, 5000]]))
    split = GestureEngine(layout)
    got: list[GestureEvent] = []
    for lo, hi in zip(
        np.concatenate([[0], cuts]), np.concatenate([cuts, [len(block)]]), strict=True
    ):
        got += split.feed(block.take(slice(lo, hi)))
    got += split.flush(float(block.t[-1]))
    assert got == expected
    assert len(expected) > 20


def test_builds_only_the_recognizers_the_layout_binds(make_layout):
    layout = make_layout(EVERYTHING.split("  - {gesture: double_tap")[0])  # taps only
    engine = GestureEngine(layout)
    assert set(engine.recognizers) == {"tap"}
    everything = GestureEngine(make_layout(EVERYTHING))
    assert set(everything.recognizers) == set(RECOGNIZERS)
    assert everything.recognizers["tap"] is everything.recognizers["double_tap"]


def test_a_taps_only_layout_never_imports_the_stroke_recognizer(tmp_path):
    layout = tmp_path / "taps.yaml"
    layout.write_text(
        "desk: kitamura2017\nregions: {b: {rect: [0, 0, 0.05, 0.05]}}\n"
        "bindings: [{gesture: tap, region: b, do: log}]\n"
    )
    code = textwrap.dedent(
        f"""
        import sys
        import numpy as np
        from hapticdesk.estimator.contacts import ContactBlock
        from hapticdesk.gestures.engine import GestureEngine
        from hapticdesk.gestures.layout_reader import load_layout
        engine = GestureEngine(load_layout({str(layout)!r}))
        engine.feed(ContactBlock.empty())
        print(sorted(engine.recognizers))
        print(sorted(m for m in sys.modules if m.startswith("hapticdesk.gestures.")))
        """
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    recognizers, modules = out.stdout.strip().splitlines()
    assert recognizers == "['tap']"
    for absent in ("stroke", "unistroke", "shapes", "swipe", "slide", "pressure", "long_press"):
        assert f"hapticdesk.gestures.{absent}'" not in modules
    assert "hapticdesk.gestures.recognizers.taps'" in modules


class KnockRecognizer(Recognizer):
    """A plugin gesture: a touch harder than ``min_n`` anywhere, decided at the release."""

    gestures = ("knock",)

    def on_contact(self, event, touch):
        limit = self.bindings[0].options.get("min_n", 15.0)
        if event.kind == "up" and touch.peak_force_n >= limit:
            x, y, _ = touch.best()
            return [GestureEvent(event.t, "knock", None, x, y, force_n=touch.peak_force_n)]
        return []


def test_plugin_recognizer_gets_contact_events(make_layout, timeline):
    text = "bindings:\n  - {gesture: knock, min_n: 12, do: log}\n"
    with pytest.raises(Exception, match="gesture"):
        make_layout(text)  # unknown without the plugin
    layout = make_layout(text, recognizer_types={"knock": KnockRecognizer})
    engine = GestureEngine(layout, recognizer_types={"knock": KnockRecognizer})
    block = timeline(4.0).touch(1.0, 0.2, (0, 0), force_n=20).touch(2.0, 0.2, (0, 0)).block()
    events = engine.feed(block)
    assert [(e.gesture, round(e.force_n)) for e in events] == [("knock", 20)]
    assert layout.bindings[0].matches(events[0])


def test_touches_on_a_tilted_surface_use_its_own_coordinates(write_layout, tmp_path, timeline):
    from hapticdesk.gestures.layout_reader import load_layout

    desk = tmp_path / "panel.yaml"
    desk.write_text(
        textwrap.dedent(
            """
            name: panel-desk
            sample_rate_hz: 1200
            sensors:
              - {name: a, position: [-0.3, -0.2, 0]}
              - {name: b, position: [0.3, -0.2, 0]}
              - {name: c, position: [0, 0.2, 0]}
            surfaces:
              - {name: top, origin: [0, 0, 0.7], normal: [0, 0, 1],
                 polygon: [[-0.4, -0.3], [0.4, -0.3], [0.4, 0.3], [-0.4, 0.3]]}
              - {name: front, origin: [0, -0.3, 0.5], normal: [0, -1, 0], u_axis: [1, 0, 0],
                 polygon: [[-0.4, -0.2], [0.4, -0.2], [0.4, 0.2], [-0.4, 0.2]]}
            """
        )
    )
    layout = load_layout(
        write_layout(
            """
            desk: panel.yaml
            regions:
              front_button: {rect: [0.1, 0.0, 0.2, 0.1], surface: front}
            bindings:
              - {gesture: tap, region: front_button, do: log}
            """
        )
    )
    # the front panel's (u, v) = (x, z - 0.5) in desk coordinates: a touch at desk
    # (0.15, -0.3, 0.55) is (0.15, 0.05) on it
    tl = timeline(2.0).touch(1.0, 0.1, (0.15, -0.3))
    block = tl.block()
    block.surface[block.located] = 1
    block.z[block.located] = 0.55
    events = GestureEngine(layout).feed(block)
    assert [(e.gesture, e.region) for e in events] == [("tap", "front_button")]
    assert (events[0].x, events[0].y) == pytest.approx((0.15, 0.05), abs=0.002)
