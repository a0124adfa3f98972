"""The gesture engine: contact blocks in, gesture events out, on sample time.

It builds only the recognizers the layout binds (a taps-only layout never imports the stroke
recognizer). Which class recognizes a gesture comes from the plugin registry, built-ins (a
plugin in :data:`~hapticdesk.registry.DEFAULT_PLUGINS`) and third-party ones alike, as lazy
``"module:Class"`` references imported on first use (python-can's ``BACKENDS`` habit,
STYLE.md 4, 15).
Output does not depend on how the contact stream is cut into blocks: state is carried
across blocks and timers fire at the first sample time at or after their deadline.
One touch fires one gesture: the recognizers are asked the most specific first and the
first gesture a binding reacts to holds the touch (:mod:`~hapticdesk.gestures.arbitration`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from hapticdesk.estimator.contacts import FLAG_GAP, ContactBlock, ContactEvent
from hapticdesk.gestures.arbitration import ORDER, claims, rank
from hapticdesk.gestures.event import GestureEvent
from hapticdesk.gestures.layout import Layout
from hapticdesk.gestures.recognizer import Recognizer
from hapticdesk.gestures.touch import Touch
from hapticdesk.gestures.touch_tracker import TouchTracker


def _default_recognizers() -> Mapping[str, Any]:
    """The built-in recognizers, from the registry like any plugin's (no entry points)."""
    from hapticdesk.plugin_loading import load_registry

    return load_registry(entry_points=False).recognizer_types()


def _load(entry: Any) -> type:
    """A recognizer class from a registry record, a ``"module:Class"`` string or a class."""
    from hapticdesk.lazy_ref import resolve

    load = getattr(entry, "load", None)
    cls: type = load() if callable(load) else resolve(entry)
    return cls


