"""One gesture per touch: which of the gestures that see a touch may fire on it.

Every recognizer sees every touch, so one touch can look like several gestures: a quick
straight stroke is also a swipe, a still touch whose noise carried its points 5 cm is a tap
and a swipe, a tap held long enough is a long press. Touch toolkits arbitrate between the
recognizers of one touch (UIKit's ``require(toFail:)``, Android's ``GestureDetector``): the
less specific gesture waits for the more specific one to fail. Here:

- :data:`ORDER` lists the gestures that fire once on a touch, the most specific first;
- a gesture *claims* its touch with the first event a binding reacts to (:func:`claims`);
  an event nothing reacts to (a stroke matching no bound shape, a rejected one) claims
  nothing, so a stroke excludes a swipe only where the stroke is bound;
- the first claim holds the touch: no other gesture of :data:`ORDER` fires on it after, and
  what the others decided at the same sample is dropped (a long press that fired excludes
  the tap at the release; a swipe excludes the tap; a stroke excludes the swipe);
- gestures decided at the same sample (the release) are asked most specific first
  (:class:`~hapticdesk.gestures.engine.GestureEngine` calls its recognizers in this order);
- a tap where a double tap is bound waits ``interval_s`` for the second one (the double
  tap's first tap waits; :mod:`~hapticdesk.gestures.recognizers.taps`), and a two-finger
  tap is decided before both.

``slide``, ``force`` and ``press`` report the touch as it goes (a value, a force level) and
are not arbitrated, nor are plugin gestures: they fire beside the gesture that holds the
touch. ``hapticdesk check`` prints the order for a layout (:func:`describe`).
"""

from __future__ import annotations

from hapticdesk.gestures.event import GestureEvent
from hapticdesk.gestures.layout import Binding, Layout
from hapticdesk.gestures.regions import regions_overlap

#: gestures that fire once on a touch, the most specific first
ORDER = ("stroke", "swipe", "long_press", "two_finger_tap", "double_tap", "tap")


def rank(gesture: str) -> int | None:
    """Place of ``gesture`` in :data:`ORDER` (0 the most specific), None when unarbitrated."""
    return ORDER.index(gesture) if gesture in ORDER else None


def claims(binding: Binding, event: GestureEvent) -> bool:
    """Whether ``event`` claims its touch for ``binding``: the binding fires on it or, for a
    long press bound to fire on its release, the event is the tier the release waits for
    (the touch is a long press from then on)."""
    if binding.matches(event):
        return True
    if binding.gesture != "long_press" or event.gesture != "long_press" or event.phase:
        return False
    if binding.region is not None and binding.region != event.region:
        return False
    return (
        bool(binding.options.get("release"))
        and abs((event.hold_s or 0.0) - binding.options["hold_s"]) < 1e-9
    )


def describe(layout: Layout) -> list[str]:
    """Lines for ``check``: the layout's arbitrated gestures in order, where each is bound,
    what it waits for among those that can see the same touch, and the gestures left
    beside."""
    bound = [g for g in ORDER if g in layout.gestures]
    if not bound:
        return []
    lines = [
        "one gesture per touch (a gesture that fired holds the touch; at the release the "
        "most specific is asked first)"
    ]
    for k, gesture in enumerate(bound):
        mine = [b for b in layout.bindings if b.gesture == gesture]
        where = ", ".join(dict.fromkeys(b.region or "anywhere" for b in mine))
        meets = [g for g in bound if g != gesture and _meet(layout, mine, g)]
        if gesture == "long_press":
            says = "fires while held, before the release: a touch it fired on is its alone"
        else:
            above = [g for g in bound[:k] if g in meets and g != "long_press"]
            says = f"waits for {', '.join(above)} to fail" if above else "asked first"
            if gesture == "tap" and "double_tap" in meets:
                says += "; where a double tap is bound, for its interval too"
            if "long_press" in meets:
                says += "; not after a long press fired"
        lines.append(f"  {k + 1}. {gesture} ({where}): {says}")
    beside = [g for g in layout.gestures if g not in ORDER]
    if beside:
        lines.append(f"  beside, not arbitrated: {', '.join(beside)}")
    return lines


def _meet(layout: Layout, mine: list[Binding], gesture: str) -> bool:
    """Whether a touch can be seen by one of the bindings ``mine`` and one of ``gesture``'s:
    either is bound anywhere, or their regions overlap."""
    theirs = [b for b in layout.bindings if b.gesture == gesture]
    for a in mine:
        for b in theirs:
            if a.region is None or b.region is None or a.region == b.region:
                return True
            ra, rb = layout.regions[a.region], layout.regions[b.region]
            if ra.surface_index == rb.surface_index and regions_overlap(ra, rb):
                return True
    return False
