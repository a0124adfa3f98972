"""Start-up cost of the command line (issue 15 item 7): ``hapticdesk --help`` lists the
commands without importing numpy, scipy or the estimator. Checked by what a fresh
interpreter has imported, not by a timing (timings are flaky on a shared machine; the README
gives the measured time)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

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


def _probe(python_probe, argv: list[str]) -> dict:
    return python_probe(PROBE.format(argv=argv, heavy=HEAVY), timeout=60)


def test_help_imports_no_heavy_module_and_lists_every_command(python_probe):
    probe = _probe(python_probe, ["--help"])
    assert probe["code"] == 0
    assert probe["heavy"] == []
    for name in probe["commands"]:
        assert name in probe["help"]


def test_no_command_prints_the_list_without_heavy_imports(python_probe):
    probe = _probe(python_probe, [])
    assert probe["code"] == 2
    assert probe["heavy"] == []
    assert "contacts" in probe["help"]


def test_a_command_s_help_still_shows_its_own_options(python_probe):
    probe = _probe(python_probe, ["contacts", "--help"])
    assert probe["code"] == 0
    assert "--method" in probe["help"]
    assert "switched" in probe["help"]


def test_listing_the_plugins_loads_no_array_library(python_probe):
    """`hapticdesk plugins` only reads the registry: numpy and scipy (and their BLAS) are not
    loaded for it, as they are for the commands that compute."""
    probe = _probe(python_probe, ["plugins"])
    assert probe["code"] == 0
    assert probe["heavy"] == []
    assert "hapticdesk.plugins.mqtt" in probe["help"]


READ_PROBE = """
import argparse, json, sys
from hapticdesk.cli import load_blas_with_one_thread
load_blas_with_one_thread()
from hapticdesk.commands.recording_input import load_input
import hapticdesk.commands.output_path
given = load_input(argparse.Namespace(recording={path!r}, desk="kitamura2017", plate=None))
print(json.dumps({{"samples": len(given.recording.t),
                   "loaded": [m for m in {watched!r} if m in sys.modules]}}))
"""


def test_reading_the_desk_and_a_recording_loads_no_scipy_and_no_plugin_registry(
    tmp_path, python_probe
):
    """All that ``contacts`` and ``plot`` do before the estimator (the desk, the recording)
    imports neither scipy (0.3–1 s), nor the plugin registry (pluggy and the entry points),
    nor the force-plate reader a CSV does not need: what scipy ``contacts`` still loads is the
    estimator's own."""
    from hapticdesk.files.recording import Recording
    from hapticdesk.files.recording_io import write_recording

    path = tmp_path / "rec.csv"
    k = 50
    names = ["fl", "fr", "bl", "br"]
    write_recording(path, Recording(np.arange(k) / 1200, np.zeros((k, 4, 6)), names))
    watched = ("scipy", "pluggy", "hapticdesk.registry", "hapticdesk.files.forceplate")
    probe = python_probe(READ_PROBE.format(path=str(path), watched=watched), timeout=60)
    assert probe == {"samples": k, "loaded": []}


BLAS_PROBE = """
import ctypes, json, os, sys
from hapticdesk.cli import BLAS_THREAD_VARIABLES, load_blas_with_one_thread
load_blas_with_one_thread()
before = [m for m in ("numpy", "scipy") if m in sys.modules]
import scipy.signal  # numpy first, then scipy with its own BLAS

def threads(library, function):
    for line in open("/proc/self/maps"):
        if library in line:
            return getattr(ctypes.CDLL(line.split()[-1]), function)()
    return None

print(json.dumps({
    "before": before,
    "numpy": threads("libscipy_openblas64_", "scipy_openblas_get_num_threads64_"),
    "scipy": threads("libscipy_openblas-", "scipy_openblas_get_num_threads"),
    "left": [name for name in BLAS_THREAD_VARIABLES if name in os.environ],
}))
"""


def test_numpy_and_scipy_load_with_one_blas_thread_when_first_imported(monkeypatch, python_probe):
    """The command line no longer imports scipy.linalg at start for every command; numpy and
    scipy still get one BLAS thread each, set as they load and not left for the programs an
    ``exec`` action starts. (Checked through OpenBLAS's own count, where the wheels bring it.)"""
    from hapticdesk.cli import BLAS_THREAD_VARIABLES

    for name in BLAS_THREAD_VARIABLES:
        monkeypatch.delenv(name, raising=False)
    probe = python_probe(BLAS_PROBE)
    assert probe["before"] == [] and probe["left"] == []
    counted = [probe[lib] for lib in ("numpy", "scipy") if probe[lib] is not None]
    if not counted:
        pytest.skip("numpy and scipy here do not bring OpenBLAS")
    assert counted == [1] * len(counted)