class GestureEngine:
    """Runs the layout's recognizers over contact blocks.

    ``recognizer_types`` maps gesture names to recognizers: registry records
    (:meth:`Registry.recognizer_types`), classes or ``"module:Class"`` strings; only the
    bound ones are imported. A gesture it lacks comes from the built-ins of the registry
    (without entry points).
    ``recognizers`` maps each bound gesture name to its recognizer (gestures served by one
    class share the instance). ``position_delay_s``: how far the contacts' positions run
    behind the finger, :attr:`ContactEstimator.position_delay_s` for the estimator's output
    (recognizers read it as ``touch.delay_s``).
    """

    def __init__(
        self,
        layout: Layout,
        recognizer_types: Mapping[str, Any] | None = None,
        position_delay_s: float = 0.0,
    ) -> None:
        self.layout = layout
        known = dict(recognizer_types or {})
        if any(g not in known for g in layout.gestures):
            known = {**_default_recognizers(), **known}
        classes: dict[str, type] = {}
        for gesture in layout.gestures:
            if gesture not in known:
                raise ValueError(f"no recognizer for gesture {gesture!r}; is its plugin installed?")
            classes[gesture] = _load(known[gesture])
        instances: dict[type, Recognizer] = {}
        self.recognizers: dict[str, Recognizer] = {}
        for gesture, cls in classes.items():
            if cls not in instances:
                served = {g for g, c in classes.items() if c is cls}
                instances[cls] = cls(layout, [b for b in layout.bindings if b.gesture in served])
            self.recognizers[gesture] = instances[cls]
        # the most specific first (arbitration.ORDER): a gesture decided at the same sample
        # as a more specific one is asked after it, and sees whether it claimed the touch
        self._active = sorted(instances.values(), key=self._specificity)
        self._tracker = TouchTracker(layout.desk, position_delay_s)
        #: a bound gesture reads a second finger: the estimator must run its second-finger
        #: stage (:meth:`ContactEstimator.use_second_finger`)
        self.needs_second_finger = any(
            gesture in getattr(cls, "needs_second_finger", ()) for gesture, cls in classes.items()
        )

    @property
    def idle(self) -> bool:
        """No touch is open and no recognizer waits for a deadline (a tap for its double):
        another engine can take over now without a touch seen twice or a decision lost
        (a layout reload swaps engines only then)."""
        tracker = self._tracker
        return (
            tracker.touch is None
            and not tracker.in_contact
            and all(r.next_deadline() is None for r in self._active)
        )

    def join_contact(self) -> None:
        """Start in the middle of a contact that began before this engine (a reloaded layout
        taking over while a finger is held): that touch is not recognised, the next one is.
        Nothing is fired for a touch whose start was not seen."""
        self._tracker.join_contact()

    @staticmethod
    def _specificity(recognizer: Recognizer) -> int:
        ranks = [r for g in type(recognizer).gestures if (r := rank(g)) is not None]
        return min(ranks, default=len(ORDER))

    def feed(self, block: ContactBlock) -> list[GestureEvent]:
        """Recognise gestures in the next block (any length, including 0).

        A sample flagged FLAG_GAP (time jumped, the estimator restarted its filters) while a
        touch is open cancels that touch: nobody saw it end, so no release is made up.
        """
        if len(block) == 0:
            return []
        gaps = np.flatnonzero(block.flags & FLAG_GAP)
        if len(gaps) == 0:
            return self._run(self._tracker.events(block), block.t)
        out: list[GestureEvent] = []
        start = 0
        for k in gaps.tolist():
            if k > start:
                part = block.take(slice(start, k))
                out += self._run(self._tracker.events(part), part.t)
            out += self.cancel(float(block.t[k]))
            start = k
        part = block.take(slice(start, len(block)))
        return out + self._run(self._tracker.events(part), part.t)

    def cancel(self, t: float) -> list[GestureEvent]:
        """The contact stream broke off at sample time ``t`` (a gap, a stop, the end of a
        recording): the open touch, if any, is cancelled, never released. Continuous
        gestures end with phase ``cancel``; a tap is not fired. Timers are left running."""
        touch = self._tracker.abort()
        if touch is None:
            return []
        out: list[GestureEvent] = []
        for recognizer in self._active:
            out += recognizer.cancel(t, touch)
        return out

    def flush(self, t_end: float) -> list[GestureEvent]:
        """The source ended at sample time ``t_end``: cancel an open touch (its release was
        not seen) and decide what is pending (a tap released before, waiting for its
        double)."""
        out = self.cancel(t_end)
        for recognizer in self._active:
            out += recognizer.flush(t_end)
        return out

    def _run(self, events: list[ContactEvent], times: np.ndarray) -> list[GestureEvent]:
        """Contact events and timers in sample-time order; a timer due at or before a contact
        event's sample fires first."""
        out: list[GestureEvent] = []
        i = 0
        while True:
            due = [(d, r) for r in self._active if (d := r.next_deadline()) is not None]
            if due:
                k = int(np.searchsorted(times, min(d for d, _ in due), side="left"))
                if k < len(times) and (i >= len(events) or times[k] <= events[i].t):
                    t = float(times[k])
                    for deadline, recognizer in due:
                        if deadline <= t:
                            out += recognizer.on_deadline(t)
                            again = recognizer.next_deadline()
                            if again is not None and again <= t:
                                raise RuntimeError(
                                    f"{type(recognizer).__name__} did not clear its deadline"
                                )
                    continue
            if i >= len(events):
                return out
            out += self._on_contact(events[i])
            i += 1

    def _on_contact(self, event: ContactEvent) -> list[GestureEvent]:
        touch = self._tracker.add(event)
        if touch is None:
            return []
        earlier: list[GestureEvent] = []
        out: list[GestureEvent] = []
        for recognizer in self._active:
            mine = recognizer.on_contact(event, touch)
            if touch.claimed_by is None:
                self._claim(touch, mine)
            out += mine
            earlier += recognizer.decided_earlier()
        if touch.claimed_by is not None:  # one gesture per touch: the others' are dropped
            out = [e for e in out if e.gesture not in ORDER or e.gesture == touch.claimed_by]
        return earlier + out

    def _claim(self, touch: Touch, events: list[GestureEvent]) -> None:
        """The first arbitrated event of ``events`` a binding reacts to claims ``touch``."""
        for e in events:
            if e.gesture in ORDER and any(claims(b, e) for b in self.layout.bindings):
                touch.claimed_by = e.gesture
                return
