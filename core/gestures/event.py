"""Gesture events: what recognizers emit and actions receive (docs: File formats)."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any


@dataclass(frozen=True)
class GestureEvent:
    """One recognised gesture on sample time.

    ``gesture`` is the recognizer's name (tap, double_tap, long_press, press, force, swipe,
    slide, stroke, …); ``region`` the layout region it happened in (None for anywhere).
    Optional fields carry what the gesture has: ``shape``/``score`` (stroke), ``direction``
    (swipe), ``value`` (slide, force, 0..1), ``level`` (press), ``phase`` (begin, update, end
    for continuous gestures; cancel when a touch broke off without a release: a gap, a stop,
    the end of a recording; repeat for a long press held on). ``extra`` holds anything a
    plugin recognizer adds.
    """

    t: float
    gesture: str
    region: str | None
    x: float
    y: float
    shape: str | None = None
    score: float | None = None
    direction: str | None = None
    value: float | None = None
    level: str | None = None
    phase: str | None = None
    hold_s: float | None = None  # long_press tier reached
    force_n: float | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dict with the documented keys; absent optional fields are left out."""
        out: dict[str, Any] = {
            "t": round(self.t, 6),
            "gesture": self.gesture,
            "region": self.region,
            "x": round(self.x, 6),
            "y": round(self.y, 6),
        }
        for key in ("shape", "score", "direction", "value", "level", "phase", "hold_s", "force_n"):
            value = getattr(self, key)
            if value is not None:
                out[key] = round(value, 6) if isinstance(value, float) else value
        out.update(self.extra)
        return out

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), ensure_ascii=False)

    @property
    def action_name(self) -> str:
        """Zigbee2MQTT-style action string: ``<region>_<gesture>[_<detail>]``."""
        parts = [self.region or "desk", self.gesture]
        detail = self.shape or self.direction or self.level or None
        if detail:
            parts.append(detail)
        if (
            self.phase
            and self.phase != "update"
            and self.gesture in ("slide", "force", "long_press")
        ):
            parts.append(self.phase)
        return "_".join(parts)
