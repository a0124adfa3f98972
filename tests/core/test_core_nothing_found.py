"""A recording that gives no contact says why: `contacts` names what kept its samples out (a
recording too short to tare, readings all NaN or beyond range), and the refused tare says
whether the desk moved or its readings were not usable (it said "the desk was not quiet (is
someone touching or leaning on it?)" of a desk whose every reading was NaN)."""

from __future__ import annotations

import numpy as np
import pytest

from hapticdesk.cli import main
from hapticdesk.estimator import ContactEstimator
from hapticdesk.files.profile_reader import load_profile
from hapticdesk.files.recording import Recording
from hapticdesk.files.recording_io import write_recording
from hapticdesk.sim import Idle, Scene, Tap, simulate


@pytest.fixture(autouse=True)
def _no_installed_plugins(monkeypatch):
    monkeypatch.setenv("HAPTICDESK_DISABLE_PLUGIN_AUTOLOAD", "1")


@pytest.fixture(scope="module")
def idle():
    """Three seconds of the paper's desk, untouched."""
    profile = load_profile("kitamura2017")
    return profile, simulate(profile, Scene([Idle(3.0)]), seed=1)


def contacts(tmp_path, capsys, recording) -> str:
    path = tmp_path / "rec.csv"
    write_recording(path, recording)
    code = main(["contacts", str(path), "--desk", "kitamura2017", "-o", str(tmp_path / "c.csv")])
    assert code == 0
    return capsys.readouterr().err


def test_a_recording_too_short_to_tare_says_so(idle, tmp_path, capsys):
    _, rec = idle
    short = Recording(rec.t[:600], rec.wrench[:600], rec.sensor_names)  # 0.5 s: the tare needs 1
    err = contacts(tmp_path, capsys, short)
    assert (
        f"hapticdesk contacts: warning: {tmp_path / 'rec.csv'}: no contact found: of its 600 "
        "samples, 600 came before the desk was tared, which it never was"
    ) in err


def test_readings_all_nan_are_named_not_taken_for_a_desk_that_moves(idle, tmp_path, capsys):
    profile, rec = idle
    rec = Recording(rec.t, rec.wrench.copy(), rec.sensor_names)
    rec.wrench[:, 0, 2] = np.nan  # one channel of one sensor lost throughout
    estimator = ContactEstimator(profile)
    estimator.push(rec.t, rec.wrench)
    refused = [n.message for n in estimator.notices if n.kind == "tare_refused"]
    assert refused and all("readings were not usable" in m for m in refused)
    assert not any("not quiet" in m for m in refused)
    err = contacts(tmp_path, capsys, rec)
    assert f"samples, {len(rec.t):,} held NaN or an infinite value" in err


def test_a_desk_that_moves_is_still_said_to_move(idle):
    profile, rec = idle
    t, wrench = rec.t, rec.wrench.copy()
    wrench[:, 0, 2] += 3.0 * np.sin(2 * np.pi * 2.0 * t)  # a lean that sways throughout
    estimator = ContactEstimator(profile)
    estimator.push(t, wrench)
    refused = [n.message for n in estimator.notices if n.kind == "tare_refused"]
    assert refused and all("the desk was not quiet" in m for m in refused)


def test_a_recording_with_contacts_gets_no_warning(tmp_path, capsys):
    profile = load_profile("kitamura2017")
    rec = simulate(profile, Scene([Idle(1.5), Tap((0.0, 0.0), peak_n=5.0), Idle(0.5)]), seed=1)
    assert "warning" not in contacts(tmp_path, capsys, rec)


def test_a_short_quiet_recording_that_tared_gets_no_warning(idle, tmp_path, capsys):
    """Most of 1.5 s comes before the tare's end, but the desk was tared: nothing to say."""
    _, rec = idle
    assert "warning" not in contacts(
        tmp_path, capsys, Recording(rec.t[:1800], rec.wrench[:1800], rec.sensor_names)
    )
