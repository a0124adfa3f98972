"""Optional outputs never stop sensing, and a run says what it delivered (issue 30, items 9
and 11).

On b5a43bd `run --events` on a full disk stopped sensing (an optional log took the desk
down), a recording cut short by a full disk was left behind as if whole, and without a broker
the summary said "actions: 57 done" when nothing was delivered."""

from __future__ import annotations

import errno
import json
import logging
import os
import subprocess
from pathlib import Path
from types import SimpleNamespace

import pytest

from hapticdesk.cli import main
from hapticdesk.hookspecs import hookimpl
from hapticdesk.plugin_loading import load_registry
from hapticdesk.runtime.assembly import build_scene
from hapticdesk.runtime.events_file import EventsFile
from hapticdesk.runtime.service import Runtime

from .taps import Tap, tap_recording
from .test_runtime_control import ScriptedSource, write_layout

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


class _DiskFillsUp:
    """A text file that takes ``lines`` writes, writes half of the next one and then fails
    with ENOSPC, as a full disk does (on every write, and on close)."""

    def __init__(self, path: Path, lines: int) -> None:
        self._file = path.open("w", encoding="utf-8")
        self.lines = lines
        self.full = False

    def write(self, text: str) -> int:
        if self.full or self.lines == 0:
            if not self.full:
                self._file.write(text[: len(text) // 2])
                self._file.flush()
            self.full = True
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        self.lines -= 1
        return self._file.write(text)

    def flush(self) -> None:
        self._file.flush()

    def close(self) -> None:
        self._file.close()
        if self.full:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


def test_events_on_a_full_disk_are_dropped_counted_and_sensing_goes_on(
    tmp_path: Path, paper_desk, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """Guards item 9: the events file filling up after two events is said once, cut back to
    its whole lines and dropped; every tap is still recognised and its action run; the
    report counts what was not written (b5a43bd: sensing stopped at the third tap)."""
    path = write_layout(tmp_path / "a.yaml", "lamp")
    taps = [Tap(1.5 + 0.5 * k, 0.0, 0.0) for k in range(6)]
    source = ScriptedSource(tap_recording(paper_desk, taps, 5.0), {})
    plugin = SimpleNamespace(
        register_sources=hookimpl(lambda register: register("s", lambda a, p, **o: source))
    )
    registry = load_registry(entry_points=False, plugins=[("s", plugin)])
    events = tmp_path / "events.jsonl"
    monkeypatch.setattr(EventsFile, "_open_file", lambda self: _DiskFillsUp(events, 2))
    runtime = Runtime(build_scene(path, "s:", registry, speed=0), events_path=events)
    with caplog.at_level(logging.ERROR):
        report = runtime.run(handle_signals=False)
    assert report.error is None
    assert report.gesture_count == 6 and report.dispatch.totals.ok == 6
    written = events.read_text().splitlines()
    assert [json.loads(x)["gesture"] for x in written] == ["tap", "tap"]
    assert events.read_text().endswith("\n")  # the half line is cut off
    assert report.output_failures == [
        f"{events}: cannot write the events (No space left on device): 2 written (whole "
        "lines), 4 not"
    ]
    said = [r for r in caplog.records if "cannot write the events" in r.getMessage()]
    assert len(said) == 1


def test_events_on_dev_full_are_one_error_and_a_run_that_senses_to_the_end(capsys) -> None:
    """Guards item 9 end to end: `run --events /dev/full` senses the whole scene, runs every
    action, and ends with status 3 (not everything delivered) naming the file once
    (b5a43bd: status 1, sensing stopped)."""
    if not Path("/dev/full").exists():
        pytest.skip("no /dev/full here")
    code = main(
        ["run", "--layout", str(EXAMPLES / "layouts" / "buttons.yaml"), "--source",
         f"sim:{EXAMPLES / 'scenes' / 'buttons.yaml'}", "--speed", "0", "--events", "/dev/full"]
    )  # fmt: skip
    err = capsys.readouterr().err
    assert code == 3
    assert "11 gestures (11 tap)" in err and "actions: 11 done" in err
    # the summary's note and the last line (the log line goes to the log, once)
    assert err.count("/dev/full: cannot write the events (No space left on device)") == 2
    assert "0 written (whole lines), 11 not" in err
    assert "Traceback" not in err


def test_a_recording_the_disk_cannot_hold_is_removed_not_left_cut_short(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    """Guards item 9's "a truncated output removed or marked": `record` whose output fails
    half-way removes what it wrote and says so (b5a43bd left the part behind)."""
    from hapticdesk.commands import record

    output = tmp_path / "rec.csv"

    def half_then_full(path: Path, rec: object) -> None:
        Path(path).write_text("t,fl_fx\n0.0,1.0\n0.0008")
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(record, "write_recording", half_then_full)
    code = main(
        ["record", "--source", f"sim:{EXAMPLES / 'scenes' / 'buttons.yaml'}", "--desk",
         "kitamura2017", "-o", str(output), "--seconds", "1"]
    )  # fmt: skip
    err = capsys.readouterr().err
    assert code != 0
    assert "cannot write: No space left on device (the partial file was removed)" in err
    assert not output.exists()


def test_a_recording_on_a_really_full_disk_is_removed(tmp_path: Path, capsys) -> None:
    """Guards item 9 on a real full file system: a 64 kB tmpfs (needs root to mount; skipped
    otherwise) cannot hold a CAN log of the buttons scene; the part is removed."""
    mount = tmp_path / "tiny"
    mount.mkdir()
    mounted = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(mount)], capture_output=True
    )
    if mounted.returncode != 0:
        pytest.skip("cannot mount a tmpfs here (needs root)")
    try:
        output = mount / "rec.csv"
        code = main(
            ["record", "--source", f"sim:{EXAMPLES / 'scenes' / 'buttons.yaml'}", "--desk",
             "kitamura2017", "-o", str(output), "--seconds", "3"]
        )  # fmt: skip
        err = capsys.readouterr().err
        assert code != 0
        assert "No space left on device (the partial file was removed)" in err
        assert list(mount.iterdir()) == []
    finally:
        subprocess.run(["umount", str(mount)], check=False)


def test_without_a_broker_the_summary_does_not_say_done(tmp_path: Path, capsys) -> None:
    """Guards item 11: with the broker unreachable the summary says the calls were handed
    over and how many messages were NOT delivered, never "N done" (b5a43bd: "actions: 22
    done"), and the run ends with status 3."""
    layout = tmp_path / "l.yaml"
    text = (EXAMPLES / "layouts" / "buttons.yaml").read_text()
    text = text.replace("do: {log: {}}", "do: {mqtt: {topic: lamp/set, payload: {state: TOGGLE}}}")
    layout.write_text(text + "mqtt: {broker: 'mqtt://127.0.0.1:9'}\n")
    code = main(
        ["run", "--layout", str(layout), "--source", f"sim:{EXAMPLES / 'scenes' / 'buttons.yaml'}",
         "--speed", "0", "--drain", "0.5"]
    )  # fmt: skip
    err = capsys.readouterr().err
    assert code == 3
    [line] = [x for x in err.splitlines() if x.startswith("actions: ")]
    assert " done" not in line
    assert line.startswith("actions: 22 handed to their connection, which did NOT deliver 44 ")
