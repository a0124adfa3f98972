"""No Python traceback reaches a user of the command line: an unexpected error is one line
naming the command, its kind and how to see the traceback (``--debug``, HAPTICDESK_DEBUG=1);
a library's warning is one line without a source path; outputs are checked before the work;
a folder with no stroke files is said so."""

from __future__ import annotations

import subprocess
import sys
import threading
import warnings
from pathlib import Path

import numpy as np
import pytest

from hapticdesk.cli import main
from hapticdesk.commands import plugins as plugins_command

HINT = "run with --debug or HAPTICDESK_DEBUG=1 for the traceback)"


@pytest.fixture
def failing(monkeypatch):
    """Make `hapticdesk plugins` (no numpy to load, no files) do what a test asks."""
    monkeypatch.delenv("HAPTICDESK_DEBUG", raising=False)

    def use(run):
        monkeypatch.setattr(plugins_command, "run", run)

    return use


def _raise(err: BaseException):
    def run(args):
        raise err

    return run


@pytest.mark.parametrize(
    ("err", "line"),
    [
        (RuntimeError("boom\nsecond line"), "error: boom (an unexpected RuntimeError; "),
        (MemoryError(), "error: out of memory (an unexpected MemoryError; "),
        (ValueError(), "error: no message (an unexpected ValueError; "),
    ],
)
def test_an_unexpected_error_is_one_line(failing, capsys, err, line):
    failing(_raise(err))
    assert main(["plugins"]) == 1
    assert capsys.readouterr().err == f"hapticdesk plugins: {line}{HINT}\n"


def test_debug_shows_the_traceback(failing, monkeypatch, capsys):
    failing(_raise(RuntimeError("boom")))
    with pytest.raises(RuntimeError, match="boom"):
        main(["plugins", "--debug"])
    monkeypatch.setenv("HAPTICDESK_DEBUG", "1")
    with pytest.raises(RuntimeError, match="boom"):
        main(["plugins"])
    for off in ("0", "false", "No", " off "):  # (false turned it on)
        monkeypatch.setenv("HAPTICDESK_DEBUG", off)
        assert main(["plugins"]) == 1


def test_ctrl_c_stays_quiet(failing, capsys):
    failing(_raise(KeyboardInterrupt()))
    assert main(["plugins"]) == 130
    assert capsys.readouterr().err == ""


def test_warnings_and_failed_threads_are_one_line_each(failing, capsys):
    def run(args):
        with warnings.catch_warnings():
            warnings.simplefilter("always")
            np.log(np.zeros(1))  # numpy: "divide by zero encountered in log"
        thread = threading.Thread(target=lambda: 1 / 0, name="worker")
        thread.start()
        thread.join()
        return 0

    failing(run)
    shown, hook = warnings.showwarning, threading.excepthook
    assert main(["plugins"]) == 0
    err = capsys.readouterr().err.splitlines()
    assert err == [
        "hapticdesk plugins: warning: divide by zero encountered in log (RuntimeWarning)",
        f"hapticdesk plugins: error: division by zero (an unexpected ZeroDivisionError; {HINT} "
        "(in thread worker)",
    ]
    assert (warnings.showwarning, threading.excepthook) == (shown, hook)  # put back


