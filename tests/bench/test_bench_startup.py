"""Start-up cost of the command line (issue 15 item 7): ``hapticdesk --help`` lists the
commands without importing numpy, scipy or the estimator. Checked by what a fresh
interpreter has imported, not by a timing (timings are flaky on a shared machine; the README
gives the measured time)."""

from __future__ import annotations

import json
import subprocess
import sys

# The help lists the plugins' commands too (``demo`` is the MQTT plugin's), so the plugin
# registry (pluggy) and the hook modules load, with the error type they share (yaml, ~15 ms);
# none of them may pull in numpy, scipy or the estimator.
HEAVY = ("numpy", "scipy", "scipy.signal", "hapticdesk.estimator")

PROBE = """
import contextlib, io, json, sys
from hapticdesk.cli import COMMANDS, main
out = io.StringIO()
with contextlib.redirect_stdout(out):
    try:
        code = main({argv!r})
    except SystemExit as exit:
        code = exit.code
heavy = [m for m in {heavy!r} if m in sys.modules]
print(json.dumps({{"code": code, "help": out.getvalue(), "heavy": heavy,
                   "commands": list(COMMANDS)}}))
"""


def _probe(argv: list[str]) -> dict:
    done = subprocess.run(
        [sys.executable, "-c", PROBE.format(argv=argv, heavy=HEAVY)],
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    )
    return json.loads(done.stdout.splitlines()[-1])


def test_help_imports_no_heavy_module_and_lists_every_command():
    probe = _probe(["--help"])
    assert probe["code"] == 0
    assert probe["heavy"] == []
    for name in probe["commands"]:
        assert name in probe["help"]


def test_no_command_prints_the_list_without_heavy_imports():
    probe = _probe([])
    assert probe["code"] == 2
    assert probe["heavy"] == []
    assert "contacts" in probe["help"]


def test_a_command_s_help_still_shows_its_own_options():
    probe = _probe(["contacts", "--help"])
    assert probe["code"] == 0
    assert "--method" in probe["help"]
    assert "switched" in probe["help"]


def test_listing_the_plugins_loads_no_array_library():
    """`hapticdesk plugins` only reads the registry: numpy and scipy (and their BLAS) are not
    loaded for it, as they are for the commands that compute."""
    probe = _probe(["plugins"])
    assert probe["code"] == 0
    assert probe["heavy"] == []
    assert "hapticdesk.plugins.mqtt" in probe["help"]
