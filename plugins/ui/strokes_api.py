"""Scoring a stroke drawn in the page (with the mouse, or on the desk) against every shape."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from hapticdesk.errors import ConfigError

#: the most points a stroke from the page may have (a 15 s stroke at 50 Hz is 750)
MAX_POINTS = 5000


def score(payload: dict[str, Any], layout_path: Path, layout_text: str, server: Any) -> dict:
    """``{"shape", "score", "best_shape", "scores"}`` for ``payload["points"]`` (metres),
    against the built-in shapes and the layout's own templates, with the layout's stroke
    settings (``min_score``, ``max_rotation_deg``)."""
    import numpy as np

    from hapticdesk.gestures.strokes.unistroke import template_set
    from hapticdesk.runtime.assembly import load_scene_layout

    points = payload.get("points")
    if not isinstance(points, list) or not 2 <= len(points) <= MAX_POINTS:
        raise ConfigError(None, f"a stroke is 2 to {MAX_POINTS} points [x, y] in metres")
    try:
        pts = np.asarray(points, dtype=float).reshape(-1, 2)
    except (TypeError, ValueError):
        raise ConfigError(None, "a stroke is a list of [x, y] points in metres") from None
    if not np.isfinite(pts).all():
        raise ConfigError(None, "a stroke's points must be finite numbers")
    layout, _ = load_scene_layout(layout_path, server.registry, server.desk, text=layout_text)
    options = layout.options_for("stroke", None)
    templates = template_set(layout.templates)
    match = templates.classify(
        pts, float(options.get("min_score", 0.85)), float(options.get("max_rotation_deg", 30.0))
    )
    ranked = sorted(match.scores.items(), key=lambda kv: -kv[1])
    return {
        "ok": True,
        "shape": match.shape,
        "score": round(match.score, 4),
        "best_shape": match.best_shape,
        "min_score": float(options.get("min_score", 0.85)),
        "scores": [{"shape": k, "score": round(v, 4)} for k, v in ranked],
        "user_shapes": sorted(layout.templates),
    }