def test_outputs_are_checked_before_the_work(tmp_path, capsys):
    folder = tmp_path / "out.csv"
    folder.mkdir()
    missing = tmp_path / "nowhere" / "x.csv"
    recording = tmp_path / "not-read.csv"  # the outputs are refused before it is read
    cases = [
        (
            ["contacts", str(recording), "--desk", "kitamura2017", "-o", str(folder)],
            f"hapticdesk contacts: error: {folder}: cannot write: it is a folder; expected a "
            "file name",
        ),
        (
            ["contacts", str(recording), "--desk", "kitamura2017", "-o", str(missing)],
            f"hapticdesk contacts: error: {missing}: cannot write: the folder {missing.parent} "
            "does not exist",
        ),
        (
            ["check", str(tmp_path / "layout.yaml"), "--png", "x.csv"],
            "hapticdesk check: error: --png: the drawing is written as .png: expected a file "
            "name ending in .png, found 'x.csv'",
        ),
        (
            ["bench", "--quick", "--seeds", "1", "--plot", "x.csv"],
            "hapticdesk bench: error: --plot: the plot is written as .png: expected a file "
            "name ending in .png, found 'x.csv'",
        ),
        (
            ["bench", "--paper", "--paper-png", str(missing.with_suffix(".png"))],
            f"hapticdesk bench: error: --paper-png: cannot write {missing.with_suffix('.png')}:"
            f" the folder {missing.parent} does not exist",
        ),
        (
            ["bench", "--quick", "--seeds", "-1"],
            "hapticdesk bench: error: --seeds: must be 1 to 20 simulated sessions, found -1",
        ),
        (  # each session is held for the pooled figures: 1000 grew the process past 3 GB
            ["bench", "--quick", "--seeds", "1000"],
            "hapticdesk bench: error: --seeds: must be 1 to 20 simulated sessions, found 1000",
        ),
        (  # uvicorn's bind had failed in its thread, with a traceback
            ["ui", "--port", "70000"],
            "hapticdesk ui: error: --port: expected a port 0..65535, found 70000",
        ),
        (  # as `run` paces a replay: 1e-300 overflowed the clock
            ["emulate", "--desk", "kitamura2017-can", "--scene", "s.yaml", "--bus", "virtual:x"]
            + ["--speed", "1e-300"],
            "hapticdesk emulate: error: --speed: must be 0 (as fast as possible) or 0.001 to "
            "1e+06 times real time, found 1e-300",
        ),
    ]
    for argv, message in cases:
        assert main(argv) == 2, argv
        assert capsys.readouterr().err.strip() == message


def test_contacts_that_cannot_be_written_after_all(tmp_path, capsys, monkeypatch):
    from pathlib import Path

    from hapticdesk.files.profile_reader import load_profile
    from hapticdesk.files.recording_io import write_recording
    from hapticdesk.sim import Idle, Scene, simulate

    recording = tmp_path / "rec.csv"
    write_recording(recording, simulate(load_profile("kitamura2017"), Scene([Idle(0.2)])))
    output = tmp_path / "contacts.csv"

    real_open = Path.open

    def refuse(self, *args, **kwargs):
        if self == output:  # (the desk profile and the recording are read as before)
            raise PermissionError(13, "Permission denied")
        return real_open(self, *args, **kwargs)

    monkeypatch.setattr(Path, "open", refuse)
    assert main(["contacts", str(recording), "--desk", "kitamura2017", "-o", str(output)]) == 2
    err = capsys.readouterr().err.strip()
    assert err == f"hapticdesk contacts: error: {output}: cannot write: Permission denied"


def test_a_folder_without_strokes_is_said(tmp_path, capsys):
    # exit 2, an input error as for every command (docs/reference/cli.md); it was 1
    assert main(["strokes", "classify", str(tmp_path)]) == 2
    assert capsys.readouterr().err == (
        f"hapticdesk strokes: error: {tmp_path}: no stroke files (.csv, .json) in this folder "
        "or below\n"
    )


def test_a_missing_stroke_file_is_said_missing(tmp_path, capsys):
    """It was told to end in .csv or .json: `strokes classify /no/such` said the suffix."""
    missing = tmp_path / "no-such"
    assert main(["strokes", "classify", str(missing)]) == 2
    assert capsys.readouterr().err == (
        f"hapticdesk strokes: error: {missing}: cannot read the stroke file: No such file or "
        "directory\n"
    )


def test_a_real_run_prints_no_traceback(tmp_path):
    """End to end in a fresh interpreter: what a user sees (one line, exit 2)."""
    folder = tmp_path / "out.csv"
    folder.mkdir()
    done = subprocess.run(
        [sys.executable, "-m", "hapticdesk", "contacts", "x.csv", "--desk", "kitamura2017",
         "-o", str(folder)],
        capture_output=True, text=True, timeout=60, cwd=tmp_path,
    )  # fmt: skip
    assert done.returncode == 2
    expected = f"hapticdesk contacts: error: {folder}: cannot write: it is a folder; expected a"
    assert done.stderr == expected + " file name\n"


def test_after_a_double_dash_debug_is_a_file_name(monkeypatch, capsys):
    """``--`` ends the options: a recording called ``--debug`` is read as one (and said
    missing), not taken for the flag."""
    monkeypatch.delenv("HAPTICDESK_DEBUG", raising=False)
    assert main(["contacts", "--desk", "kitamura2017", "--", "--debug"]) == 2
    err = capsys.readouterr().err
    assert "--debug: cannot read the recording: No such file or directory" in err


