"""Hostile files (the robustness hunt): every bad stroke file, recording, YAML file or path
ends in a ConfigError that says where and what was expected, in bounded time and memory —
never a traceback, never a read that does not end. Limits are made small here rather than
files large."""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from hapticdesk.errors import ConfigError
from hapticdesk.files import recording_io, recording_lines, strokefile
from hapticdesk.files.profile_reader import builtin_profile_path, load_profile, resolve_profile_path
from hapticdesk.files.recording_io import read_recording
from hapticdesk.files.strokefile import read_stroke
from hapticdesk.files.validators import number, vector
from hapticdesk.files.yamlfile import load_marked_yaml

NAMES = ["fl", "fr", "bl", "br"]
HEADER = ",".join(["t"] + [f"{s}_{a}" for s in NAMES for a in ("fx", "fy", "fz", "mx", "my", "mz")])
ROW = ",".join(["0"] * 25)


def within(seconds: float, fn: Callable[[], Any]) -> Any:
    """``fn()``'s result or exception, failing the test if it has not ended in ``seconds``
    (a read of a FIFO without a writer would block forever)."""
    out: dict[str, Any] = {}

    def run() -> None:
        try:
            out["value"] = fn()
        except BaseException as err:  # noqa: BLE001 - handed to the test
            out["error"] = err

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    thread.join(seconds)
    if thread.is_alive():
        pytest.fail(f"still running after {seconds} s")
    if "error" in out:
        raise out["error"]
    return out.get("value")


# --- stroke files ----------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("name", "data", "where", "message"),
    [
        ("latin1.csv", b"x,y\n0,0\n1,1\ncaf\xe9,1\n", ":4:4", "not UTF-8 text: byte 0xe9"),
        ("utf16.csv", "x,y\n0,0\n".encode("utf-16"), ":1:1", "UTF-16"),
        ("big.csv", b"x,y\n" + b"1" * 200_000 + b",1\n", ":2", "field larger than field limit"),
        ("deep.json", b'{"points": ' + b"[" * 5000 + b"]" * 5000 + b"}", ":1:", "nested more"),
        ("bigint.json", b'{"points": [[0, 0], [1' + b"0" * 5000 + b", 3]]}", "", "point 2 is"),
        ("bigint2.json", b'{"points": [[0, 0], [1' + b"0" * 400 + b", 3]]}", "", "finite"),
        ("far.csv", b"x,y\n1e308,1e308\n-1e308,-1e308\n", "", "in metres on the desk"),
    ],
)
def test_bad_stroke_files_are_config_errors(
    tmp_path: Path, name: str, data: bytes, where: str, message: str
) -> None:
    path = tmp_path / name
    path.write_bytes(data)
    with pytest.raises(ConfigError) as err:
        read_stroke(path)
    assert str(err.value).startswith(f"{path}{where}"), str(err.value)
    assert message in str(err.value)


@pytest.mark.parametrize(
    ("name", "data"),
    [
        ("bom.csv", b"\xef\xbb\xbfx,y\n0,0\n1,1\n"),
        ("bom.json", b'\xef\xbb\xbf{"points": [[0, 0], [1, 1]]}'),
    ],
)
def test_a_utf8_bom_is_read_as_yaml_and_recordings_read_it(
    tmp_path: Path, name: str, data: bytes
) -> None:
    path = tmp_path / name
    path.write_bytes(data)
    np.testing.assert_array_equal(read_stroke(path), [[0, 0], [1, 1]])


