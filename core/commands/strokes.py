"""``hapticdesk strokes``: classify stroke files, or record stroke templates from a source.

    hapticdesk strokes classify PATH... [--templates DIR] [--no-builtin] [--json]
    hapticdesk strokes record NAME --layout L --source SPEC [--desk D] [--into DIR] [--count N]

``classify`` prints, per stroke, the file, the recognised shape (null when nothing matches
well enough) and the score; with ``--json`` one JSON object a line (docs/reference/files.md).
A file that cannot be read is reported and the others are still classified; the exit status
is then 2, as for any input a command was given wrong (docs/reference/cli.md).

``record`` runs a source (``sim:SCENE.yaml``, ``replay:REC.csv``, a live CAN bus …) through
the estimator and saves every touch big enough to be a stroke as ``DIR/NAME/NAME-<n>.csv``,
each as soon as it ends, so Ctrl-C loses nothing already drawn. DIR defaults to the layout's
template folder (its ``templates:`` when that names a folder, else ``strokes/`` beside it).
Exit status 1 when no stroke was saved, or when sensing stopped part way on an error (a
replayed recording's bad line: the strokes before it are kept), as ``run`` and ``record``.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from hapticdesk.errors import ConfigError
from hapticdesk.files.strokefile import (
    SHAPE_NAME,
    STROKE_SUFFIXES,
    read_stroke,
    read_template_dir,
    write_stroke,
)
from hapticdesk.gestures.options import GESTURE_OPTIONS

if TYPE_CHECKING:  # (imported when the command runs: `--help` stays light)
    from hapticdesk.estimator import ContactEstimator
    from hapticdesk.gestures.strokes.capture import CapturedStroke, StrokeCapture
    from hapticdesk.runtime.source import Source

_STROKE = GESTURE_OPTIONS["stroke"]


def configure(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="strokes_command", metavar="SUBCOMMAND", required=True)
    c = sub.add_parser("classify", help="recognise the shape of stroke files")
    c.add_argument("paths", nargs="+", metavar="PATH", help="stroke files or folders of them")
    c.add_argument("--templates", metavar="DIR", help="user templates: one sub-folder per shape")
    c.add_argument(
        "--no-builtin", action="store_true", help="match only the --templates, not the built-ins"
    )
    c.add_argument(
        "--min-score",
        type=float,
        default=_STROKE["min_score"].default,
        help="similarity needed to accept a shape (default %(default)s)",
    )
    c.add_argument(
        "--max-rotation",
        type=float,
        default=_STROKE["max_rotation_deg"].default,
        metavar="DEG",
        help="how far a stroke may be turned from a template (default %(default)s)",
    )
    c.add_argument("--json", action="store_true", help="one JSON object per stroke")
    r = sub.add_parser("record", help="capture stroke templates from a source")
    r.add_argument("name", help="the shape name the strokes are templates of")
    r.add_argument("--layout", required=True, help="the layout whose templates these are")
    r.add_argument("--source", required=True, metavar="SPEC", help="sim:SCENE, replay:FILE, …")
    r.add_argument("--desk", help="a desk profile name or path (overrides the layout's)")
    r.add_argument("--into", metavar="DIR", help="template folder (default: the layout's)")
    r.add_argument("--count", type=int, default=0, help="stop after N strokes (default: all)")
    r.add_argument(
        "--speed", type=float, default=0.0, help="replay speed: 1 real time, 0 (default) at once"
    )


def run(args: argparse.Namespace) -> int:
    if args.strokes_command == "classify":
        return classify(args)
    return record(args)


# --- classify --------------------------------------------------------------------------------


def _stroke_paths(paths: list[str]) -> tuple[list[Path], list[Path]]:
    """The stroke files named or in the folders named, and the folders that hold none."""
    out: list[Path] = []
    empty: list[Path] = []
    for text in paths:
        path = Path(text)
        if path.is_dir():
            found = sorted(
                p for p in path.rglob("*") if p.is_file() and p.suffix.lower() in STROKE_SUFFIXES
            )
            out += found
            if not found:
                empty.append(path)
        else:
            out.append(path)  # a missing file is reported when it is read
    return out, empty


def classify(args: argparse.Namespace) -> int:
    from hapticdesk.gestures.strokes.unistroke import template_set

    if not 0.0 <= args.min_score <= 1.0:
        raise ConfigError("--min-score", f"must be between 0 and 1, found {args.min_score:g}")
    if not 0.0 <= args.max_rotation <= 180.0:
        raise ConfigError("--max-rotation", f"must be 0..180 degrees, found {args.max_rotation:g}")
    user = read_template_dir(args.templates) if args.templates else None
    if args.no_builtin and not user:
        raise ConfigError("--no-builtin", "needs --templates DIR holding at least one shape")
    templates = template_set(user, builtin=not args.no_builtin)
    paths, empty = _stroke_paths(args.paths)
    for folder in empty:
        print(
            f"hapticdesk strokes: error: {folder}: no stroke files "
            f"({', '.join(STROKE_SUFFIXES)}) in this folder or below",
            file=sys.stderr,
        )
    failed = len(empty)
    rows: list[dict[str, Any]] = []
    for path in paths:
        try:
            points = read_stroke(path)
        except ConfigError as err:
            print(f"hapticdesk strokes: error: {err}", file=sys.stderr)
            failed += 1
            continue
        match = templates.classify(points, args.min_score, args.max_rotation)
        row: dict[str, Any] = {
            "file": str(path),
            "shape": match.shape,
            "score": round(match.score, 4),
        }
        if match.shape is None and match.best_shape is not None:
            row["nearest"] = match.best_shape
        rows.append(row)
        if args.json:
            print(json.dumps(row, ensure_ascii=False), flush=True)
    if not args.json and rows:
        width = max(len(r["file"]) for r in rows)
        for r in rows:
            shape = r["shape"] or f"-- (nearest {r.get('nearest')})"
            print(f"{r['file']:<{width}}  {r['score']:.3f}  {shape}")
    _hint_unknown_folders(args.paths, rows, set(templates.shapes))
    # a file given that could not be read is an input error (2, as every command's), even
    # with the others classified: `grep` exits 2 on an unreadable file beside its matches
    return 2 if failed else 0


def _hint_unknown_folders(given: list[str], rows: list[dict[str, Any]], known: set[str]) -> None:
    """A folder named like a shape no template has (examples/strokes/zed without
    ``--templates``): its strokes can only be rejected; say why, not only that."""
    for text in given:
        folder = Path(text)
        if not folder.is_dir() or not SHAPE_NAME.match(folder.name) or folder.name in known:
            continue
        inside = [r for r in rows if Path(r["file"]).is_relative_to(folder)]
        if inside and all(r["shape"] is None for r in inside):
            print(
                f"hapticdesk strokes: `{folder.name}` is not a shape the templates know "
                f"(they know {len(known)}); give your own with --templates DIR, the "
                f"folder holding {folder.name}/, e.g. --templates {folder.parent}",
                file=sys.stderr,
            )


# --- record ----------------------------------------------------------------------------------


def _next_index(folder: Path, name: str) -> int:
    pattern = re.compile(rf"^{re.escape(name)}-(\d+)\.(csv|json)$")
    found = [int(m.group(1)) for p in folder.iterdir() if (m := pattern.match(p.name))]
    return max(found, default=0) + 1


def record(args: argparse.Namespace) -> int:
    from hapticdesk.estimator import ContactEstimator
    from hapticdesk.files.profile_reader import load_profile
    from hapticdesk.gestures.strokes.capture import StrokeCapture
    from hapticdesk.gestures.strokes.unistroke import template_set
    from hapticdesk.plugin_loading import load_registry
    from hapticdesk.runtime.assembly import load_scene_layout
    from hapticdesk.runtime.source_spec import open_source

    if not SHAPE_NAME.match(args.name):
        raise ConfigError(
            "NAME",
            f"a shape name is letters, digits and _, starting with a letter; found {args.name!r}",
        )
    if args.count < 0:
        raise ConfigError("--count", f"must be 0 (all) or more, found {args.count}")
    registry = load_registry()
    profile = load_profile(args.desk) if args.desk else None
    # as `check` and `run` load it: a layout with an `mqtt:` section or a plugin's actions
    # records strokes too (it was refused for its `mqtt:` key)
    layout, _ = load_scene_layout(args.layout, registry, profile)
    into = Path(args.into) if args.into else layout.template_dir
    folder = into / args.name
    options = layout.options_for("stroke", None)
    capture = StrokeCapture(layout.desk, min_size=options["min_size"])
    templates = template_set(layout.templates, builtin=layout.builtin_templates)
    estimator = ContactEstimator(layout.desk)
    saved: list[Path] = []
    stopped_by: ConfigError | None = None
    source = open_source(args.source, layout.desk, registry, speed=args.speed)
    try:
        _make_folder(folder)
        stopped_by = _capture_strokes(
            source,
            capture,
            estimator,
            args.count,
            lambda stroke: saved.append(_save(stroke, folder, args.name, templates, options)),
        )
    except KeyboardInterrupt:
        print("stopped; the strokes drawn so far are saved", file=sys.stderr)
    finally:
        source.close()
    if stopped_by is not None:
        print(
            f"hapticdesk strokes: error: sensing stopped part way: {stopped_by}; the strokes "
            "drawn before it are saved",
            file=sys.stderr,
        )
    print(
        f"recorded {len(saved)} stroke(s) of `{args.name}` into {folder}"
        + (f" ({capture.small} smaller touches skipped)" if capture.small else ""),
        file=sys.stderr,
    )
    if saved and not _layout_uses(layout, into, args.name):
        print(
            f"to use them, add to {layout.path}:  {_hint(layout, into, args.name)}", file=sys.stderr
        )
    return 0 if saved and stopped_by is None else 1


def _make_folder(folder: Path) -> None:
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise ConfigError(str(folder), f"cannot create it: {err.strerror or err}") from None


def _hint(layout: Any, into: Path, name: str) -> str:
    """What to add to the layout so that it loads the templates recorded into ``into``."""
    if "templates" not in layout.raw:
        return f"templates: {_relative(into, layout.path.parent)}"
    return f"{name}: [{_relative(into / name, layout.path.parent)}] under `templates:`"


def _capture_strokes(
    source: Source,
    capture: StrokeCapture,
    estimator: ContactEstimator,
    count: int,
    keep: Callable[[CapturedStroke], None],
) -> ConfigError | None:
    """Every stroke drawn on ``source`` handed to ``keep``, until ``count`` (0: the source's
    end, when a stroke still open is closed). The source's error after it gave samples (a
    replayed recording's bad line) is returned, not raised: sensing stopped part way, as a
    run's does, and the strokes before it are kept; one before any sample is the input's."""
    kept = 0
    t_last = None
    try:
        for block in source.blocks():
            if len(block.t) == 0:
                continue
            t_last = float(block.t[-1])
            for stroke in capture.feed(estimator.push(block.t, block.wrench, block.accel)):
                keep(stroke)
                kept += 1
            if count and kept >= count:
                return None
    except ConfigError as err:
        if t_last is None:
            raise
        return err  # (a stroke still open when it stopped is cut short: not saved)
    if t_last is not None:
        for stroke in capture.flush(t_last):
            keep(stroke)
    return None


def _save(stroke: Any, folder: Path, name: str, templates: Any, options: dict[str, Any]) -> Path:
    path = folder / f"{name}-{_next_index(folder, name):03d}.csv"
    write_stroke(path, stroke.points, stroke.t - stroke.t[0])
    match = templates.classify(stroke.points, options["min_score"], options["max_rotation_deg"])
    row = {
        "file": str(path),
        "size_cm": round(stroke.size * 100, 1),
        "duration_s": round(float(stroke.t[-1] - stroke.t[0]), 3),
        "looks_like": match.shape,
        "score": round(match.score, 4),
    }
    print(json.dumps(row, ensure_ascii=False), flush=True)
    return path


def _layout_uses(layout: Any, into: Path, name: str) -> bool:
    """Whether the layout already loads the templates recorded into ``into``/``name``."""
    value = layout.raw.get("templates")
    if isinstance(value, str):
        return (layout.path.parent / value).resolve() == into.resolve()
    return isinstance(value, dict) and name in value


def _relative(path: Path, base: Path) -> str:
    return os.path.relpath(path.resolve(), base.resolve())
