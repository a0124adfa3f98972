"""``hapticdesk init [FILE] [--desk D | --desk FILE.c3d [--plate N]] [--units U] [--blank]
[--force]``: start a layout.

Writes a layout for a chosen desk that ``check``, ``run`` and the browser's designer take as
it is: commented, with one button in the middle of the desk's top bound to a tap that logs,
and the other region shapes and a slider as comments to copy; or, with ``--blank``, no
regions and no bindings yet (``check`` then warns that nothing will happen). An existing
file is never overwritten without ``--force``. For a C3D file's force plate the layout names
no desk (the replay brings it: ``run --source replay:FILE.c3d``) and its button, a foot's
size, is pressed, a foot's gesture, where the recording's steps come down
(:func:`stepped_on`), so that replaying it fires the press. ``hapticdesk ui --layout
NEW.yaml`` starts a missing layout the same way.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path
from typing import Any

from hapticdesk.commands.recording_input import desk_or_plate, plate_number
from hapticdesk.errors import ConfigError
from hapticdesk.files.c3d import is_c3d
from hapticdesk.files.profile import DeskProfile

DEFAULT_FILE = "layout.yaml"
DEFAULT_DESK = "kitamura2017"
#: the example button's side, metres (a fingertip's width and some)
BUTTON_M = 0.05
#: on a force plate: a foot's length, metres (the centre of pressure runs heel to toe)
FOOT_M = 0.25
#: on a force plate the starter press's one level, newtons: a foot bearing weight (a
#: finger's 4, 10 and 20 N levels would all fire at a heel strike's first sample)
STEP_N = 100.0
#: how far inside the top's bounding box a button moved to the steps is kept, metres
EDGE_M = 0.005


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "file", nargs="?", default=DEFAULT_FILE, help="the layout to write (%(default)s)"
    )
    parser.add_argument(
        "--desk",
        default=DEFAULT_DESK,
        help="a desk profile name or path (default %(default)s, the paper's desk), or a C3D "
        "file: its force plate is the desk, as in run --source replay:FILE.c3d",
    )
    parser.add_argument(
        "--plate",
        type=plate_number,
        metavar="N",
        help="with --desk FILE.c3d: its force plate, from 1 as C3D counts (default 1)",
    )
    parser.add_argument(
        "--units", choices=("m", "cm", "mm"), default="cm", help="lengths in (default cm)"
    )
    parser.add_argument(
        "--blank", action="store_true", help="no regions and no bindings yet (draw them in `ui`)"
    )
    parser.add_argument("--force", action="store_true", help="overwrite FILE if it exists")


def run(args: argparse.Namespace) -> int:
    path = Path(args.file)
    if path.exists() and not args.force:
        raise ConfigError(str(path), "already exists; give another name, or --force to replace it")
    desk = write_starter(path, args.desk, units=args.units, blank=args.blank, plate=args.plate)
    gesture = _button_gesture(args.desk)
    regions = "no regions yet" if args.blank else f"a button bound to a {gesture} that logs"
    print(f"wrote {path}: a layout for desk {desk} with {regions}")
    print("next:")
    print(f"  hapticdesk check {path}{_plate_arguments(args.desk, args.plate)}")
    if is_c3d(args.desk):
        print(
            f"  hapticdesk run --layout {path} --source replay:{args.desk} --plate "
            f"{args.plate or 1} --speed 0     # the recording's steps on the button"
        )
    print(f"  hapticdesk ui --layout {path}     # draw regions and bind gestures in the browser")
    return 0


def desk_reference(desk: str, layout: Path) -> str:
    """How the layout names ``desk``: a shipped profile by its name, a file by its path
    relative to the layout's folder (as a layout's paths are read) when it is in or below that
    folder, else absolute."""
    given = Path(desk).expanduser()
    if given.suffix.lower() not in (".yaml", ".yml") and not given.exists():
        return desk
    relative = os.path.relpath(given.resolve(), layout.resolve().parent)
    return given.resolve().as_posix() if relative.startswith("..") else Path(relative).as_posix()


def _plate_arguments(desk: str, plate: int | None) -> str:
    """`` --desk FILE.c3d --plate N`` for a C3D desk (a layout cannot name it), else ``""``."""
    return f" --desk {desk} --plate {plate or 1}" if is_c3d(desk) else ""


def _desk_line(desk: str, file_name: str, plate: int | None) -> str:
    """The layout's ``desk:``; for a C3D file's plate, which a layout cannot name, how a
    replay brings it."""
    if not is_c3d(desk):
        return f"desk: {desk}"
    return (
        f"# desk: the force plate {plate or 1} of {desk}, which a replay brings:\n"
        f"#   hapticdesk run --layout {file_name} --source replay:{desk} --plate {plate or 1}"
    )


def _axes_line(desk: str, centre: tuple[float, float] | None) -> str:
    """The comment that says which way x and y run, and on a plate where the button is."""
    if not is_c3d(desk):
        return "# x to your right, y away from you, seen from where you sit."
    where = (
        "the button is where the recording's steps come down"
        if centre is not None
        else f"no step of the recording reaches {STEP_N:g} N: the button is in the middle"
    )
    return f"# x, y from the plate's centre, the lab's axes as its corners turn them; {where}."


def _button_gesture(desk: str) -> str:
    """The example button's gesture: a tap; on a C3D file's force plate a press, a foot's."""
    return "press" if is_c3d(desk) else "tap"


