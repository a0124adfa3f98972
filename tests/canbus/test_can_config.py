"""The profile's `can:` section: valid forms load, every mistake names file:line:column."""

from __future__ import annotations

import re

import numpy as np
import pytest

from hapticdesk.canbus.config import AtiSensor, SignalSensor
from hapticdesk.canbus.config_reader import can_config
from hapticdesk.errors import ConfigError
from hapticdesk.files.profile_reader import load_profile

from .can_profiles import HEAD, error_at, full_can, line_of


def test_shipped_profiles_load(can_desk, bench):
    config = can_config(can_desk)
    assert config.assemble == "counter"
    assert list(config.sensors) == ["fl", "fr", "bl", "br"]
    fl = config.sensors["fl"]
    assert isinstance(fl, SignalSensor)
    assert str(fl.axes["mz"]) == "FL_MOMENT.Mz"
    assert [str(c) for c in fl.counters] == ["FL_FORCE.Seq", "FL_MOMENT.Seq"]
    assert config.database_path is not None and config.database_path.name == "kitamura2017.dbc"
    ft = can_config(bench).sensors["ft"]
    assert isinstance(ft, AtiSensor) and ft.base == 0x20 and ft.calibration is None
    assert can_config(bench).assemble == "time"


def test_the_form_in_the_issue_loads(profile_text):
    config = can_config(
        profile_text(full_can("  interface: virtual\n  channel: desk\n  bitrate: 500000\n"))
    )
    assert (config.interface, config.channel, config.bitrate) == ("virtual", "desk", 500000)


def test_a_profile_without_can_section_says_what_to_do():
    with pytest.raises(ConfigError, match="no `can:` section"):
        can_config(load_profile("kitamura2017"))


def test_unknown_sensor_named_with_position(profile_text):
    text = full_can() + "    tab: {fz: FL_FORCE.Fz}\n"
    line, col, message = error_at(profile_text, text)
    assert line == line_of(text, "tab:") and col == 5
    assert "`tab`" in message and "fl, fr, bl, br" in message


def test_a_sensor_without_decoding(profile_text):
    text = full_can(skip="br")
    line, _, message = error_at(profile_text, text)
    assert line == line_of(text, "    fl: {")  # the `sensors` mapping starts there
    assert "says nothing about sensor(s) br" in message


def test_unknown_message_and_signal(profile_text):
    text = full_can().replace("FR_FORCE.Fy", "FR_FORCE.Fq")
    line, col, message = error_at(profile_text, text)
    assert line == line_of(text, "FR_FORCE.Fq")
    assert col == text.splitlines()[line - 1].index("FR_FORCE.Fq") + 1
    assert "no signal `Fq`" in message and "Fx, Fy, Fz" in message
    text = full_can().replace("BL_MOMENT.Mz", "BL_TORQUE.Mz")
    line, _, message = error_at(profile_text, text)
    assert line == line_of(text, "BL_TORQUE") and "no message `BL_TORQUE`" in message


def test_one_signal_read_as_two_axes_is_refused_at_the_second(profile_text):
    # a copied line left unedited: fz reads fx, and the balance would be silently wrong
    text = full_can().replace("fz: BR_FORCE.Fz", "fz: BR_FORCE.Fx")
    line, col, message = error_at(profile_text, text)
    row = text.splitlines()[line - 1]
    assert line == line_of(text, "br: {fx") and col == row.index("fz: BR_FORCE.Fx") + 5
    assert message.startswith(
        "`fz` of sensor `br` reads signal `BR_FORCE.Fx`, which `fx` of sensor `br` reads "
        "already (at "
    )
    assert message.endswith(
        f"desk.yaml:{line}:{row.index('BR_FORCE.Fx') + 1}); each axis needs its own signal"
    )


def test_signal_must_be_message_dot_signal(profile_text):
    text = full_can().replace("fx: FL_FORCE.Fx", "fx: 12")
    _, _, message = error_at(profile_text, text)
    assert "`Message.Signal`" in message


def test_missing_database_file(profile_text):
    text = full_can().replace("kitamura2017.dbc", "nowhere.dbc")
    line, col, message = error_at(profile_text, text)
    assert (line, col) == (line_of(text, "nowhere.dbc"), 13)
    assert "not found" in message


def test_broken_database_file(profile_text, tmp_path):
    (tmp_path / "broken.dbc").write_text('BO_ 12 X: 8 Y\n SG_ Fx : 0|16@1- (0.01,0 [] "" HOST\n')
    text = full_can().replace("kitamura2017.dbc", "broken.dbc")
    _, _, message = error_at(profile_text, text)
    assert "cannot load CAN database" in message


def test_counter_needs_one_per_message(profile_text):
    text = full_can().replace("counter: [FL_FORCE.Seq, FL_MOMENT.Seq]", "counter: FL_FORCE.Seq")
    line, _, message = error_at(profile_text, text)
    assert line == line_of(text, "counter: FL_FORCE.Seq") and "missing for FL_MOMENT" in message


def test_counter_in_a_foreign_message(profile_text):
    text = full_can().replace(
        "counter: [FL_FORCE.Seq, FL_MOMENT.Seq]", "counter: [FL_FORCE.Seq, FR_MOMENT.Seq]"
    )
    _, _, message = error_at(profile_text, text)
    assert "FR_MOMENT" in message and "carries none" in message


