"""The wheel carries what an installed hapticdesk needs outside a clone: the desk profiles,
the stroke templates and the demo's layout and scene (`hapticdesk demo` after `pip install`)."""

import subprocess
import sys
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_the_wheel_carries_profiles_templates_and_the_demo(tmp_path):
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", str(tmp_path), str(ROOT)],
        check=True,
        capture_output=True,
    )
    (wheel,) = tmp_path.glob("hapticdesk-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    for needed in (
        "hapticdesk/profiles/kitamura2017.yaml",
        "hapticdesk/profiles/kitamura2017.dbc",
        "hapticdesk/gestures/strokes/templates/circle.json",
        "hapticdesk/examples/layouts/demo.yaml",
        "hapticdesk/examples/scenes/demo.yaml",
        "hapticdesk/plugins/mqtt/__init__.py",
    ):
        assert needed in names, needed
    assert not any("plugin-example" in n for n in names)  # a package of its own
