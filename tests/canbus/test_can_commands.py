"""`hapticdesk record` and `hapticdesk emulate`, run through the command line in one process."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from hapticdesk.cli import main
from hapticdesk.files.recording import Recording
from hapticdesk.files.recording_io import read_recording, write_recording

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


@pytest.fixture
def recording_file(tmp_path, can_desk, make_samples):
    t, wrench = make_samples(1440, 4, seed=11)  # 1.2 s
    path = tmp_path / "in.npz"
    write_recording(path, Recording(t, wrench, can_desk.sensor_names))
    return path, t, wrench


def run_json(argv, capsys) -> dict:
    assert main(argv) == 0
    return json.loads(capsys.readouterr().out.strip().splitlines()[-1])


def emulate_in_background(argv) -> threading.Thread:
    thread = threading.Thread(target=main, args=(argv,), daemon=True)
    thread.start()
    return thread


def _wait_for_a_listener(channel: str, timeout_s: float = 10.0) -> None:
    """Until a bus is open on the virtual ``channel`` (a fixed sleep lost the first frames
    of a recording on a loaded machine: 1404 of 1440 samples)."""
    from can.interfaces import virtual

    deadline = time.monotonic() + timeout_s
    while not virtual.channels.get(channel):
        assert time.monotonic() < deadline, f"nothing listens on virtual:{channel}"
        time.sleep(0.01)


@pytest.mark.parametrize("suffix", [".csv", ".asc"])
def test_record_a_live_bus_fed_by_emulate(
    tmp_path, recording_file, capsys, suffix, dbc_tolerance, can_desk, virtual_channel
):
    source, t, wrench = recording_file
    name = virtual_channel
    out = tmp_path / f"rec{suffix}"
    # record listens first; emulate then sends the recording in real time (1.2 s)
    recorder = threading.Thread(
        target=main,
        args=(
            [
                "record",
                "--source",
                f"can:virtual:{name}",
                "--desk",
                "kitamura2017-can",
                "-o",
                str(out),
                "--seconds",
                "5",  # from the bus's opening: emulate's start and 1.2 s of frames, under load
                "--json",
            ],
        ),
    )
    recorder.start()
    _wait_for_a_listener(name)  # a virtual bus gives frames only to the buses already open
    assert (
        main(
            [
                "emulate",
                "--desk",
                "kitamura2017-can",
                "--recording",
                str(source),
                "--bus",
                f"virtual:{name}",
                "--json",
            ]
        )
        == 0
    )
    sent = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    recorder.join(10)
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert sent["samples"] == 1440 and sent["frames"] == 8 * 1440 and sent["encoding"] == "dbc"
    assert summary["samples"] == 1440 and summary["problems"] == []
    if suffix == ".csv":
        rec = read_recording(out, can_desk.sensor_names)
    else:
        from hapticdesk.canbus.logs.desk_samples import read_can_log

        assert summary["frames"] == 8 * 1440
        rec = read_can_log(out, can_desk)
    np.testing.assert_allclose(rec.t, t, atol=1e-9)
    assert (np.abs(rec.wrench - wrench) <= dbc_tolerance).all()


def test_record_an_ati_bench_through_emulate(
    tmp_path, capsys, bench, make_samples, virtual_channel
):
    t, wrench = make_samples(200, 1, seed=2)
    wrench[:, :, 2] -= 34.0  # a bare sensor
    source = tmp_path / "bench.csv"
    write_recording(source, Recording(t / 5, wrench, bench.sensor_names))
    name = virtual_channel
    emulator = emulate_in_background(
        ["emulate", "--desk", "ati-bench", "--recording", str(source), "--bus", f"virtual:{name}"]
    )
    time.sleep(0.2)
    out = tmp_path / "bench.blf"
    summary = run_json(
        [
            "record",
            "--source",
            f"can:virtual:{name}",
            "--desk",
            "ati-bench",
            "-o",
            str(out),
            "--seconds",
            "2",  # (200 polls: a round waits for the board's reply, slower on a loaded host)
            "--json",
        ],
        capsys,
    )
    emulator.join(5)
    assert not emulator.is_alive()  # every sample was polled, the board went quiet
    from hapticdesk.canbus.logs.desk_samples import decode_can_log

    decoded = decode_can_log(out, bench)  # decodes on its own: calibration and polls are in it
    got = decoded.recording.wrench[:, 0]
    ok = ~np.isnan(got).any(axis=1)
    assert summary["samples"] == len(decoded.recording) and ok.sum() >= 100
    diff = np.abs(got[ok][:, None, :] - wrench[None, :, 0, :]).max(axis=2)
    assert (diff.min(axis=1) < 0.05).all() and (np.diff(diff.argmin(axis=1)) > 0).all()


def test_record_converts_files(tmp_path, recording_file, capsys, can_desk, dbc_tolerance):
    source, t, wrench = recording_file
    trc = tmp_path / "desk.trc"
    summary = run_json(
        [
            "record",
            "--source",
            f"replay:{source}",
            "--desk",
            "kitamura2017-can",
            "-o",
            str(trc),
            "--json",
        ],
        capsys,
    )
    assert summary["frames"] == 8 * 1440
    asc = tmp_path / "desk.asc"
    summary = run_json(
        [
            "record",
            "--source",
            f"replay:{trc}",
            "--desk",
            "kitamura2017-can",
            "-o",
            str(asc),
            "--seconds",
            "0.5",
            "--json",
        ],
        capsys,
    )
    assert summary["samples"] == 600 and summary["frames"] == 8 * 600
    npz = tmp_path / "back.npz"
    summary = run_json(
        [
            "record",
            "--source",
            f"replay:{asc}",
            "--desk",
            "kitamura2017-can",
            "-o",
            str(npz),
            "--json",
        ],
        capsys,
    )
    rec = read_recording(npz, can_desk.sensor_names)
    assert summary["samples"] == len(rec) == 600
    assert (np.abs(rec.wrench - wrench[:600]) <= dbc_tolerance).all()


def test_record_a_scene_as_an_ati_log(tmp_path, capsys, ati_desk):
    profile, _ = ati_desk
    scene = tmp_path / "scene.yaml"
    scene.write_text(
        "name: s\nunits: cm\nquiet_s: 1.5\ntail_s: 0.2\ntimeline:\n  - tap: {point: [0, 0]}\n"
    )
    out = tmp_path / "scene.log"
    summary = run_json(
        [
            "record",
            "--source",
            f"sim:{scene}",
            "--desk",
            str(profile.path),
            "-o",
            str(out),
            "--json",
        ],
        capsys,
    )
    from hapticdesk.canbus.logs.desk_samples import read_can_log
    from hapticdesk.sim import load_scene, simulate

    rec = read_can_log(out, profile)
    truth = simulate(profile, load_scene(scene))
    assert summary["samples"] == len(truth) == len(rec)
    np.testing.assert_allclose(rec.wrench, truth.wrench, atol=0.1)


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (
            ["record", "--source", "can:virtual:x", "--desk", "kitamura2017-can", "-o", "x.mp3"],
            "cannot record to .mp3",
        ),
        (
            ["record", "--source", "tcp:1", "--desk", "kitamura2017-can", "-o", "x.csv"],
            "unknown source kind `tcp`; installed: can, replay, serial, sim",
        ),
        (
            ["record", "--source", "can:nosuch:x", "--desk", "kitamura2017-can", "-o", "x.csv"],
            "cannot open CAN interface 'nosuch'",
        ),
        (
            [
                "record",
                "--source",
                "replay:nowhere.asc",
                "--desk",
                "kitamura2017-can",
                "-o",
                "x.csv",
            ],
            "no such file",
        ),
        (
            ["record", "--source", "can:virtual:x", "--desk", "kitamura2017", "-o", "x.csv"],
            "no `can:` section",
        ),
        (
            ["emulate", "--desk", "kitamura2017", "--recording", "r.csv", "--bus", "virtual:x"],
            "no `can:` section",
        ),
        (
            [
                "emulate",
                "--desk",
                "ati-bench",
                "--recording",
                "r.csv",
                "--bus",
                "virtual:x",
                "--encoding",
                "dbc",
            ],
            "--encoding dbc",
        ),
        (
            ["emulate", "--desk", "kitamura2017-can", "--recording", "r.csv", "--bus", "nocolon"],
            "INTERFACE:CHANNEL",
        ),
        (
            [
                "emulate",
                "--desk",
                "kitamura2017-can",
                "--recording",
                "r.csv",
                "--bus",
                "virtual:x",
                "--speed",
                "-1",
            ],
            "--speed",
        ),
    ],
)
def test_mistakes_are_one_line_errors(tmp_path, monkeypatch, capsys, argv, expected):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert expected in err and "Traceback" not in err and len(err.strip().splitlines()) == 1


def test_emulate_ati_on_a_desk_profile_says_how_to_decode(
    tmp_path, can_desk, make_samples, capsys, virtual_channel
):
    import can

    t, wrench = make_samples(3, 4)
    source = tmp_path / "three.csv"
    write_recording(source, Recording(t, wrench, can_desk.sensor_names))
    name = virtual_channel
    bus = can.Bus(interface="virtual", channel=name)
    thread = emulate_in_background(
        [
            "emulate",
            "--desk",
            "kitamura2017-can",
            "--recording",
            str(source),
            "--bus",
            f"virtual:{name}",
            "--encoding",
            "ati",
        ]
    )
    reply = None
    for _ in range(40):  # until the emulator listens
        bus.send(can.Message(arbitration_id=0x217, data=b"", is_extended_id=False))  # counts, 0x21
        reply = bus.recv(0.1)
        if reply is not None:
            break
    assert reply is not None and reply.arbitration_id == 0x217 and len(reply.data) == 8
    replies = 0
    for _ in range(3):  # the boards answer one poll per sample, then the emulator ends
        for base in (0x20, 0x21, 0x22, 0x23):
            bus.send(can.Message(arbitration_id=base << 4, data=b"", is_extended_id=False))
            replies += sum(bus.recv(1.0) is not None for _ in range(2))
    thread.join(5)
    bus.shutdown()
    assert replies == 3 * 4 * 2 and not thread.is_alive()
    captured = capsys.readouterr()
    assert "fr: {ati_netcanoem: {base: 0x21}}" in captured.err
    assert "(3 samples, ati)" in captured.out


def test_record_a_live_bus_keeps_the_accelerometers_readings(tmp_path, capsys, virtual_channel):
    """A desk whose accelerometer board sends ACCEL frames: recorded to CSV, its readings are
    the recording's accelerometer columns (to the DBC's 1 mm/s² step), as `record` keeps them
    from any other live source; before, the CAN capture dropped them."""
    from hapticdesk.estimator.inertia import accelerometer_readings
    from hapticdesk.files.profile_reader import load_profile
    from hapticdesk.sim import simulate
    from hapticdesk.sim.actions import Idle
    from hapticdesk.sim.scene import Scene

    desk = load_profile("kitamura2017-accel")
    sim = simulate(desk, Scene([Idle(0.2)], quiet_s=0.5, tail_s=0.3), 4)
    accel = accelerometer_readings(desk, sim.extra)
    assert accel is not None and np.abs(accel).max() > 0.001  # the idle desk's noise at least
    source = tmp_path / "accel.csv"
    write_recording(source, Recording(sim.t, sim.wrench, desk.sensor_names, sim.extra))
    out = tmp_path / "rec.csv"
    argv = ["record", "--source", f"can:virtual:{virtual_channel}", "--desk", desk.name]
    recorder = threading.Thread(
        target=main, args=([*argv, "-o", str(out), "--seconds", "4", "--json"],)
    )
    recorder.start()
    _wait_for_a_listener(virtual_channel)
    emulate = ["emulate", "--desk", desk.name, "--recording", str(source)]
    assert main([*emulate, "--bus", f"virtual:{virtual_channel}", "--json"]) == 0
    recorder.join(10)
    rec = read_recording(out, desk.sensor_names)
    assert len(rec.t) == len(sim.t)
    got = accelerometer_readings(desk, rec.extra)
    assert got is not None, f"no accelerometer columns in {sorted(rec.extra)}"
    np.testing.assert_allclose(got, accel, atol=0.0005 + 1e-9)


def test_emulate_loop_of_one_sample_is_refused(tmp_path, monkeypatch, capsys, can_desk):
    """A one-sample recording has no spacing to pace a loop: it was sent as fast as the
    bus took it, one core at 100 % until Ctrl-C."""
    monkeypatch.chdir(tmp_path)
    write_recording(
        tmp_path / "one.csv", Recording(np.zeros(1), np.zeros((1, 4, 6)), can_desk.sensor_names)
    )
    argv = ["emulate", "--desk", "kitamura2017-can", "--recording", "one.csv", "--loop"]
    assert main([*argv, "--bus", "virtual:one"]) == 2
    err = capsys.readouterr().err
    assert "--loop" in err and "one sample" in err and "Traceback" not in err


@pytest.mark.parametrize("stop", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_emulate_on_a_bus_stops_on_a_signal_and_says_what_it_sent(stop):
    """Ctrl-C or a kill ends a looping `emulate --bus` with its summary, by its own handlers
    (a process started in the background by a shell ignores Ctrl-C's KeyboardInterrupt)."""
    command = [sys.executable, "-m", "hapticdesk", "emulate", "--desk", "kitamura2017-can"]
    command += ["--scene", str(EXAMPLES / "scenes" / "buttons.yaml"), "--seed", "1"]
    command += ["--bus", "virtual:stop-test", "--loop", "--json"]
    proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stderr is not None
        said = proc.stderr.readline()  # (said once its handlers are set)
        assert "sending desk kitamura2017-can on virtual:stop-test (Ctrl-C stops)" in said, said
        time.sleep(0.5)
    finally:
        proc.send_signal(stop)
        out, err = proc.communicate(timeout=20)
    assert proc.returncode == 0, err
    summary = json.loads(out.strip().splitlines()[-1])
    assert summary["frames"] > 0 and summary["desk"] == "kitamura2017-can"
    assert "Traceback" not in err