def _example_binding(gesture: str) -> list[str]:
    """The button's binding: ``gesture`` (:func:`_button_gesture`) that logs; a foot's press
    at one level, STEP_N."""
    done = {"tap": "tapped", "press": "pressed"}[gesture]
    levels = [f"    levels: {{step: {STEP_N:g}}}   # newtons: a foot bearing weight"]
    return [
        f"  - gesture: {gesture}",
        "    region: button",
        *(levels if gesture == "press" else []),
        f'    do: {{log: {{message: "{{{{ region }}}} {done} at {{{{ t }}}} s"}}}}',
    ]


def stepped_on(desk: str, profile: DeskProfile) -> tuple[float, float] | None:
    """Where the feet of the C3D file ``desk`` come down on its plate whose desk is
    ``profile``, as the starter's press sees them: each step's centre of pressure (paper
    eq. 5 on the top z = 0: x = −M_y / F_z, y = M_x / F_z) at its first sample whose force
    reaches STEP_N, where the press places itself (a heel's, not the median of the roll to
    the toes); the median over steps. None where no step reaches STEP_N."""
    import numpy as np

    from hapticdesk.files.forceplate import read_plate_recording

    recording = read_plate_recording(desk, profile)
    wrench = recording.channels @ profile.wrench_map().T  # [F_o; M_o] (paper eqs. 1–4)
    force = np.linalg.norm(wrench[:, :3], axis=1)
    bearing = force >= STEP_N
    # a step's first sample at STEP_N: a bearing sample after one that was not
    starts = np.flatnonzero(bearing & ~np.concatenate(([False], bearing[:-1])))
    starts = starts[np.abs(wrench[starts, 2]) > 0]
    if not starts.size:
        return None
    x = -wrench[starts, 4] / wrench[starts, 2]
    y = wrench[starts, 3] / wrench[starts, 2]
    return float(np.median(x)), float(np.median(y))


def _button_square(
    polygon: Any, foot: bool, centre: tuple[float, float] | None
) -> tuple[float, float, float]:
    """The example button's centre and half side: BUTTON_M at most a fifth of the top
    (``polygon``'s bounding box), or for a ``foot`` FOOT_M at most half of it; at ``centre``
    (the top's middle when None), kept EDGE_M inside the box (a plate's measured corners
    are seldom square to the mm)."""
    (x0, y0), (x1, y1) = polygon.min(axis=0), polygon.max(axis=0)
    side, share = (FOOT_M, 2) if foot else (BUTTON_M, 5)
    half = min(side, (x1 - x0) / share, (y1 - y0) / share) / 2
    cx, cy = centre if centre is not None else ((x0 + x1) / 2, (y0 + y1) / 2)
    inset = half + EDGE_M
    return min(max(cx, x0 + inset), x1 - inset), min(max(cy, y0 + inset), y1 - inset), half