def _press_recording(path) -> None:
    """Three seconds of the paper's desk at rest, pressed for one in the middle."""
    from hapticdesk.files.recording import Recording
    from hapticdesk.files.recording_io import write_recording

    t = np.arange(3600) / 1200
    wrench = np.zeros((len(t), 4, 6))
    wrench[:, :, 2] = 33.75
    wrench += np.random.default_rng(1).normal(scale=0.02, size=wrench.shape)
    wrench[(t > 1.5) & (t < 2.5), :, 2] += [6.0, 2.0, 1.0, 1.0]
    write_recording(path, Recording(t, wrench, ["fl", "fr", "bl", "br"]))


def test_the_program_ends_with_all_it_wrote_as_main_writes_it(tmp_path):
    """``hapticdesk`` as a program (``cli.entry``) freezes the objects it loaded before its
    exit, so that the exit does not walk them: what the command wrote, to its ``-o`` file
    and to standard output, is all there, and the same as :func:`main` writes in process."""
    import contextlib
    import io

    from hapticdesk.cli import main

    recording = tmp_path / "press.csv"
    _press_recording(recording)
    args = ["contacts", str(recording), "--desk", "kitamura2017"]
    in_process = io.StringIO()
    with contextlib.redirect_stdout(in_process):
        assert main([*args, "-o", "-"]) == 0
    assert in_process.getvalue().count("\n") > 500  # (the press: a second of contact)
    to_stdout = subprocess.run(
        [sys.executable, "-m", "hapticdesk", *args, "-o", "-"],
        capture_output=True,
        text=True,
        timeout=120,
        check=True,
    )
    assert to_stdout.stdout == in_process.getvalue()
    to_file = subprocess.run(
        [sys.executable, "-m", "hapticdesk", *args, "-o", str(tmp_path / "out.csv")],
        capture_output=True,
        text=True,
        timeout=120,
        check=True,
    )
    assert (tmp_path / "out.csv").read_text(encoding="utf-8") == in_process.getvalue()
    assert "touches" in to_file.stderr  # (the summary line, written at the end)


def test_main_within_another_program_leaves_the_collector_as_it_was(tmp_path):
    """Only the program freezes what it loaded: :func:`main` called by another program (a
    test, a script) leaves its collector on and freezes none of its objects."""
    import gc

    from hapticdesk.cli import main

    recording = tmp_path / "press.csv"
    _press_recording(recording)
    frozen = gc.get_freeze_count()
    assert main(["contacts", str(recording), "--desk", "kitamura2017", "-o", "-"]) == 0
    assert gc.isenabled()
    assert gc.get_freeze_count() == frozen


QUIET_TARE_PROBE = """
import json, sys
import numpy as np
from hapticdesk.estimator import ContactEstimator, resolution
from hapticdesk.files.profile_reader import load_profile

searched = []
search = resolution.likeliest_noise
resolution.likeliest_noise = lambda *args: searched.append(1) or search(*args)
desk = load_profile("kitamura2017")
n, step = 3600, 0.05  # three seconds at rest, each channel rounded to 0.05 N, noise 0.3 step
rest = np.random.default_rng(0).normal(0.0, 0.3 * step, (n, len(desk.sensors), 6))
rest[:, :, 2] -= 30.0
ContactEstimator(desk, method="fused").push(np.arange(n) / 1200, np.round(rest / step) * step)
print(json.dumps({{"searched": len(searched),
                  "loaded": [m for m in {watched!r} if m in sys.modules]}}))
"""


def test_a_tare_on_quiet_rounded_channels_readies_neither_scipy_nor_numba_s_compiler(
    python_probe,
):
    """The tare's noise search for the zero's rounding floor (resolution.py) runs on a cached
    kernel loaded as the others are (kernel.warm: numba's compiler unreadied, which would
    import scipy.linalg) and with no scipy.special (0.2 s of ``contacts``' start-up each)."""
    watched = ("scipy.special", "scipy.linalg", "scipy.signal")
    # the kernels in numba's cache first (a compile readies numba's compiler, scipy.linalg too)
    warm = "from hapticdesk.estimator import kernel; kernel.warm()"
    subprocess.run([sys.executable, "-c", warm], capture_output=True, timeout=300, check=True)
    probe = python_probe(QUIET_TARE_PROBE.format(watched=watched), timeout=300)
    assert probe == {"searched": 1, "loaded": []}