def test_counter_mode_without_counters(profile_text):
    text = full_can("  assemble: counter\n").replace(
        ",\n         counter: [FL_FORCE.Seq, FL_MOMENT.Seq]", ""
    )
    line, _, message = error_at(profile_text, text)
    assert (
        line == line_of(text, "assemble: counter")
        and "fl" in message
        and "assemble: time" in message
    )
    # without `assemble`, missing counters mean assembly by time
    relaxed = profile_text(
        full_can().replace(",\n         counter: [FL_FORCE.Seq, FL_MOMENT.Seq]", "")
    )
    assert can_config(relaxed).assemble == "time"


def test_bad_choices_and_numbers(profile_text):
    for extra, needle, expected in (
        ("  assemble: magic\n", "assemble", "counter, time"),
        ("  silent_sensor: panic\n", "silent_sensor", "continue, stop"),
        ("  silent_timeout_s: 0\n", "silent_timeout_s", "> 0"),
        # the fuzzing pass: waits had no upper bound
        ("  silent_timeout_s: 1.0e+300\n", "silent_timeout_s", "expected > 0 and <= 3600"),
        ("  reconnect_timeout_s: 1.0e+300\n", "reconnect_timeout_s", "<= 3600"),
        ("  frame_gap_s: 1.0e+300\n", "frame_gap_s", "expected > 0 and <= 0.1"),
        ("  bitrate: fast\n", "bitrate", "whole number"),
        ("  busrate: 5\n", "busrate", "unknown key"),
    ):
        text = full_can(extra)
        line, _, message = error_at(profile_text, text)
        assert line == line_of(text, needle) and expected in message, (extra, message)


def test_ati_sections(profile_text):
    ati = (
        HEAD
        + """can:
  sensors:
    fl: {ati_netcanoem: {base: 0x23}}
    fr: {ati_netcanoem: {base: 0x21, slot: 2}}
    bl:
      ati_netcanoem:
        base: 0x22
        calibration:
          matrix: [[1,0,0,0,0,0],[0,1,0,0,0,0],[0,0,1,0,0,0],
                   [0,0,0,1,0,0],[0,0,0,0,1,0],[0,0,0,0,0,1]]
          counts_per_force: 1000
          force_unit: lbf
    br: {ati_netcanoem: }
"""
    )
    config = can_config(profile_text(ati))
    assert [s.base for s in config.sensors.values()] == [0x23, 0x21, 0x22, 0x20]  # type: ignore[union-attr]
    assert config.sensors["fr"].slot == 2  # type: ignore[union-attr]
    cal = config.sensors["bl"].calibration  # type: ignore[union-attr]
    assert cal is not None and cal.counts_per_force == 1000 and cal.force_unit == "lbf"
    np.testing.assert_allclose(cal.gauge_map()[0, 0], 4.4482216152605 / 1000)


def test_ati_mistakes(profile_text):
    base = HEAD + (
        "can:\n  sensors:\n"
        "    fl: {ati_netcanoem: {base: 0x21}}\n"
        "    fr: {ati_netcanoem: {base: 0x22}}\n"
        "    bl: {ati_netcanoem: {base: 0x23}}\n"
    )
    for br, needle, expected in (
        ("{ati_netcanoem: {base: 0x80}}", "0x80", "0…127"),
        ("{ati_netcanoem: {base: 0x21}}", "br: {ati", "uses CAN id 0x21"),
        ("{ati_netcanoem: {bas: 3}}", "bas:", "unknown key `bas`"),
        ("{ati_netcanoem: {calibration: {matrix: [[1, 2]]}}}", "matrix", "6 rows"),
        (
            "{ati_netcanoem: {calibration: {matrix: [[1,0,0,0,0,0],[1,0,0,0,0,0],[0,0,1,0,0,0],"
            "[0,0,0,1,0,0],[0,0,0,0,1,0],[0,0,0,0,0,1]]}}}",
            "matrix",
            "singular",
        ),
        ("{ati_netcanoem: {slot: 16}}", "slot", "0…15"),
        ("{ati_netcanoem: {base: 0x24}, fz: X.Y}", "fz", "unknown key `fz`"),
    ):
        text = base + f"    br: {br}\n"
        line, _, message = error_at(profile_text, text)
        assert line == line_of(text, needle) and expected in message, (br, message)


def test_a_bench_profile_has_one_sensor_and_no_surfaces(bench):
    assert len(bench.sensors) == 1 and not bench.surfaces


@pytest.mark.parametrize(
    ("change", "needle"),
    [
        ("message length", "a CAN frame carries at most 64"),
        ("many signals", "more than 10,000 signals"),
    ],
)
def test_a_database_cantools_would_build_for_minutes_is_refused_at_its_line(
    profile_text, tmp_path, change, needle
):
    """The fuzzing pass: `BO_ 272 FL_FORCE: 99999999` ran cantools past a minute and 2.8 GB;
    2,000 messages of 64 signals took 25 s and 475 MB. Refused first, at the DBC's line."""
    dbc = (tmp_path / "kitamura2017.dbc").read_text()
    if change == "message length":
        bad = dbc.replace("BO_ 272 FL_FORCE: 8", "BO_ 272 FL_FORCE: 99999999", 1)
    else:
        signal = ' SG_ S{k} : 0|8@1+ (1,0) [0|255] "" Vector__XXX\n'
        bad = dbc + "".join(
            f"BO_ {4096 + m} M{m}: 8 Vector__XXX\n" + "".join(signal.format(k=k) for k in range(8))
            for m in range(1300)
        )
    (tmp_path / "big.dbc").write_text(bad)
    profile = profile_text(full_can().replace("kitamura2017.dbc", "big.dbc"))
    with pytest.raises(ConfigError) as info:
        can_config(profile)
    assert re.match(r".*big\.dbc:\d+:\d+: ", str(info.value)), str(info.value)
    assert needle in str(info.value)