def starter_text(
    profile: Any,
    desk: str,
    file_name: str,
    units: str,
    blank: bool,
    plate: int | None = None,
    centre: tuple[float, float] | None = None,
) -> str:
    """The layout ``init`` writes (see the module docstring); for a C3D file's force plate
    (``desk`` the file) no ``desk:`` (the replay brings it) and a foot's button, pressed,
    at ``centre`` (:func:`stepped_on`; the top's middle when None)."""
    from hapticdesk.gestures.layout import UNITS

    scale = UNITS[units]
    if not profile.surfaces:
        raise ConfigError(
            desk, f"desk `{profile.name}` has no surfaces to touch (its profile needs `surfaces:`)"
        )
    top = profile.surfaces[0]
    (x0, y0), (x1, y1) = top.polygon.min(axis=0), top.polygon.max(axis=0)

    def n(metres: float) -> str:
        # (a float's last bits, such as a centre's 2.78e-07, rounded away: to 1 µm)
        return f"{round(metres, 6) / scale + 0.0:.4g}"

    lines = [
        f"# A layout for hapticdesk, started by `hapticdesk init` for desk {profile.name}.",
        f"# Its surface `{top.name}` spans x {n(x0)}..{n(x1)} and y {n(y0)}..{n(y1)} {units}:",
        _axes_line(desk, centre),
        f"#   hapticdesk check {file_name}{_plate_arguments(desk, plate)}"
        "            # what it means, or where it is wrong",
        f"#   hapticdesk ui --layout {file_name}      # draw regions and bind gestures",
        "# Every key, gesture and action: the documentation's Reference pages.",
        _desk_line(desk, file_name, plate),
        f"units: {units}                  # m | cm | mm, for every length below",
    ]
    if blank:
        return "\n".join(lines + ["regions: {}", "bindings: []", ""])
    bx, by, half = _button_square(top.polygon, is_c3d(desk), centre)
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2  # (the other shapes about the top's middle)
    width, depth = x1 - x0, y1 - y0
    lines += [
        "regions:",
        f"  button: {{rect: [{n(bx - half)}, {n(by - half)}, {n(bx + half)}, {n(by + half)}]}}"
        "   # x0, y0, x1, y1",
        f"  # knob: {{circle: {{center: [{n(cx + width / 4)}, {n(cy)}], radius: {n(half)}}}}}",
        f"  # dimmer: {{rect: [{n(cx - width / 4)}, {n(cy + depth / 4 - half)}, "
        f"{n(cx + width / 4)}, {n(cy + depth / 4 + half)}], axis: x}}   # a slider along x",
        f"  # corner: {{polygon: [[{n(x0)}, {n(y0)}], [{n(x0 + width / 5)}, {n(y0)}], "
        f"[{n(x0)}, {n(y0 + depth / 5)}]]}}",
        "bindings:",
        *_example_binding(_button_gesture(desk)),
        "  # - gesture: slide",
        "  #   region: dimmer",
        "  #   do: {mqtt: {topic: zigbee2mqtt/desk_lamp/set,",
        '  #               payload: {brightness: "{{ (value * 254) | round | int }}"}}}',
        "",
    ]
    return "\n".join(lines)


def write_starter(
    path: Path,
    desk: str = DEFAULT_DESK,
    *,
    units: str = "cm",
    blank: bool = False,
    plate: int | None = None,
) -> str:
    """Write the starter layout to ``path`` (checked as ``check`` would, first); the desk's
    name. ``desk`` a C3D file: its force plate ``plate`` (default 1) is the desk."""
    from hapticdesk.files.profile_reader import load_profile
    from hapticdesk.plugin_loading import load_registry
    from hapticdesk.runtime.assembly import load_scene_layout

    chosen = desk_or_plate(desk, plate)  # (a C3D file: its plate's desk; else as given)
    plate_profile = chosen if isinstance(chosen, DeskProfile) else None
    profile = plate_profile or load_profile(desk)
    reference = desk if plate_profile else desk_reference(desk, path)
    centre = stepped_on(desk, profile) if plate_profile and not blank else None
    text = starter_text(profile, reference, path.name, units, blank, plate, centre)
    if not path.parent.is_dir():
        raise ConfigError(str(path), f"no such folder {path.parent}")
    # (it is ours: never fails; a plate's layout names no desk, so it is given)
    load_scene_layout(path, load_registry(), plate_profile, text=text)
    try:
        with path.open("x" if not path.exists() else "w", encoding="utf-8") as out:
            out.write(text)
    except OSError as err:
        raise ConfigError(str(path), f"cannot write it: {err.strerror or err}") from None
    return str(profile.name)
