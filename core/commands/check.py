"""``hapticdesk check LAYOUT [--desk D | --desk FILE.c3d [--plate N]] [--png FILE]``: validate a
layout and explain it (a C3D file's force plate is the desk as ``run --source replay:`` makes it).

Actions, gestures and the sections plugins claim (``mqtt:``) are checked by the installed
plugins, exactly as ``run`` loads the layout (unknown names and bad options are errors with
file:line:column); so is every layout it names under ``layouts:``, as the running desk
loads one it switches to (the same desk, the same ``desk_name``). Prints the verdict and a
summary of regions, bindings, settings and templates; ``--png`` draws the layout on the
desk's outline (matplotlib, imported only then).
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from hapticdesk.commands.output_path import check_output_path
from hapticdesk.commands.recording_input import desk_or_plate, plate_number
from hapticdesk.errors import ConfigError
from hapticdesk.files.sensing import sensing_of
from hapticdesk.gestures.layout import Binding, Layout
from hapticdesk.gestures.options import GESTURE_OPTIONS, describe_value


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("layout", help="the layout YAML file")
    parser.add_argument(
        "--desk",
        help="a desk profile name or path (overrides the layout's), or a C3D file: its force "
        "plate is the desk, as in run --source replay:FILE.c3d",
    )
    parser.add_argument(
        "--plate",
        type=plate_number,
        metavar="N",
        help="with --desk FILE.c3d: its force plate, from 1 as C3D counts (default 1)",
    )
    parser.add_argument("--png", metavar="FILE", help="draw the layout on the desk into FILE")


def run(args: argparse.Namespace) -> int:
    from hapticdesk.plugin_loading import load_registry
    from hapticdesk.runtime.assembly import check_named_layouts, load_scene_layout

    if args.png:  # before the work: matplotlib would refuse the format only after it
        check_output_path(Path(args.png), "--png", (".png",), "the drawing")
    desk = desk_or_plate(args.desk, args.plate)  # (a C3D file's plate is read here, once)
    registry = load_registry()
    # the same loading as `run`: actions, recognizers and plugins' sections all checked
    layout, _ = load_scene_layout(args.layout, registry, desk)
    check_named_layouts(layout, registry, desk)  # (those a running desk switches to)
    # (a plugin's problem was logged once by the registry as it loaded; not repeated here)
    print(explain(layout))
    if args.png:
        try:
            draw_layout(layout, Path(args.png))
        except OSError as err:
            raise ConfigError("--png", f"cannot write {args.png}: {err.strerror or err}") from None
        print(f"drawn: {args.png}")
    return 0


def explain(layout: Layout) -> str:
    """The verdict and a summary a person can check their intent against."""
    desk = layout.desk
    scale, units = layout.metres_per_unit, layout.units
    surfaces = ", ".join(
        f"{s.name} {_span(s.polygon[:, 0], scale)} × {_span(s.polygon[:, 1], scale)} {units}"
        for s in desk.surfaces
    )
    sensors = len(desk.sensors)
    lines = [
        f"OK: {layout.path} is a valid layout",
        f"desk      {desk.name} ({sensors} sensor{'s' if sensors != 1 else ''}; {surfaces})",
        *(f"sensing   {line}" for line in sensing_of(desk).lines()),
        f"units     {units}",
        f"regions   {len(layout.regions)}",
    ]
    width = max((len(n) for n in layout.regions), default=0)
    for name, region in layout.regions.items():
        gestures = ", ".join(dict.fromkeys(b.gesture for b in layout.bindings if b.region == name))
        lines.append(
            f"  {name:<{width}}  {_region_text(region, layout)} on {region.surface}"
            f"  [{gestures or 'nothing bound'}]"
        )
    lines.append(f"bindings  {len(layout.bindings)}")
    for b in layout.bindings:
        actions = ", ".join(a.name for a in b.actions)
        lines.append(f"  {b.index + 1:>2}. {_binding_text(b, layout)} → {actions}")
    from hapticdesk.gestures.arbitration import describe  # (numpy: loaded with the layout)

    lines += describe(layout)
    tuned = _tuned(layout)
    if tuned:
        lines.append("settings (differing from the built-in defaults)")
        lines += [f"  {line}" for line in tuned]
    if "stroke" in layout.gestures:
        from hapticdesk.gestures.layout import builtin_shape_names

        user = ", ".join(f"{k} ({len(v)})" for k, v in layout.templates.items()) or "none"
        lines.append(f"templates built-in: {len(builtin_shape_names())} shapes; yours: {user}")
    lines += [f"warning: {w}" for w in layout.warnings]
    return "\n".join(lines)


def _span(values: Any, scale: float) -> str:
    return f"{(max(values) - min(values)) / scale:g}"


def _region_text(region: Any, layout: Layout) -> str:
    scale, units = layout.metres_per_unit, layout.units
    if region.kind == "circle":
        cx, cy = region.center / scale
        text = f"circle at ({cx:g}, {cy:g}) r {region.radius / scale:g}"
    else:
        x0, y0, x1, y1 = (v / scale for v in region.bounds)
        kind = "rect" if region.kind == "rect" else f"polygon ({len(region.outline)} points)"
        text = f"{kind} x {x0:g}..{x1:g}, y {y0:g}..{y1:g}"
    if region.axis is not None:
        (ax, ay), (bx, by) = region.axis / scale
        text += f", slider 0→1 from ({ax:g}, {ay:g}) to ({bx:g}, {by:g})"
    return f"{text} {units}"


def _binding_text(b: Binding, layout: Layout) -> str:
    where = f"in {b.region}" if b.region else "anywhere"
    specs = GESTURE_OPTIONS.get(b.gesture, {})
    filters = [
        f"{k} {describe_value(spec, b.options[k], layout.units, layout.metres_per_unit)}"
        for k, spec in specs.items()
        if spec.role == "match" and b.options.get(k) not in (None, spec.default)
    ]
    if b.gesture == "long_press":
        hold = b.options["hold_s"]
        filters = [f"on release after {hold:g} s" if b.options["release"] else f"at {hold:g} s"]
        if b.options["repeat"]:
            filters.append(f"then every {b.options['interval_s']:g} s while held")
    return " ".join([b.gesture, where] + ([f"({'; '.join(filters)})"] if filters else []))


def _tuned(layout: Layout) -> list[str]:
    out = []
    for (gesture, region), options in layout.region_options.items():
        specs = GESTURE_OPTIONS.get(gesture)
        if not specs:
            continue
        changed = [
            f"{k} {describe_value(specs[k], v, layout.units, layout.metres_per_unit)}"
            for k, v in options.items()
            if k in specs and specs[k].role == "recognize" and v != specs[k].default
        ]
        if changed:
            where = f"in {region}" if region else "anywhere"
            out.append(f"{gesture} {where}: {', '.join(changed)}")
    return out


def draw_layout(layout: Layout, path: Path) -> None:
    """A PNG of the desk's outline(s), the sensors and the regions with what they bind."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle, Polygon

    desk = layout.desk
    fig, ax = plt.subplots(figsize=(8, 6))
    for surface in desk.surfaces:
        if surface.is_desk_xy:
            ax.add_patch(Polygon(surface.polygon, closed=True, fill=False, lw=1.5, ec="0.3"))
            x0, y0 = surface.polygon.min(axis=0)
            ax.annotate(surface.name, (x0, y0), xytext=(3, 3), textcoords="offset points",
                        color="0.4", fontsize=8)  # fmt: skip
    legs = [s.position for s in desk.sensors]
    ax.plot([p[0] for p in legs], [p[1] for p in legs], "s", color="0.5", ms=6, label="sensors")
    colours = plt.get_cmap("tab10")
    for i, (name, region) in enumerate(layout.regions.items()):
        colour = colours(i % 10)
        if region.kind == "circle":
            patch: Any = Circle(tuple(region.center), region.radius, alpha=0.35, color=colour)
        else:
            patch = Polygon(region.outline, closed=True, alpha=0.35, color=colour)
        ax.add_patch(patch)
        gestures = ", ".join(dict.fromkeys(b.gesture for b in layout.bindings if b.region == name))
        cx, cy = region.outline.mean(axis=0)
        label = f"{name}\n{gestures}" + (
            "" if region.surface_index == 0 else f"\n({region.surface})"
        )
        ax.text(cx, cy, label, ha="center", va="center", fontsize=8)
        if region.axis is not None:
            (ax0, ay0), (ax1, ay1) = region.axis
            ax.annotate(
                "", (ax1, ay1), (ax0, ay0), arrowprops={"arrowstyle": "->", "color": colour}
            )
    anywhere = sorted({b.gesture for b in layout.bindings if b.region is None})
    title = f"{layout.path.name} on {desk.name}"
    if anywhere:
        title += f"; anywhere: {', '.join(anywhere)}"
    ax.set_title(title, fontsize=10)
    ax.set_xlabel("x (m), to the right")
    ax.set_ylabel("y (m), away from you")
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.margins(0.05)
    ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