def test_a_stroke_file_is_capped_by_size_and_points(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "many.csv"
    path.write_text("x,y\n" + "".join(f"{i * 1e-3},0\n" for i in range(50)))
    monkeypatch.setattr(strokefile, "MAX_STROKE_BYTES", 100)
    with pytest.raises(ConfigError, match=r"more than the 0.0001 MB a stroke may have"):
        read_stroke(path)
    monkeypatch.setattr(strokefile, "MAX_STROKE_BYTES", 10_000)
    monkeypatch.setattr(strokefile, "MAX_STROKE_POINTS", 20)
    with pytest.raises(ConfigError, match=r"many.csv:22: a stroke has at most 20 points"):
        read_stroke(path)
    path = tmp_path / "many.json"
    path.write_text('{"points": ' + str([[i * 1e-3, 0] for i in range(50)]) + "}")
    with pytest.raises(ConfigError, match=r"at most 20 points, found 50"):
        read_stroke(path)


# --- recordings ------------------------------------------------------------------------------


def write_rows(path: Path, rows: list[str], header: str = HEADER) -> Path:
    path.write_text(header + "\n" + "".join(r + "\n" for r in rows))
    return path


@pytest.mark.parametrize("block_rows", [4, 16_384])
def test_a_row_with_more_values_than_the_header_is_refused(tmp_path: Path, block_rows: int) -> None:
    rows = [f"{i * 1e-3}," + ROW[2:] for i in range(10)]
    rows[6] += ",7"  # file line 8
    path = write_rows(tmp_path / "shifted.csv", rows)
    with pytest.raises(
        ConfigError, match=r"shifted.csv:8: this row has 26 value\(s\), the header 25"
    ):
        read_recording(path, NAMES, block_rows=block_rows)


def test_a_quoted_cell_may_hold_commas_but_a_row_may_not_hold_more_cells(tmp_path: Path) -> None:
    rows = [f'{i * 1e-3},{ROW[2:]},"a, b"' for i in range(5)]
    path = write_rows(tmp_path / "note.csv", rows, HEADER + ",note")
    assert len(read_recording(path, NAMES)) == 5
    rows[3] += ",x"
    write_rows(path, rows, HEADER + ",note")
    with pytest.raises(ConfigError, match=r"note.csv:5: this row has 27 value\(s\), the header 26"):
        read_recording(path, NAMES)


def test_a_line_without_end_is_refused_after_the_line_limit(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(recording_lines, "MAX_LINE_CHARS", 1000)
    path = tmp_path / "nonl.csv"
    path.write_text("t" * 5000)
    with pytest.raises(ConfigError, match=r"nonl.csv:1: a line longer than 1000 characters"):
        read_recording(path, NAMES)
    # a long cell (once over the csv module's field limit) further down names its line
    path = write_rows(tmp_path / "bigfield.csv", ["0," + ROW[2:], "1," + "9" * 3000 + ROW[1:]])
    with pytest.raises(ConfigError, match=r"bigfield.csv:3: a line longer than 1000"):
        read_recording(path, NAMES, block_rows=1)


@pytest.mark.parametrize(
    "bad",
    [
        "0.02,x," + ROW[4:],
        "0.02," + ROW[2:] + ",2",
        "0.02," + "9" * 3000 + ROW[3:],
        "nan" + ROW[1:],
    ],
    ids=["not a number", "a value too many", "a line too long", "no time"],
)
def test_the_samples_before_a_bad_line_are_handed_out_first(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, bad: str
) -> None:
    # a replay read in blocks lost the good rows of the block that held a bad line (a run
    # ended at 16,384 samples on a file good to line 27,000): nothing read is lost now
    monkeypatch.setattr(recording_lines, "MAX_LINE_CHARS", 1000)
    rows = [f"{i * 1e-3}," + ROW[2:] for i in range(30)]
    rows[20] = bad  # file line 22
    path = write_rows(tmp_path / "late_bad.csv", rows)
    with recording_io.RecordingBlocks(path, NAMES, block_rows=8) as blocks:
        got: list[float] = []
        with pytest.raises(ConfigError, match=r"late_bad.csv:22\b"):
            for block in blocks.blocks():
                got += block.t.tolist()
    np.testing.assert_allclose(got, [i * 1e-3 for i in range(20)])


def test_a_trailing_comma_is_not_a_value_too_many(tmp_path: Path) -> None:
    # a logger that ends each row with a comma was read before the width check: still read
    path = write_rows(tmp_path / "trailing.csv", [f"{i * 1e-3}," + ROW[2:] + "," for i in range(5)])
    assert len(read_recording(path, NAMES)) == 5


def test_a_block_ends_once_its_lines_hold_the_block_limit(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(recording_lines, "MAX_BLOCK_CHARS", 1000)  # about 20 rows of 50 characters
    path = write_rows(tmp_path / "rows.csv", [f"{i * 1e-3}," + ROW[2:] for i in range(200)])
    with recording_io.RecordingBlocks(path, NAMES, block_rows=16_384) as blocks:
        sizes = [len(block) for block in blocks.blocks()]
    # (a block holds the limit and at most one read of as many characters more)
    assert sum(sizes) == 200 and max(sizes) <= 2 * 1000 // len(ROW) + 2 and len(sizes) >= 5


def test_a_byte_that_is_not_utf8_is_named_at_its_line_after_the_samples_before(
    tmp_path: Path,
) -> None:
    path = tmp_path / "bad_utf8.csv"
    rows = [f"{i * 1e-3}," + ROW[2:] for i in range(1500)]
    data = (HEADER + "\n" + "\n".join(rows) + "\n").encode()
    at = data.index(("\n" + rows[999] + "\n").encode()) + 1 + 6  # line 1001, column 7
    path.write_bytes(data[:at] + b"\xe9" + data[at + 1 :])
    with recording_io.RecordingBlocks(path, NAMES, block_rows=16_384) as blocks:
        got: list[float] = []
        with pytest.raises(ConfigError, match=r"bad_utf8.csv:1001:7: not UTF-8 text: byte 0xe9"):
            for block in blocks.blocks():
                got += block.t.tolist()
    assert len(got) == 999


def test_a_blank_and_a_last_line_without_end_are_still_read(tmp_path: Path) -> None:
    path = tmp_path / "ok.csv"
    path.write_text(HEADER + "\r\n0," + ROW[2:] + "\r\n\r\n1," + ROW[2:])
    np.testing.assert_array_equal(read_recording(path, NAMES, block_rows=1).t, [0, 1])


# --- not regular files -----------------------------------------------------------------------


@pytest.mark.parametrize(
    ("suffix", "read"),
    [
        (".yaml", load_marked_yaml),
        (".csv", lambda p: read_recording(p, NAMES)),
        (".npz", lambda p: read_recording(p, NAMES)),
        (".csv", read_stroke),
    ],
    ids=["yaml", "recording", "npz", "stroke"],
)
def test_a_fifo_without_writer_is_refused_at_once(
    tmp_path: Path, suffix: str, read: Callable[[Path], Any]
) -> None:
    fifo = tmp_path / f"fifo{suffix}"
    os.mkfifo(fifo)
    try:
        with pytest.raises(
            ConfigError, match=rf"fifo{suffix}: cannot read .*a named pipe \(FIFO\)"
        ):
            within(5.0, lambda: read(fifo))
    finally:
        # a reader still blocked in open() (the bug) is released by a writer opening it
        try:
            os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))
        except OSError:  # no reader: nothing blocked
            pass


@pytest.mark.parametrize("read", [load_marked_yaml, read_stroke], ids=["yaml", "stroke"])
def test_a_directory_and_a_device_are_named(tmp_path: Path, read: Callable[[Path], Any]) -> None:
    folder = tmp_path / "dir.csv"
    folder.mkdir()
    with pytest.raises(ConfigError, match="it is a directory, not a regular file"):
        read(folder)
    link = tmp_path / "zero.csv"
    link.symlink_to("/dev/zero")
    with pytest.raises(ConfigError, match="it is a character device, not a regular file"):
        read(link)


@pytest.mark.parametrize("kind", ["directory", "fifo", "device"])
def test_a_desk_that_is_not_a_file_says_what_it_is(tmp_path: Path, kind: str) -> None:
    path = tmp_path / "desk.yaml"
    if kind == "directory":
        path.mkdir()
    elif kind == "fifo":
        os.mkfifo(path)
    else:
        path.symlink_to("/dev/zero")
    expected = {"directory": "a directory", "fifo": "a named pipe", "device": "a character"}
    with pytest.raises(ConfigError, match=f"desk.yaml: the desk profile is {expected[kind]}"):
        resolve_profile_path(path)


# --- YAML numbers ----------------------------------------------------------------------------


def test_yaml_numbers_with_an_exponent_and_no_dot_are_numbers(tmp_path: Path) -> None:
    text = "a: 5e-2\nb: 1e6\nc: 2.5e3\nd: 5\ne: 1_000\nf: -1E-3\ng: e5\nh: 1.0e+6\n"
    text += "v: [1e3, 2]\n"
    doc = load_marked_yaml("x.yaml", text=text)
    read = {key: number(doc, key, "x") for key in "abcdefh"}
    assert read == {"a": 0.05, "b": 1e6, "c": 2500.0, "d": 5, "e": 1000, "f": -0.001, "h": 1e6}
    assert vector(doc["v"], doc.where("v"), "v", 2) == [1000.0, 2.0]
    assert doc["g"] == "e5"
    # where text is meant (a payload, an exec argument) `1e3` stays what was written: as
    # YAML 1.1 reads it, before and after; PyYAML's own loader is left as it was
    assert doc["b"] == "1e6" and str(doc["b"]) == "1e6" and isinstance(doc["d"], int)
    import yaml

    assert yaml.safe_load("a: 1e6") == {"a": "1e6"}


def test_an_exponent_number_in_a_payload_or_argv_stays_text(tmp_path: Path) -> None:
    import json

    doc = load_marked_yaml("x.yaml", text="argv: [echo, 1e3]\npayload: {code: 1e3}\n")
    assert [str(a) for a in doc["argv"]] == ["echo", "1e3"]
    assert json.dumps(doc["payload"]) == '{"code": "1e3"}'


def test_words_and_numbers_read_as_yaml_1_2_reads_them(tmp_path: Path) -> None:
    """PyYAML is YAML 1.1: `state: ON` went out to Zigbee2MQTT as `{"state": true}`, `1:30`
    was 90 and `010` was 8, while the browser UI's ruamel (YAML 1.2) read the same file as
    "ON", "1:30" and 10. Now both read it alike; a true-or-false setting still takes `on`."""
    import json

    from hapticdesk.files.validators import flag
    from hapticdesk.gestures.event import GestureEvent
    from hapticdesk.plugins.mqtt.message import encode_payload
    from hapticdesk.plugins.templating import compile_value, event_variables

    text = "payload: {state: ON, at: 1:30, code: 010, power: off, ok: true}\nretain: no\n"
    text += "a: yes\nb: Off\nc: 'on'\nd: 0x1F\n"
    doc = load_marked_yaml("x.yaml", text=text)
    rendered = compile_value(doc["payload"], doc.where("payload"), "`payload`").render(
        event_variables(GestureEvent(1.0, "tap", "lamp", 0.0, 0.0), "study")
    )
    assert json.loads(encode_payload(rendered)) == {
        "state": "ON",
        "at": "1:30",
        "code": 10,
        "power": "off",
        "ok": True,
    }
    assert [flag(doc, k, "x", default=False) for k in ("retain", "a", "b")] == [False, True, False]
    with pytest.raises(ConfigError, match="x.yaml:5:4: `c` in x must be true or false"):
        flag(doc, "c", "x", default=False)  # quoted: text, in 1.1 as in 1.2
    assert doc["d"] == 31
    # and the settings that are true or false read them as before
    from hapticdesk.gestures.layout_reader import load_layout
    from hapticdesk.plugins.mqtt.settings import settings_from_layout

    mqtt = load_marked_yaml("x.yaml", text="mqtt: {discovery: off, retain: yes}\n")["mqtt"]
    settings = settings_from_layout(mqtt, desk="study")
    assert settings.discovery is False and settings.retain is True
    path = tmp_path / "layout.yaml"
    path.write_text(
        "desk: kitamura2017\nunits: cm\nregions: {lamp: {rect: [-26, -16, -14, -4]}}\n"
        "bindings:\n  - {gesture: long_press, region: lamp, release: yes, do: {log: {}}}\n",
        encoding="utf-8",
    )
    assert load_layout(path).bindings[0].options["release"] is True


def test_a_quoted_number_is_named_with_a_hint() -> None:
    doc = load_marked_yaml("x.yaml", text="a: '5e-2'\nv: [1, 2, '3', 4]\n")
    with pytest.raises(ConfigError, match=r"x.yaml:1:4: .*found str '5e-2'; write the number"):
        number(doc, "a", "the test")
    with pytest.raises(
        ConfigError, match=r"x.yaml:2:11: `v` must be 4 numbers; item 3 is str '3'; write"
    ):
        vector(doc["v"], doc.where("v"), "`v`", 4)


# --- profiles: settings checked against each other -------------------------------------------


def desk_with(tmp_path: Path, edit: Callable[[str], str]) -> Path:
    """The shipped paper desk's profile with ``edit`` applied to its text."""
    text = Path(str(builtin_profile_path("kitamura2017"))).read_text(encoding="utf-8")
    edited = edit(text)
    assert edited != text
    path = tmp_path / "desk.yaml"
    path.write_text(edited, encoding="utf-8")
    return path


def sub(old: str, new: str) -> Callable[[str], str]:
    return lambda text: text.replace(old, new, 1)


@pytest.mark.parametrize(
    ("edit", "where", "message"),
    [
        (sub("sample_rate_hz: 1200", "sample_rate_hz: 5"), "14:17", "must be >= 10, found 5"),
        (sub("sample_rate_hz: 1200", "sample_rate_hz: 1e-300"), "14:17", "must be >= 10"),
        (sub("sample_rate_hz: 1200", "sample_rate_hz: 1.0e+300"), "14:17", "<= 100000"),
        (sub("sample_rate_hz: 1200", "sample_rate_hz: 2e6"), "14:17", "<= 100000"),
        (
            sub("force_lowpass_hz: 4.77", "force_lowpass_hz: 1e6"),
            "39:21",
            "`force_lowpass_hz` in `estimation` is 1e+06 Hz; a low-pass cut-off must be below "
            "half the sample rate (the Nyquist frequency, 600 Hz",
        ),
        (sub("diff_lowpass_hz: 4.77", "diff_lowpass_hz: 600"), "38:20", "is 600 Hz; a low-pass"),
        (
            sub("force_lowpass_hz: 4.77", "force_lowpass_hz: 1.0e-300"),
            "39:21",
            "a cut-off must be at least 0.0048 Hz",
        ),
        (sub("diff_window_s: 0.166", "diff_window_s: 1.0e+300"), "37:18", "<= 5, found 1e+300"),
        (sub("tare_s: 1.0", "tare_s: 1.0e+300"), "35:11", "<= 60, found 1e+300"),
        (
            # the low-passes a natural frequency sets are checked at that key
            lambda t: sub("natural_frequency_hz: 5.9", "natural_frequency_hz: 1e6")(
                t.replace("  diff_lowpass_hz: 4.77\n", "").replace("  force_lowpass_hz: 4.77\n", "")
            ),
            "15:45",
            "`natural_frequency_hz` of `desk` is 1e+06 Hz; a sway the sensors can see must be "
            "below half the sample rate (600 Hz",
        ),
        (
            # with its own low-passes the desk's sway at 1e300 Hz had crashed the estimator
            sub("natural_frequency_hz: 5.9", "natural_frequency_hz: 1e300"),
            "15:45",
            "`natural_frequency_hz` of `desk` is 1e+300 Hz",
        ),
        (
            # a sensor at 1e300 m: infinite moments, the estimator crashed on its covariances
            sub("position: [-0.34, -0.22, 0.0]", "position: [-1e300, -0.22, 0.0]"),
            "17:26",
            "`position` of sensor `fl` has a coordinate of 1e+300 m from P_o; a desk's parts lie "
            "within 100 m of it",
        ),
        (sub("origin: [0.0, 0.0, 0.733]", "origin: [0.0, 0.0, 1e300]"), "27:13", "of 1e+300 m"),
        (
            # the simulator had crashed with an OverflowError
            sub("polygon: [[-0.375, -0.25]", "polygon: [[-1e300, -0.25]"),
            "29:15",
            "polygon point 1 of surface `top` has a coordinate of 1e+300 m from its origin",
        ),
        (
            sub("force_n: [150, 150, 300]", "force_n: [1.0e-300, 150, 300]"),
            "18:23",
            "`force_n` of sensor `fl` must be ratings from 0.001 to 1e+07",
        ),
        (
            sub(
                "polygon: [[-0.375, -0.25], [0.375, -0.25], [0.375, 0.25], [-0.375, 0.25]]",
                "polygon: [" + ", ".join(["[0.1, 0.1]"] * 501) + "]",
            ),
            "29:14",
            "`polygon` of surface `top` must list 3 to 500 [u, v] points, found 501",
        ),
    ],
)
def test_a_profile_the_estimator_cannot_run_is_refused_where_it_is_wrong(
    tmp_path: Path, edit: Callable[[str], str], where: str, message: str
) -> None:
    path = desk_with(tmp_path, edit)
    with pytest.raises(ConfigError) as err:
        load_profile(path)
    assert str(err.value).startswith(f"{path}:{where}: "), str(err.value)
    assert message in str(err.value)


@pytest.mark.parametrize("rate", [10, 50, 100_000])
def test_every_rate_the_reader_accepts_builds_an_estimator(tmp_path: Path, rate: int) -> None:
    from hapticdesk.estimator import ContactEstimator

    def slower(text: str) -> str:
        text = text.replace("sample_rate_hz: 1200", f"sample_rate_hz: {rate}", 1)
        if rate < 2 * 5.9:  # a sway beyond half the rate is refused: not known (0)
            text = text.replace("natural_frequency_hz: 5.9", "natural_frequency_hz: 0", 1)
        return text

    path = desk_with(tmp_path, slower)
    profile = load_profile(path)
    settings = ContactEstimator(profile).stage_settings  # the filters are designed
    assert np.isfinite(settings.lp_sos).all() and np.isfinite(settings.det_sos).all()
    assert settings.n_diff >= 1 and settings.window >= 1