def test_a_missing_recording_is_said_missing_whatever_its_name(capsys, tmp_path):
    """Without a recording suffix a file is read as a CAN log: missing, it is said missing,
    not taken for a log the desk's profile (no ``can:`` section) cannot decode."""
    missing = tmp_path / "session"
    assert main(["contacts", "--desk", "kitamura2017", str(missing)]) == 2
    assert f"{missing}: cannot read the recording: No such file or directory" in (
        capsys.readouterr().err
    )


def test_a_file_that_is_no_recording_is_said_so(capsys, tmp_path):
    """A ``.npy`` (or any file not a recording nor a CAN log) for a desk without `can:` was
    reported as the profile's missing `can:` section."""
    array = tmp_path / "a.npy"
    array.write_bytes(b"\x93NUMPY")
    assert main(["contacts", "--desk", "kitamura2017", str(array)]) == 2
    assert f"{array}: not a recording hapticdesk reads: expected .csv or .npz" in (
        capsys.readouterr().err
    )


@pytest.mark.parametrize(
    "redirect, code, said",
    [
        ("| head -c 1", None, ""),  # the reader went away: quiet (was an unexpected error)
        ("> /dev/full", 2, "cannot write its output: No space left on device"),
        (">&-", 2, "cannot write the standard output: it is closed"),
    ],
    ids=["closed-pipe", "full-disk", "closed"],
)
def test_standard_output_that_cannot_be_written_is_one_line_or_none(redirect, code, said):
    """`hapticdesk check L | head -1`, `> /dev/full`, `>&-`: a shell tool's behaviour, not
    "an unexpected BrokenPipeError / OSError / AttributeError"."""
    if redirect == "> /dev/full" and not Path("/dev/full").exists():
        pytest.skip("no /dev/full here")
    layout = Path(__file__).resolve().parents[2] / "examples" / "layouts" / "buttons.yaml"
    run = subprocess.run(
        f'{sys.executable} -m hapticdesk check {layout} {redirect}; echo "exit $?" >&2',
        shell=True,
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    lines = run.stderr.splitlines()
    if code is None:  # the pipeline's status is the reader's; ours must print nothing
        assert run.stdout == "O" and lines[:-1] == []
    else:
        assert lines == [f"hapticdesk check: error: {said}", f"exit {code}"]


@pytest.mark.parametrize("command", ["simulate", "record", "emulate"])
def test_a_negative_seed_is_refused_by_every_command_that_simulates(command, capsys):
    """numpy refuses a negative seed: `record` and `emulate` let it through to an unexpected
    ValueError; all three now refuse it as an argument."""
    argv = {
        "simulate": ["simulate", "scene.yaml", "-o", "x.csv"],
        "record": ["record", "--source", "sim:scene.yaml", "--desk", "kitamura2017", "-o", "x.csv"],
        "emulate": [
            "emulate",
            "--desk",
            "kitamura2017-can",
            "--scene",
            "s.yaml",
            "--bus",
            "virtual:x",
        ],
    }[command]
    with pytest.raises(SystemExit) as stop:
        main([*argv, "--seed=-1"])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert err.splitlines()[-1] == (
        f"hapticdesk {command}: error: argument --seed: must be a whole number >= 0, found -1"
    )


@pytest.mark.parametrize("command", ["record", "emulate"])
@pytest.mark.parametrize("rate", ["0", "-1", "9000000"])
def test_a_bit_rate_no_bus_has_is_refused(command, rate, capsys):
    """0 was taken for "the profile's" without a word, −1 passed to the interface."""
    argv = {
        "record": ["record", "--source", "sim:s.yaml", "--desk", "kitamura2017", "-o", "x.csv"],
        "emulate": ["emulate", "--desk", "kitamura2017-can", "--scene", "s.yaml", "--bus", "v:x"],
    }[command]
    with pytest.raises(SystemExit) as stop:
        main([*argv, f"--bitrate={rate}"])
    assert stop.value.code == 2
    assert capsys.readouterr().err.splitlines()[-1] == (
        f"hapticdesk {command}: error: argument --bitrate: expected 1 to 8000000 bits per "
        f"second, found {rate}"
    )
